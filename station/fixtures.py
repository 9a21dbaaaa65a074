"""Study fixtures: GEO of an emulated acquisition without the downlink, where the geometry
studies (tests, tools, benchmarks) start. Not the run's path (that goes through the
channel, the station and an L0 archive: :mod:`station.run`).
"""

from __future__ import annotations

import numpy as np

from levels.geo.scenes import PassGeometry, SceneGeometry, cut_scenes, pass_geometry
from levels.process import nominal_pixel_size_m
from station.spacecraft.emulator import Acquisition

__all__ = ["emulated_pass", "emulated_scene"]


def emulated_pass(
    acq: Acquisition,
    scene_lines: int = 0,
    reference_height_m: float = 450.0,
    lost: tuple[int, ...] = (),
) -> tuple[PassGeometry, list[SceneGeometry]]:
    """GEO of an emulated acquisition without the downlink: its pass geometry from the
    emulator's hand-over (line times, bulletins, gyros, nominal look angles of every band)
    and its scenes of ``scene_lines`` (the whole strip by default). The scenes ``lost``
    are taken away with the attitude records over them, as an outage of the station does.
    The geometry studies (tests, tools, benchmarks) start here."""
    n = scene_lines or acq.hrv.n_lines
    t = acq.gyros.t_s
    keep = np.ones(t.size, dtype=bool)
    if lost:
        t0, t1 = acq.line_times_s[[min(lost) * n, (max(lost) + 1) * n - 1]]
        keep = (t < t0) | (t > t1)
    pg = pass_geometry(
        acq.epoch,
        acq.line_times_s,
        acq.hrv.line_period_s,
        acq.bulletins,
        t[keep],
        acq.gyros.rates_rad_per_s[keep],
        {b.name: b.look_nominal for b in acq.hrv.bands},
    )
    cuts = [c for c in cut_scenes(pg.n_lines, n) if c.index not in lost]
    return pg, [pg.scene(c, reference_height_m) for c in cuts]


def emulated_scene(
    acq: Acquisition, scene_lines: int = 0, reference_height_m: float = 450.0
) -> tuple[PassGeometry, SceneGeometry, float]:
    """:func:`emulated_pass` and its first scene (the whole strip by default), with the
    nominal pixel."""
    pg, scenes = emulated_pass(acq, scene_lines, reference_height_m)
    return pg, scenes[0], nominal_pixel_size_m(acq.hrv.bands[0].look_nominal)
