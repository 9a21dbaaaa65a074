"""Passes of the satellite over a receiving station: acquisition and loss of signal.

A pass is the interval during which the satellite is above the station's elevation mask.
Elevation is sampled every ``step_s`` (10 s: a pass of a few minutes cannot hide between
samples at 822 km unless it peaks within 0.1° of the mask) and each crossing of the mask is
refined by bisection on the dense truth orbit to 1 ms, all crossings at once.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from levels.geometry.ellipsoid import WGS84
from station.spacecraft.orbit import TruthOrbit
from station.spacecraft.sun import sun_direction_ecef

__all__ = ["Pass", "elevation_rad", "find_passes"]


@dataclass(frozen=True)
class Pass:
    """One pass over the station (times in seconds since the orbit's epoch)."""

    aos_s: float
    los_s: float
    max_elevation_rad: float
    t_max_s: float
    descending: bool
    daylight: bool

    @property
    def duration_s(self) -> float:
        return self.los_s - self.aos_s


def elevation_rad(
    orbit: TruthOrbit, t_s: NDArray[np.float64], lat_rad: float, lon_rad: float, h_m: float
) -> NDArray[np.float64]:
    """Elevation of the satellite seen from a ground point (geodetic, above the ellipsoid
    normal's horizon), rad; NaN outside the orbit's span."""
    site = WGS84.to_ecef(lat_rad, lon_rad, h_m)
    up = WGS84.up(lat_rad, lon_rad)
    r, _ = orbit.state_ecef(t_s)
    d = r - site
    return np.arcsin(d @ up / np.linalg.norm(d, axis=-1))


def find_passes(
    orbit: TruthOrbit,
    lat_rad: float,
    lon_rad: float,
    h_m: float,
    mask_rad: float,
    t_start_s: float,
    t_end_s: float,
    step_s: float = 10.0,
) -> list[Pass]:
    """Every complete pass above ``mask_rad`` within ``[t_start_s, t_end_s]``.

    A pass cut by either end of the interval is left out: its duration would be wrong.
    """
    t = np.arange(t_start_s, t_end_s + step_s / 2, step_s)
    above = elevation_rad(orbit, t, lat_rad, lon_rad, h_m) > mask_rad
    edges = np.flatnonzero(np.diff(above.astype(np.int8)))
    if edges.size == 0:
        return []
    lo, hi = t[edges], t[edges + 1]
    rising = above[edges + 1]
    for _ in range(int(np.ceil(np.log2(step_s / 1e-3)))):  # bisection to 1 ms, vectorised
        mid = 0.5 * (lo + hi)
        up = elevation_rad(orbit, mid, lat_rad, lon_rad, h_m) > mask_rad
        go_hi = up == rising  # the crossing lies before mid
        hi = np.where(go_hi, mid, hi)
        lo = np.where(go_hi, lo, mid)
    cross = 0.5 * (lo + hi)
    if not rising[0]:
        cross, rising = cross[1:], rising[1:]
    if rising.size and rising[-1]:
        cross, rising = cross[:-1], rising[:-1]
    aos, los = cross[0::2], cross[1::2]
    passes = []
    for a, b in zip(aos, los, strict=True):
        tt = np.linspace(a, b, 61)
        el = elevation_rad(orbit, tt, lat_rad, lon_rad, h_m)
        k = int(np.argmax(el))
        _, v = orbit.state_ecef(tt[k : k + 1])
        sun = sun_direction_ecef(orbit.epoch, tt[k : k + 1])[0]
        passes.append(
            Pass(
                aos_s=float(a),
                los_s=float(b),
                max_elevation_rad=float(el[k]),
                t_max_s=float(tt[k]),
                descending=bool(v[0, 2] < 0),
                daylight=bool(sun @ WGS84.up(lat_rad, lon_rad) > 0),
            )
        )
    return passes
