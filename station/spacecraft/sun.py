"""The Sun's direction, to 0.01°: enough for sun-synchronous node placement and shading.

References
----------
The Astronomical Almanac, "Low-precision formulas for the Sun" (section C), valid
1950–2050 to 0.01°: with n = JD − 2451545.0, L = 280.460° + 0.9856474° n,
g = 357.528° + 0.9856003° n, λ = L + 1.915° sin g + 0.020° sin 2g, ε = 23.439° − 4e-7° n.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from levels.geometry.frames import apply, rot_z
from levels.geometry.times import Epoch

__all__ = ["sun_direction_ecef", "sun_direction_eci"]


def _sun_equatorial(n_days: NDArray[np.float64]) -> NDArray[np.float64]:
    """Unit vector to the Sun on the mean equator and equinox of date, shape (N, 3)."""
    deg = np.pi / 180.0
    mean_lon = (280.460 + 0.9856474 * n_days) * deg
    anomaly = (357.528 + 0.9856003 * n_days) * deg
    ecl_lon = mean_lon + (1.915 * np.sin(anomaly) + 0.020 * np.sin(2 * anomaly)) * deg
    obliquity = (23.439 - 4e-7 * n_days) * deg
    return np.stack(
        [
            np.cos(ecl_lon),
            np.cos(obliquity) * np.sin(ecl_lon),
            np.sin(obliquity) * np.sin(ecl_lon),
        ],
        axis=-1,
    )


def sun_direction_eci(epoch: Epoch, t_s: ArrayLike) -> NDArray[np.float64]:
    """Unit vectors to the Sun in the ECI frame of ``levels.geometry.frames``, shape (N, 3).

    The Almanac gives the Sun on the equinox of date; the ECI frame's origin is the CIO. The
    hour angle is the same in both (GMST − α_equinox = ERA − α_CIO), so the CIO-based right
    ascension is α_equinox + ERA − GMST: a rotation about z by ERA − GMST.
    """
    t = np.atleast_1d(np.asarray(t_s, dtype=np.float64))
    u_equinox = _sun_equatorial(epoch.days_since_j2000(t))
    shift = epoch.era_rad(t) - epoch.gmst_rad(t)
    return apply(rot_z(shift), u_equinox)


def sun_direction_ecef(epoch: Epoch, t_s: ArrayLike) -> NDArray[np.float64]:
    """Unit vectors to the Sun in ECEF: the apparent Sun as seen from the rotating Earth."""
    t = np.atleast_1d(np.asarray(t_s, dtype=np.float64))
    u_equinox = _sun_equatorial(epoch.days_since_j2000(t))
    return apply(rot_z(-epoch.gmst_rad(t)), u_equinox)
