"""Attitude: roll, pitch and yaw of the satellite as functions of time.

Two sources, as SPOT provides them:

* absolute angles sampled in time (SPOT 5 ``Corrected_Attitudes``; SPOT 1–4 AOCS angles),
  interpolated linearly between samples (0.125 s apart: the attitude is smooth at that scale);
* angular rates from the gyros every 125 ms, integrated by the trapezoid rule from a starting
  attitude (:func:`integrate_rates`): INPE's GEO integrates "attitude rate data broadcasted
  by the satellite ... assuming a null attitude for the first received attitude rate record;
  later ... the attitude at scene center time is subtracted" (paper ``004_…`` §2.1), which
  is :meth:`SampledAttitude.zeroed_at`.

Angles follow SPOT's conventions (``levels.geometry.frames.orbital_from_body``). Arrays of
angles have shape ``(N, 3)`` with columns roll, pitch, yaw.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from levels.errors import GeometryError

__all__ = [
    "MICRODEGREE_RAD",
    "WESTIN_HARMONIC",
    "WESTIN_POWER",
    "Attitude",
    "ConstantAttitude",
    "SampledAttitude",
    "attitude_gaps",
    "integrate_rates",
    "interpolation_sigma_rad",
    "westin_variogram_rad2",
]

#: Westin's variogram unit: the paper says "[10⁻⁶]²" and checks itself with
#: [2γ_ω(31)]^½ = 0.93° × 10⁻³, so the unit is the micro-degree (``station.spacecraft.attitude``).
MICRODEGREE_RAD = np.pi / 180.0 * 1e-6

#: Westin eqs. (24)–(26): power-law terms (c, α) and harmonic terms (c, ω rad/s) per axis,
#: in micro-degrees squared.
WESTIN_POWER = ((1774.0, 1.8),), ((17500.0, 0.5),), ((3200.0, 1.0),)
WESTIN_HARMONIC = (), ((80000.0, 0.93),), ()


def westin_variogram_rad2(axis: int, dt_s: ArrayLike) -> NDArray[np.float64]:
    """Westin's 2γ(Δt) for axis 0 (roll, eq. 24), 1 (pitch, eq. 25), 2 (yaw, eq. 26), rad²."""
    dt = np.abs(np.asarray(dt_s, dtype=np.float64))
    out = np.zeros_like(dt)
    for c, alpha in WESTIN_POWER[axis]:
        out += c * dt**alpha
    for c, omega in WESTIN_HARMONIC[axis]:
        out += c * (1 - np.cos(omega * dt))
    return out * MICRODEGREE_RAD**2


#: Fractions of a gyro interval where :func:`interpolation_sigma_rad` averages (midpoints).
_INTERPOLATION_NODES = 64


def interpolation_sigma_rad(period_s: float, scale: float = 1.0) -> NDArray[np.float64]:
    """RMS error (rad; roll, pitch, yaw) of the attitude between gyro records ``period_s``
    apart, interpolated linearly, for a drift of Westin's variograms (× ``scale``): what
    no model of the records can know, at any number of control points.

    For a process with increments of structure function ``D(τ) = 2γ(τ)`` (eqs. 24–26),
    the linear interpolation at the fraction ``u`` of an interval ``p`` misses by a
    variance ``(1 − u) D(u p) + u D((1 − u) p) − u (1 − u) D(p)``, averaged here over ``u``.
    Westin's pitch (``D ∝ τ^0.5``, a rough process) gives 0.8 µrad at SPOT's 0.125 s:
    0.07 px along the track at 10 m."""
    u = (np.arange(_INTERPOLATION_NODES) + 0.5) / _INTERPOLATION_NODES
    out = np.empty(3)
    for axis in range(3):
        d_u, d_v, d_p = (
            westin_variogram_rad2(axis, x) for x in (u * period_s, (1 - u) * period_s, period_s)
        )
        out[axis] = np.mean((1 - u) * d_u + u * d_v - u * (1 - u) * d_p)
    return np.sqrt(np.maximum(out * scale, 0.0))


class Attitude(Protocol):
    """Anything that gives roll, pitch, yaw (rad), shape ``(*t.shape, 3)``, at instants ``t_s``."""

    def angles_rad(self, t_s: ArrayLike) -> NDArray[np.float64]: ...


@dataclass(frozen=True)
class ConstantAttitude:
    """The same roll, pitch, yaw at every instant; the null attitude by default."""

    roll_rad: float = 0.0
    pitch_rad: float = 0.0
    yaw_rad: float = 0.0

    def angles_rad(self, t_s: ArrayLike) -> NDArray[np.float64]:
        t = np.asarray(t_s, dtype=np.float64)
        out = np.empty((*t.shape, 3))
        out[...] = (self.roll_rad, self.pitch_rad, self.yaw_rad)
        return out


@dataclass(frozen=True, eq=False)
class SampledAttitude:
    """Attitude samples interpolated linearly.

    Within ``hold_s`` of either end the end value is held (a scene's first and last lines
    often fall a few tens of milliseconds outside the 0.125 s gyro records); further out the
    angles are NaN, so the model flags the point instead of extrapolating.

    Parameters
    ----------
    t_s
        Instants, seconds since the model's epoch, strictly increasing, shape ``(n,)``.
    angles_rad
        Roll, pitch, yaw at each instant, shape ``(n, 3)``.
    hold_s
        How far beyond the samples the end values are held (s); default: the median
        sample interval.
    """

    t_s: NDArray[np.float64]
    angles_rad_samples: NDArray[np.float64]
    hold_s: float | None = None

    def __post_init__(self) -> None:
        t = np.asarray(self.t_s, dtype=np.float64)
        a = np.asarray(self.angles_rad_samples, dtype=np.float64)
        if t.ndim != 1 or t.size < 2:
            raise GeometryError(f"attitude needs at least 2 samples, got shape {t.shape}")
        if a.shape != (t.size, 3):
            raise GeometryError(
                f"attitude sizes differ: {t.size} instants but angles of shape {a.shape}; "
                f"expected ({t.size}, 3)"
            )
        if np.any(np.diff(t) <= 0):
            raise GeometryError("attitude instants must increase strictly")
        if not (np.all(np.isfinite(t)) and np.all(np.isfinite(a))):
            raise GeometryError("attitude has non-finite values")
        t.setflags(write=False)
        a.setflags(write=False)
        object.__setattr__(self, "t_s", t)
        object.__setattr__(self, "angles_rad_samples", a)
        if self.hold_s is None:
            object.__setattr__(self, "hold_s", float(np.median(np.diff(t))))
        elif not self.hold_s >= 0:
            raise GeometryError(f"hold_s={self.hold_s}: must be >= 0 (seconds)")

    def angles_rad(self, t_s: ArrayLike) -> NDArray[np.float64]:
        t = np.asarray(t_s, dtype=np.float64)
        out = np.stack(
            [np.interp(t, self.t_s, self.angles_rad_samples[:, k]) for k in range(3)], axis=-1
        )
        outside = (
            (t < self.t_s[0] - self.hold_s) | (t > self.t_s[-1] + self.hold_s) | ~np.isfinite(t)
        )
        out[outside] = np.nan
        return out

    def zeroed_at(self, t0_s: float) -> SampledAttitude:
        """The same attitude minus its value at ``t0_s`` (INPE: null attitude at scene centre)."""
        at0 = self.angles_rad(np.array([t0_s]))[0]
        if not np.all(np.isfinite(at0)):
            raise GeometryError(
                f"cannot zero the attitude at {t0_s} s: outside the samples "
                f"[{self.t_s[0]}, {self.t_s[-1]}] s"
            )
        return SampledAttitude(self.t_s, self.angles_rad_samples - at0, self.hold_s)


def integrate_rates(
    t_s: ArrayLike,
    rates_rad_per_s: ArrayLike,
    *,
    start_t_s: float | None = None,
    start_angles_rad: ArrayLike = (0.0, 0.0, 0.0),
    max_gap_s: float | None = None,
) -> SampledAttitude:
    """Attitude from angular rates, integrated by the trapezoid rule.

    The rates are the time derivatives of roll, pitch, yaw (small-angle SPOT gyro data,
    where body rates and Euler-angle rates coincide to second order).

    Parameters
    ----------
    t_s
        Rate sample instants, strictly increasing, shape ``(n,)``.
    rates_rad_per_s
        Roll, pitch, yaw rates, shape ``(n, 3)``.
    start_t_s
        Instant at which the attitude equals ``start_angles_rad``; by default the first rate
        sample (INPE: null attitude at the first record). If earlier than the first rate
        sample, the first rate is held constant back to it.
    start_angles_rad
        Roll, pitch, yaw at ``start_t_s``.
    max_gap_s
        Intervals between rate samples longer than this are gaps (records lost): the
        attitude is held across them, not integrated. Rates at a gap's two ends say little
        about the drift in between (SPOT's pitch drift is rough, Westin eq. 25: one 125 ms
        rate times 31 s would be off by tens of microradians), while the expected increment
        of a drift with a variogram is zero and its variance the variogram (Westin §"Weights
        for attitude difference observations"), which is what level 2 weights the jump by
        (:func:`attitude_gaps`).

    Returns
    -------
    SampledAttitude
        Samples at the rate instants (and at ``start_t_s`` if it precedes them).
    """
    t = np.asarray(t_s, dtype=np.float64)
    w = np.asarray(rates_rad_per_s, dtype=np.float64)
    if t.ndim != 1 or w.shape != (t.size, 3):
        raise GeometryError(
            f"rates of shape {w.shape} for {t.shape} instants: expected ({t.size}, 3)"
        )
    if start_t_s is not None and start_t_s < t[0]:
        t = np.concatenate([[start_t_s], t])
        w = np.concatenate([w[:1], w])
    # Trapezoid rule: A(t_k) = A(t_0) + Σ (w_i + w_{i+1}) / 2 · (t_{i+1} − t_i)
    increments = 0.5 * (w[1:] + w[:-1]) * np.diff(t)[:, None]
    if max_gap_s is not None:
        increments[np.diff(t) > max_gap_s] = 0.0
    angles = np.zeros_like(w)
    angles[1:] = np.cumsum(increments, axis=0)
    sampled = SampledAttitude(t, angles)
    t_start = t[0] if start_t_s is None else start_t_s
    if t_start > t[-1]:
        raise GeometryError(f"start_t_s={start_t_s} after the last rate sample {t[-1]}")
    offset = (
        np.asarray(start_angles_rad, dtype=np.float64) - sampled.angles_rad(np.array([t_start]))[0]
    )
    return SampledAttitude(t, angles + offset, sampled.hold_s)


#: An interval between attitude records longer than this many times their median spacing
#: is a gap: records were lost (one missing record already makes 2×).
GAP_FACTOR = 1.5


def attitude_gaps(t_s: ArrayLike) -> NDArray[np.float64]:
    """The gaps of a record of attitude instants: ``(k, 2)`` start and end times of every
    interval longer than ``GAP_FACTOR`` × the median spacing."""
    t = np.asarray(t_s, dtype=np.float64)
    if t.size < 3:
        return np.zeros((0, 2))
    dt = np.diff(t)
    big = np.flatnonzero(dt > GAP_FACTOR * np.median(dt))
    return np.stack([t[big], t[big + 1]], axis=-1)
