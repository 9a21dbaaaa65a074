"""SIPC on an emulated pass: ``levels`` makes the products (:mod:`levels.process`), the
emulator's truth measures them (:mod:`station.sipc.truth`, :mod:`station.sipc.process`)."""

from station.sipc.process import emulated_scene, process_scenario, reprocess_l0, truth_for
from station.sipc.truth import Truth

__all__ = ["Truth", "emulated_scene", "process_scenario", "reprocess_l0", "truth_for"]
