"""SIPC, the processing centre: GEO once per pass and COR once per scene and level
(:mod:`station.sipc.process`), measured against the emulator's truth
(:mod:`station.sipc.truth`)."""

from station.sipc.process import PassProducts, SceneProducts, process_l0, process_scenario

__all__ = ["PassProducts", "SceneProducts", "process_l0", "process_scenario"]
