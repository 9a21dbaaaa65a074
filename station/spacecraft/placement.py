"""Where the truth orbit is put: so that a view of the satellite (its nadir, or the centre
of a tilted swath) crosses the pass's target on its day, on the descending branch."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from levels.geometry.ellipsoid import WGS84
from levels.geometry.frames import apply, ecef_from_orbital, inertial_velocity_ecef
from levels.geometry.sensor import look_direction
from levels.geometry.times import Epoch
from station.errors import OrbitError
from station.scenario import OrbitConfig, PassConfig
from station.spacecraft.orbit import (
    GM_M3_PER_S2,
    TruthOrbit,
    node_state,
    phased_targets,
    secular_targets,
    state_from_elements,
)

__all__ = ["ViewPoint", "mean_element_orbit", "nadir_point", "place_orbit", "swath_centre_view"]


ViewPoint = Callable[["TruthOrbit", NDArray[np.float64]], tuple[NDArray, NDArray]]


def nadir_point(orbit: TruthOrbit, t_s: NDArray[np.float64]) -> tuple[NDArray, NDArray]:
    """Geodetic latitude and longitude (rad) below the satellite (ellipsoid normal)."""
    r, _ = orbit.state_ecef(t_s)
    lat, lon, _h = WGS84.to_geodetic(r)
    return lat, lon


def _wrap(angle: ArrayLike) -> NDArray[np.float64]:
    return np.angle(np.exp(1j * np.asarray(angle, dtype=np.float64)))


def _crossing(
    orbit: TruthOrbit,
    view: ViewPoint,
    lat_rad: float,
    t_guess_s: float,
) -> tuple[float, float]:
    """Time near ``t_guess_s`` at which the view crosses ``lat_rad``, and its longitude."""
    t = t_guess_s
    for _ in range(8):  # secant on time; the view's latitude changes by ~6e-3°/s
        dt = 0.5
        (la, lb), _lons = view(orbit, np.array([t, t + dt]))
        step = (lat_rad - la) / ((lb - la) / dt)
        t += step
        if abs(step) < 1e-6:
            break
    _lat, lon = view(orbit, np.array([t]))
    return t, float(lon[0])


def place_orbit(
    epoch: Epoch,
    a_m: float,
    i_rad: float,
    e: float,
    ltdn_h: float,
    target_lat_rad: float,
    target_lon_rad: float,
    span_s: tuple[float, float],
    view: ViewPoint = nadir_point,
) -> tuple[TruthOrbit, float]:
    """A truth orbit whose descending pass on the epoch's day puts ``view`` on the target.

    The osculating node state (``a_m``, ``i_rad``, ``e``) comes from :func:`node_state`; the
    node's right ascension keeps the mean local time of the ascending node at
    ``ltdn_h + 12`` h (Ω = ERA + 2π (LTAN/24 − UT/1 d), so that λ_node = Ω − ERA is the
    longitude where the mean Sun's hour angle is LTAN − 12 h). Along the descending branch
    the ground track crosses latitude φ at longitude λ = 2π (LTAN − UT)/24 h + Δα(u): the
    UT of the crossing is solved in closed form, then refined by Newton on the integrated
    orbit until ``view`` crosses the target latitude within 1e-9 rad of its longitude.

    Returns the orbit over ``span_s`` (seconds since ``epoch``) and the time at which the
    view is on the target.
    """
    ltan_turns = (ltdn_h + 12.0) / 24.0
    sin_u = np.sin(target_lat_rad) / np.sin(i_rad)
    if abs(sin_u) > 1:
        raise OrbitError(
            f"target latitude {np.degrees(target_lat_rad):.2f}° is beyond the orbit's "
            f"reach (inclination {np.degrees(i_rad):.2f}°)"
        )
    u = np.pi - np.arcsin(sin_u)  # descending branch
    d_alpha = np.arctan2(np.cos(i_rad) * np.sin(u), np.cos(u))
    period = 2 * np.pi * np.sqrt(a_m**3 / GM_M3_PER_S2)
    ut_turns = np.mod(ltan_turns - (target_lon_rad - d_alpha) / (2 * np.pi), 1.0)
    t_centre = ut_turns * 86400.0
    lead = u / (2 * np.pi) * period  # node to target
    day_rate = 2 * np.pi / 86400.0  # the track's westward drift per second of UT shift
    for _ in range(6):
        t_node = t_centre - lead
        raan = float(epoch.era_rad(t_node)) + 2 * np.pi * (
            ltan_turns - np.mod(float(epoch.days_since_j2000(t_node)) + 0.5, 1.0)
        )
        r0, v0 = state_from_elements(a_m, e, i_rad, raan, 0.0, 0.0, mean_anomaly=False)
        probe = TruthOrbit(epoch, t_node, r0, v0, t_node, t_centre + 600.0)
        t_cross, lon = _crossing(probe, view, target_lat_rad, t_centre)
        miss = float(_wrap(target_lon_rad - lon))
        lead = t_cross - t_node  # keep the phase that puts the view on the target latitude
        t_centre = t_cross - miss / day_rate
        if abs(miss) < 1e-9:
            break
    else:
        raise OrbitError("could not place the orbit over the target (no convergence)")
    lo, hi = min(span_s[0], t_node, t_cross), max(span_s[1], t_node, t_cross)
    return TruthOrbit(epoch, t_node, r0, v0, lo, hi), float(t_cross)


def swath_centre_view(
    mirror_rad: float, height_m: float, reference_velocity: str = "inertial"
) -> ViewPoint:
    """The point seen by the centre of the swath at null attitude, the mirror at
    ``mirror_rad``, on the ellipsoid raised by ``height_m`` (for aiming the orbit), the
    orbital frame built on ``reference_velocity`` (``levels.geometry.frames``)."""
    u = look_direction(0.0, mirror_rad)

    def view(orbit: TruthOrbit, t_s: NDArray[np.float64]) -> tuple[NDArray, NDArray]:
        r, v = orbit.state_ecef(t_s)
        if reference_velocity == "inertial":
            v = inertial_velocity_ecef(r, v)
        los = apply(ecef_from_orbital(r, v), u)
        point, _ok = WGS84.intersect(r, los, height_m)
        lat, lon, _h = WGS84.to_geodetic(point)
        return lat, lon

    return view


def mean_element_orbit(
    oc: OrbitConfig,
    pc: PassConfig,
    epoch: Epoch,
    span_s: tuple[float, float],
    view: ViewPoint = nadir_point,
) -> tuple[TruthOrbit, float]:
    """The truth orbit of a ``phased`` or ``elements`` orbit section, placed by
    :func:`place_orbit` so that ``view`` crosses the pass's target on its day."""
    if oc.kind == "phased":
        period, raan_rate = phased_targets(oc.repeat_revs, oc.repeat_days)
    elif oc.kind == "elements":
        period, raan_rate = secular_targets(
            WGS84.a_m + oc.altitude_m, oc.eccentricity, oc.inclination_rad
        )
    else:
        raise OrbitError(f"[orbit] kind = {oc.kind!r} is not given by mean elements")
    a, i = node_state(period, raan_rate, oc.eccentricity)
    return place_orbit(
        epoch,
        a,
        i,
        oc.eccentricity,
        oc.descending_node_local_time_h,
        pc.target_lat_rad,
        pc.target_lon_rad,
        span_s,
        view,
    )
