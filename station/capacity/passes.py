"""The passes of a phased orbit over a station, one repeat cycle: the capacity model lays
it end to end over the simulated year."""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from levels.geometry.times import Epoch
from station.scenario import GroundStationConfig, OrbitConfig

__all__ = ["PassPattern", "pass_pattern"]

_DAY = 86400.0


@dataclass(frozen=True, eq=False)
class PassPattern:
    """The passes over a station in one repeat cycle of the phased orbit."""

    aos_s: np.ndarray  # since the cycle's start
    duration_s: np.ndarray
    daylight: np.ndarray  # descending in daylight: the imaging passes
    cycle_s: float
    weekday0: int  # weekday of the cycle's start (0 = Monday)


@functools.lru_cache(maxsize=8)
def pass_pattern(gs: GroundStationConfig, oc: OrbitConfig | None = None) -> PassPattern:
    """The passes over ``gs`` above its mask in one repeat cycle of the phased orbit ``oc``
    (SPOT's by default; Landsat's for the shared antenna).

    The orbit repeats its ground track every cycle (SPOT: 369 revolutions in 26 days), so
    a year is this pattern laid end to end; a satellite trailing by whole days on the same
    orbit has the same pattern, delayed.
    """
    from station.scenario import PassConfig, WorldConfig
    from station.spacecraft.orbit import TruthOrbit
    from station.spacecraft.passes import find_passes
    from station.spacecraft.placement import mean_element_orbit, swath_centre_view

    # SPOT's phased orbit, placed as a default pass would place it (nadir view on the
    # default target); only its reference state matters: the cycle is propagated from it
    oc, pc = oc or OrbitConfig(), PassConfig()
    epoch = Epoch(np.datetime64(pc.date_utc, "ns"), name="00:00 UTC of the pass day")
    o, _t = mean_element_orbit(
        oc, pc, epoch, (0.0, _DAY), swath_centre_view(0.0, WorldConfig().base_height_m)
    )
    cycle_s = oc.repeat_days * _DAY
    orbit = TruthOrbit(
        o.epoch, o.t_ref_s, o.r_ref_eci_m, o.v_ref_eci_m_per_s, min(0.0, o.t_ref_s), cycle_s + _DAY
    )
    passes = [
        p
        for p in find_passes(
            orbit,
            gs.lat_rad,
            gs.lon_rad,
            gs.height_m,
            gs.elevation_mask_rad,
            0.0,
            cycle_s + _DAY,
            step_s=20.0,
        )
        if p.aos_s < cycle_s
    ]
    return PassPattern(
        aos_s=np.array([p.aos_s for p in passes]),
        duration_s=np.array([p.duration_s for p in passes]),
        daylight=np.array([p.daylight and p.descending for p in passes]),
        cycle_s=cycle_s,
        weekday0=int((o.epoch.t0_utc.astype("datetime64[D]").astype(np.int64) + 3) % 7),
    )
