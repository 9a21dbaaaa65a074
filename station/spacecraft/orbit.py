"""The truth orbit: numerical propagation under J2, set up from mean elements or a TLE.

The truth is integrated (scipy DOP853, relative tolerance 1e-11) in the quasi-inertial ECI
frame of :mod:`levels.geometry.frames`, and handed out in ECEF with the Earth-fixed velocity.
The station never sees it: it gets bulletins sampled from it with errors
(:mod:`station.spacecraft.handover`).

Mean elements
    A mean orbit is defined by what an operator plans with: its nodal period ``T_N`` (node
    to node) and its node regression per revolution ``ΔΩ``. Both are secular, so they can be
    *measured* on the integrated orbit from one ascending node to the next (the short-period
    terms of J2 depend on the argument of latitude, which is 0 at both ends). We solve, by
    Newton's method on one-revolution integrations, for the osculating semi-major axis and
    inclination at the ascending node that give the targets. For a phased sun-synchronous
    orbit the targets are

        Ω̇ = 2π / 365.2422 d (the mean Sun)           (sun-synchronism)
        R · T_N · (ω⊕ − Ω̇) = 2π D                    (R revolutions in D days)

    and for given mean elements (a, e, i) they are the first-order secular J2 rates
    (Vallado, *Fundamentals of Astrodynamics*, eqs. 9-41 and 9-42), so that ``altitude_km``
    and ``inclination_deg`` mean what a mission analyst means by them.

Two-line elements are read and turned into a state by :mod:`station.spacecraft.tle`; the
orbit is placed over a target by :mod:`station.spacecraft.placement`.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.integrate import solve_ivp

from levels.geometry.ellipsoid import WGS84
from levels.geometry.frames import (
    EARTH_ROTATION_RATE_RAD_PER_S,
    REFERENCE_VELOCITIES,
    ecef_to_eci,
    eci_to_ecef,
    inertial_velocity_ecef,
)
from levels.geometry.times import Epoch
from station.errors import OrbitError

__all__ = [
    "GM_M3_PER_S2",
    "J2",
    "MEAN_SUN_RATE_RAD_PER_S",
    "OrbitError",
    "TruthOrbit",
    "ascending_node_ecef",
    "node_state",
    "phased_targets",
    "propagate",
    "secular_targets",
    "state_from_elements",
]

GM_M3_PER_S2 = 3.986004418e14  # WGS84 (IERS 2010)
J2 = 1.08262668e-3  # EGM96 / WGS84 unnormalised C20
RE_M = WGS84.a_m
#: Mean motion of the mean Sun (one tropical year).
MEAN_SUN_RATE_RAD_PER_S = 2.0 * np.pi / (365.2421897 * 86400.0)
_RTOL = 1e-11
_ATOL_M = 1e-5


def _rhs(_t: float, y: NDArray[np.float64]) -> NDArray[np.float64]:
    """State derivative under a J2 Earth (ECI), scalar code: scipy calls it per step."""
    r = y[:3]
    rn2 = r @ r
    rn = np.sqrt(rn2)
    z2 = r[2] * r[2] / rn2
    k = 1.5 * J2 * RE_M**2 / rn2
    g = -GM_M3_PER_S2 / (rn2 * rn)
    out = np.empty(6)
    out[:3] = y[3:]
    out[3] = g * r[0] * (1 + k * (1 - 5 * z2))
    out[4] = g * r[1] * (1 + k * (1 - 5 * z2))
    out[5] = g * r[2] * (1 + k * (3 - 5 * z2))
    return out


def propagate(r0_eci_m: ArrayLike, v0_eci_m_per_s: ArrayLike, t_end_s: float) -> Any:
    """Integrate the J2 orbit from ``t = 0`` to ``t_end_s`` (either sign) with dense output.

    Returns scipy's ``OdeResult``; ``.sol(t)`` gives the state (6, N) at ``t`` s.
    """
    y0 = np.concatenate([np.asarray(r0_eci_m, float), np.asarray(v0_eci_m_per_s, float)])
    return solve_ivp(
        _rhs,
        (0.0, float(t_end_s)),
        y0,
        method="DOP853",
        rtol=_RTOL,
        atol=_ATOL_M,
        dense_output=True,
    )


def state_from_elements(
    a_m: float,
    e: float,
    i_rad: float,
    raan_rad: float,
    argp_rad: float,
    anomaly_rad: float,
    mean_anomaly: bool = True,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Position and velocity (inertial) of Keplerian elements; anomaly mean or true."""
    if mean_anomaly:
        ecc = anomaly_rad
        for _ in range(20):  # Newton on Kepler's equation E − e sin E = M
            ecc -= (ecc - e * np.sin(ecc) - anomaly_rad) / (1 - e * np.cos(ecc))
        nu = 2 * np.arctan2(np.sqrt(1 + e) * np.sin(ecc / 2), np.sqrt(1 - e) * np.cos(ecc / 2))
    else:
        nu = anomaly_rad
    p = a_m * (1 - e * e)
    r_pf = p / (1 + e * np.cos(nu)) * np.array([np.cos(nu), np.sin(nu), 0.0])
    v_pf = np.sqrt(GM_M3_PER_S2 / p) * np.array([-np.sin(nu), e + np.cos(nu), 0.0])
    co, so, ci, si = np.cos(raan_rad), np.sin(raan_rad), np.cos(i_rad), np.sin(i_rad)
    cw, sw = np.cos(argp_rad), np.sin(argp_rad)
    rot = np.array(
        [
            [co * cw - so * sw * ci, -co * sw - so * cw * ci, so * si],
            [so * cw + co * sw * ci, -so * sw + co * cw * ci, -co * si],
            [sw * si, cw * si, ci],
        ]
    )
    return rot @ r_pf, rot @ v_pf


def _raan_rad(r: NDArray[np.float64], v: NDArray[np.float64]) -> float:
    h = np.cross(r, v)
    return float(np.arctan2(h[0], -h[1]))


def _node_to_node(a_m: float, i_rad: float, e: float) -> tuple[float, float]:
    """Nodal period (s) and node change per revolution (rad) from an ascending node."""
    r0, v0 = state_from_elements(a_m, e, i_rad, 0.0, 0.0, 0.0, mean_anomaly=False)

    def ascending(_t: float, y: NDArray[np.float64]) -> float:
        return y[2]

    ascending.direction = 1.0  # type: ignore[attr-defined]
    period_guess = 2 * np.pi * np.sqrt(a_m**3 / GM_M3_PER_S2)
    sol = solve_ivp(
        _rhs,
        (0.0, 1.2 * period_guess),
        np.concatenate([r0, v0]),
        method="DOP853",
        rtol=_RTOL,
        atol=_ATOL_M,
        events=ascending,
    )
    later = np.flatnonzero(sol.t_events[0] > 0.5 * period_guess)  # not the start node
    if later.size == 0:
        raise OrbitError(f"no ascending node within a revolution for a = {a_m:.0f} m")
    t1, y1 = sol.t_events[0][later[0]], sol.y_events[0][later[0]]
    d_raan = np.angle(np.exp(1j * (_raan_rad(y1[:3], y1[3:]) - _raan_rad(r0, v0))))
    return float(t1), float(d_raan)


def secular_targets(a_m: float, e: float, i_rad: float) -> tuple[float, float]:
    """Nodal period (s) and node regression rate (rad/s) of mean elements, first order in J2.

    References
    ----------
    Vallado, *Fundamentals of Astrodynamics*, 4th ed., eqs. (9-41) for Ω̇, ω̇ and Ṁ:
    Ω̇ = −3/2 n J2 (R/p)² cos i, ω̇ = 3/4 n J2 (R/p)² (4 − 5 sin² i),
    Ṁ = n [1 + 3/4 J2 (R/p)² √(1−e²) (2 − 3 sin² i)]; the nodal period is 2π / (Ṁ + ω̇).
    """
    n = np.sqrt(GM_M3_PER_S2 / a_m**3)
    p = a_m * (1 - e * e)
    k = J2 * (RE_M / p) ** 2
    si2 = np.sin(i_rad) ** 2
    raan_rate = -1.5 * n * k * np.cos(i_rad)
    argp_rate = 0.75 * n * k * (4 - 5 * si2)
    mean_rate = n * (1 + 0.75 * k * np.sqrt(1 - e * e) * (2 - 3 * si2))
    return float(2 * np.pi / (mean_rate + argp_rate)), float(raan_rate)


def phased_targets(repeat_revs: int, repeat_days: int) -> tuple[float, float]:
    """Nodal period (s) and node rate (rad/s) of a sun-synchronous orbit repeating R in D."""
    raan_rate = MEAN_SUN_RATE_RAD_PER_S
    period = 2 * np.pi * repeat_days / (repeat_revs * (EARTH_ROTATION_RATE_RAD_PER_S - raan_rate))
    return float(period), float(raan_rate)


def _mean_elements_for(period_s: float, raan_rate: float, e: float) -> tuple[float, float]:
    """First-order mean (a, i) with the given nodal period and node rate (Newton, 2×2)."""
    a = (GM_M3_PER_S2 * (period_s / (2 * np.pi)) ** 2) ** (1 / 3)
    i = np.arccos(
        np.clip(-raan_rate / (1.5 * np.sqrt(GM_M3_PER_S2 / a**3) * J2 * (RE_M / a) ** 2), -1, 1)
    )
    for _ in range(20):
        f0 = np.array(secular_targets(a, e, i)) - (period_s, raan_rate)
        if abs(f0[0]) < 1e-9 and abs(f0[1]) < 1e-18:
            break
        jac = np.empty((2, 2))
        for k, (da, di) in enumerate(((1.0, 0.0), (0.0, 1e-7))):
            jac[:, k] = (
                np.array(secular_targets(a + da, e, i + di)) - (period_s, raan_rate) - f0
            ) / (da + di)
        a, i = np.array([a, i]) - np.linalg.solve(jac, f0)
    return float(a), float(i)


def node_state(
    period_s: float,
    raan_rate_rad_per_s: float,
    e: float = 0.0,
    guess: tuple[float, float] | None = None,
) -> tuple[float, float]:
    """Osculating (a, i) at the ascending node whose integrated orbit has the given nodal
    period and node regression (module docstring). Returns (a_m, i_rad)."""
    a, i = guess if guess is not None else _mean_elements_for(period_s, raan_rate_rad_per_s, e)
    targets = np.array([period_s, raan_rate_rad_per_s * period_s])
    scale = np.array([1.0, 1e-6])  # seconds against radians: solve in comparable units
    for _ in range(8):
        f0 = (np.array(_node_to_node(a, i, e)) - targets) / scale
        if abs(f0[0]) < 1e-6 and abs(f0[1]) < 1e-4:  # 1 µs per rev, 1e-10 rad per rev
            return a, i
        jac = np.empty((2, 2))
        for k, (da, di) in enumerate(((10.0, 0.0), (0.0, 1e-5))):
            fk = (np.array(_node_to_node(a + da, i + di, e)) - targets) / scale
            jac[:, k] = (fk - f0) / (da + di)
        a, i = np.array([a, i]) - np.linalg.solve(jac, f0)
    raise OrbitError(
        f"no orbit with nodal period {period_s:.3f} s and node rate "
        f"{raan_rate_rad_per_s:.3e} rad/s (Newton did not converge)"
    )


@dataclass(frozen=True, eq=False)
class TruthOrbit:
    """The integrated orbit over ``[t_start_s, t_end_s]`` (seconds since ``epoch``).

    ``t_ref_s`` is where the initial state was given; the solution is integrated backward
    and forward from it.
    """

    epoch: Epoch
    t_ref_s: float
    r_ref_eci_m: NDArray[np.float64]
    v_ref_eci_m_per_s: NDArray[np.float64]
    t_start_s: float
    t_end_s: float
    #: The velocity the platform's local orbital frame follows (its attitude is controlled
    #: about that frame, and its ephemeris bulletins carry that velocity): "inertial" for
    #: SPOT 1–4, "earth_fixed" for SPOT 5 (``levels.geometry.frames``).
    reference_velocity: str = "inertial"

    def __post_init__(self) -> None:
        if self.reference_velocity not in REFERENCE_VELOCITIES:
            raise OrbitError(
                f"reference velocity {self.reference_velocity!r}: expected one "
                f"of {REFERENCE_VELOCITIES}"
            )
        if not self.t_start_s <= self.t_ref_s <= self.t_end_s:
            raise OrbitError(
                f"reference time {self.t_ref_s} s outside the span "
                f"[{self.t_start_s}, {self.t_end_s}] s"
            )
        segments = []
        for end in (self.t_start_s, self.t_end_s):
            if end != self.t_ref_s:
                sol = propagate(self.r_ref_eci_m, self.v_ref_eci_m_per_s, end - self.t_ref_s)
                if sol.status != 0:
                    raise OrbitError(f"orbit integration failed: {sol.message}")
                segments.append(sol.sol)
            else:
                segments.append(None)
        object.__setattr__(self, "_segments", tuple(segments))

    def state_eci(self, t_s: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Position and velocity (ECI), shape (N, 3) each; NaN outside the span."""
        t = np.atleast_1d(np.asarray(t_s, dtype=np.float64))
        y = np.full((t.size, 6), np.nan)
        back, fwd = self._segments  # type: ignore[attr-defined]
        dt = t - self.t_ref_s
        for seg, mask in (
            (back, (dt < 0) & (t >= self.t_start_s)),
            (fwd, (dt >= 0) & (t <= self.t_end_s)),
        ):
            if seg is not None and mask.any():
                y[mask] = seg(dt[mask]).T
            elif seg is None and mask.any():
                y[mask] = np.concatenate([self.r_ref_eci_m, self.v_ref_eci_m_per_s])
        return y[:, :3], y[:, 3:]

    def state_ecef(self, t_s: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Position and Earth-fixed velocity (ECEF), shape (N, 3) each; NaN outside."""
        t = np.atleast_1d(np.asarray(t_s, dtype=np.float64))
        r, v = self.state_eci(t)
        return eci_to_ecef(r, v, self.epoch.era_rad(t))

    def frame_state_ecef(self, t_s: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Position and the reference velocity (ECEF axes) that the platform's local orbital
        frame is built on, shape (N, 3) each."""
        r, v = self.state_ecef(t_s)
        if self.reference_velocity == "inertial":
            v = inertial_velocity_ecef(r, v)
        return r, v

    def with_reference_velocity(self, reference_velocity: str) -> TruthOrbit:
        """The same integrated orbit, its frame built on another velocity."""
        if reference_velocity not in REFERENCE_VELOCITIES:
            raise OrbitError(
                f"reference velocity {reference_velocity!r}: expected one of {REFERENCE_VELOCITIES}"
            )
        new = copy.copy(self)
        object.__setattr__(new, "reference_velocity", reference_velocity)
        return new

    @classmethod
    def from_ecef(
        cls,
        epoch: Epoch,
        t_ref_s: float,
        r_ecef_m: ArrayLike,
        v_ecef_m_per_s: ArrayLike,
        t_start_s: float,
        t_end_s: float,
    ) -> TruthOrbit:
        """The orbit through an ECEF state (Earth-fixed velocity) at ``t_ref_s``."""
        r, v = ecef_to_eci(r_ecef_m, v_ecef_m_per_s, epoch.era_rad(t_ref_s))
        return cls(epoch, t_ref_s, np.asarray(r, float), np.asarray(v, float), t_start_s, t_end_s)


def ascending_node_ecef(orbit: TruthOrbit, after_s: float) -> NDArray[np.float64]:
    """ECEF position where the orbit first crosses the equator northward after ``after_s``
    (sampled every second over one revolution, refined linearly)."""
    t = np.linspace(after_s, after_s + 6200.0, 6201)
    r, _ = orbit.state_ecef(t)
    k = np.flatnonzero(np.diff(np.sign(r[:, 2])) > 0)[0]
    frac = -r[k, 2] / (r[k + 1, 2] - r[k, 2])
    return r[k] + frac * (r[k + 1] - r[k])
