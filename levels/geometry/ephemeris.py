"""Ephemeris: satellite positions and velocities interpolated by 8-point Lagrange.

INPE interpolates the ephemeris received by telex "through a seventh order Lagrangian
polynomial" (paper ``004_…`` §2.1); the SPOT Geometry Handbook prescribes the same for the
DIMAP ephemeris (positions and velocities interpolated independently, velocities used as
given). For each instant the 8 samples nearest to it are used: 4 on each side inside the
span, a window shifted inwards near the ends (graceful fall-back: same order, one-sided), and
all samples (order n − 1) when fewer than 8 are given. Instants outside the sampled span are
not extrapolated: they get NaN, which the photogrammetric model reports as not located.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from levels.errors import GeometryError
from levels.geometry.frames import REFERENCE_VELOCITIES

__all__ = ["ORBIT_RADIUS_M", "Ephemeris", "EphemerisSpacingWarning", "lagrange_interpolate"]

#: Relative departure of a sample interval from the median interval beyond which the
#: spacing is called uneven (1 ms on 60 s; the real files are even to the microsecond).
UNEVEN_SPACING_REL = 1e-5
#: Distances from the Earth's centre an orbit's positions lie within (m): 100 km above the
#: equator to beyond the geostationary orbit; outside, the file holds no orbit (zeros, km
#: taken for metres, a damaged field).
ORBIT_RADIUS_M = (6.478e6, 5.0e7)


class EphemerisSpacingWarning(UserWarning):
    """The ephemeris samples are not evenly spaced: Lagrange error bounds do not hold."""


def lagrange_interpolate(
    t_nodes_s: NDArray[np.float64], y_nodes: NDArray[np.float64], t_s: ArrayLike, n_points: int = 8
) -> NDArray[np.float64]:
    """Interpolate ``y_nodes`` (shape ``(n, k)``) at ``t_s`` with ``n_points``-point Lagrange.

    Instants are grouped by their window of nodes (at most ``n − n_points + 1`` windows, a
    handful for an ephemeris): within a window the nodes are scalars, the Lagrange weights
    are built from prefix and suffix products of ``t − x_m`` (exact at the nodes, no division
    by ``t − x_j``) and applied to the window's values with one matrix product. Instants
    outside ``[t_nodes_s[0], t_nodes_s[-1]]`` give NaN.

    Returns
    -------
    ndarray, shape ``(*t_s.shape, k)``
    """
    t = np.asarray(t_s, dtype=np.float64)
    shape = t.shape
    t = t.ravel()
    n = t_nodes_s.size
    m = min(n_points, n)
    out = np.full((t.size, y_nodes.shape[-1]), np.nan)
    inside = (t >= t_nodes_s[0]) & (t <= t_nodes_s[-1])
    # Window of m nodes centred on t, shifted inwards at the ends.
    start = np.clip(np.searchsorted(t_nodes_s, t, side="right") - m // 2, 0, n - m)
    for s0 in np.unique(start[inside]):  # loop over windows, not over instants
        sel = np.flatnonzero(inside & (start == s0))
        x = t_nodes_s[s0 : s0 + m]
        diff = t[sel] - x[:, None]  # (m, k): rows contiguous
        prefix = np.ones_like(diff)
        suffix = np.ones_like(diff)
        for j in range(1, m):
            np.multiply(prefix[j - 1], diff[j - 1], out=prefix[j])
            np.multiply(suffix[m - j], diff[m - j], out=suffix[m - 1 - j])
        gaps = x[:, None] - x[None, :]
        np.fill_diagonal(gaps, 1.0)
        denom = gaps.prod(axis=1)  # Π over m ≠ j of (x_j − x_m)
        prefix *= suffix
        prefix /= denom[:, None]
        out[sel] = prefix.T @ y_nodes[s0 : s0 + m]
    return out.reshape(*shape, y_nodes.shape[-1])


@dataclass(frozen=True, eq=False)
class Ephemeris:
    """Sampled satellite states, interpolated by 8-point Lagrange.

    Parameters
    ----------
    t_s
        Sample instants, seconds since the model's epoch, strictly increasing, shape ``(n,)``.
    r_ecef_m
        Positions, shape ``(n, 3)``.
    v_ecef_m_per_s
        Velocities, shape ``(n, 3)``, used as given (see ``levels.geometry.frames``).
    n_points
        Lagrange window (8: "seventh order", INPE).
    reference_velocity
        Which velocity the samples carry, when the source says: ``"inertial"`` (SPOT 1–4,
        in ECEF axes) or ``"earth_fixed"`` (SPOT 5); the local orbital frame is built on it
        as given (``levels.geometry.frames``).
    """

    t_s: NDArray[np.float64]
    r_ecef_m: NDArray[np.float64]
    v_ecef_m_per_s: NDArray[np.float64]
    n_points: int = 8
    reference_velocity: str | None = None

    def __post_init__(self) -> None:
        if self.reference_velocity not in (None, *REFERENCE_VELOCITIES):
            raise GeometryError(
                f"reference velocity {self.reference_velocity!r}: expected one of "
                f"{REFERENCE_VELOCITIES}"
            )
        t = np.asarray(self.t_s, dtype=np.float64)
        r = np.asarray(self.r_ecef_m, dtype=np.float64)
        v = np.asarray(self.v_ecef_m_per_s, dtype=np.float64)
        if t.ndim != 1 or t.size < 2:
            raise GeometryError(f"ephemeris needs at least 2 instants, got shape {t.shape}")
        if r.shape != (t.size, 3) or v.shape != (t.size, 3):
            raise GeometryError(
                f"ephemeris sizes differ: {t.size} instants, positions {r.shape}, "
                f"velocities {v.shape}; expected ({t.size}, 3) each"
            )
        if not np.all(np.isfinite(t)) or not np.all(np.isfinite(r)) or not np.all(np.isfinite(v)):
            raise GeometryError("ephemeris has non-finite values")
        dt = np.diff(t)
        if np.any(dt <= 0):
            i = int(np.argmin(dt))
            raise GeometryError(
                f"ephemeris instants must increase strictly: sample {i + 1} at {t[i + 1]} s "
                f"follows {t[i]} s"
            )
        radius = np.linalg.norm(r, axis=1)
        if not np.all((ORBIT_RADIUS_M[0] <= radius) & (radius <= ORBIT_RADIUS_M[1])):
            raise GeometryError(
                f"ephemeris positions {radius.min():.0f}…{radius.max():.0f} m from the Earth's "
                f"centre: expected an orbit, {ORBIT_RADIUS_M[0]:.0f}…{ORBIT_RADIUS_M[1]:.0f} m "
                "(positions in metres, ECEF)"
            )
        if self.n_points < 2:
            raise GeometryError(f"n_points={self.n_points}: need at least 2")
        if np.max(np.abs(dt / np.median(dt) - 1.0)) > UNEVEN_SPACING_REL:
            warnings.warn(
                f"ephemeris spacing uneven: intervals from {dt.min():.6g} s to {dt.max():.6g} s; "
                "Lagrange interpolation error grows with uneven nodes",
                EphemerisSpacingWarning,
                stacklevel=3,
            )
        for name, value in (("t_s", t), ("r_ecef_m", r), ("v_ecef_m_per_s", v)):
            value.setflags(write=False)
            object.__setattr__(self, name, value)

    @property
    def span_s(self) -> tuple[float, float]:
        """First and last sampled instant (s since epoch)."""
        return float(self.t_s[0]), float(self.t_s[-1])

    def interpolate(self, t_s: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Positions (m) and velocities (m/s), shape ``(*t_s.shape, 3)``; NaN outside the span."""
        states = lagrange_interpolate(
            self.t_s, np.hstack([self.r_ecef_m, self.v_ecef_m_per_s]), t_s, self.n_points
        )
        return states[..., :3], states[..., 3:]
