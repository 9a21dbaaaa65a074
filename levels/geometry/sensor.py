"""Sensor: look directions of the detectors of a pushbroom line, and the HRV mirror.

A look-angle table gives, for detectors of the array, the along-track angle ``psi_x`` and the
across-track angle ``psi_y`` (rad) in the sensor frame; ``psi_y`` includes the mirror. The
look direction of a detector is ``normalise(-tan psi_y, tan psi_x, -1)`` (SPOT Geometry
Handbook). Between tabulated detectors the angles are interpolated linearly, which is how
PHOTOMOD (paper ``003_…``) and the producer use SPOT 1–4 tables that give only the first
and last detector; beyond the ends they are extrapolated linearly, so that the ground →
image iteration can step outside the array and come back.

Image columns are 0-based, integer at pixel centres: column ``c`` is detector ``c + 1``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from levels.errors import GeometryError

__all__ = [
    "MIRROR_STEP_RAD",
    "MIRROR_ZERO_STEP",
    "LookAngleTable",
    "butting_columns",
    "mirror_angle_rad",
]

#: HRV mirror: 0.6° per step, nadir at step 48 (SPOT 1–4; 91 positions, ±27°).
MIRROR_STEP_RAD = np.deg2rad(0.6)
MIRROR_ZERO_STEP = 48
MIRROR_MAX_STEP = 2 * MIRROR_ZERO_STEP


def mirror_angle_rad(step: ArrayLike) -> NDArray[np.float64]:
    """Viewing angle across track of an HRV mirror step: ``(step − 48) × 0.6°``."""
    s = np.asarray(step)
    if np.any((s < 0) | (s > MIRROR_MAX_STEP)) or np.any(s != np.round(s)):
        raise GeometryError(f"mirror step {step!r}: expected an integer in 0..{MIRROR_MAX_STEP}")
    return (s - MIRROR_ZERO_STEP) * MIRROR_STEP_RAD


def _interp_linear_extrapolated(x: NDArray, xp: NDArray, fp: NDArray) -> NDArray[np.float64]:
    """Piecewise-linear interpolation with linear extrapolation from the end segments."""
    y = np.interp(x, xp, fp)
    lo = x < xp[0]
    hi = x > xp[-1]
    if np.any(lo):
        y[lo] = fp[0] + (x[lo] - xp[0]) * (fp[1] - fp[0]) / (xp[1] - xp[0])
    if np.any(hi):
        y[hi] = fp[-1] + (x[hi] - xp[-1]) * (fp[-1] - fp[-2]) / (xp[-1] - xp[-2])
    return y


@dataclass(frozen=True, eq=False)
class LookAngleTable:
    """Look angles of tabulated detectors of one band.

    Parameters
    ----------
    column
        0-based columns of the tabulated detectors (detector id − 1), strictly increasing,
        at least 2 (first and last detector for SPOT 1–4, every detector for SPOT 5).
    psi_x_rad, psi_y_rad
        Along-track and across-track look angles of those detectors (rad), ``psi_y``
        strictly monotonic (it is inverted to find a column).
    n_columns
        Number of detectors of the line.
    """

    column: NDArray[np.float64]
    psi_x_rad: NDArray[np.float64]
    psi_y_rad: NDArray[np.float64]
    n_columns: int

    def __post_init__(self) -> None:
        c = np.asarray(self.column, dtype=np.float64)
        px = np.asarray(self.psi_x_rad, dtype=np.float64)
        py = np.asarray(self.psi_y_rad, dtype=np.float64)
        if c.ndim != 1 or c.size < 2 or px.shape != c.shape or py.shape != c.shape:
            raise GeometryError(
                f"look-angle table sizes: {c.shape} columns, psi_x {px.shape}, psi_y {py.shape}; "
                "expected equal 1-D sizes of at least 2"
            )
        if np.any(np.diff(c) <= 0):
            raise GeometryError("look-angle table columns must increase strictly")
        dpy = np.diff(py)
        if not (np.all(dpy > 0) or np.all(dpy < 0)):
            raise GeometryError("look-angle table psi_y must be strictly monotonic across the line")
        if np.max(np.abs(np.concatenate([px, py]))) >= np.pi / 2:
            raise GeometryError("look angles must be below 90° (radians expected)")
        if not (0 <= c[0] and c[-1] <= self.n_columns - 1):
            raise GeometryError(
                f"look-angle columns {c[0]}..{c[-1]} outside the line of {self.n_columns} detectors"
            )
        for name, value in (("column", c), ("psi_x_rad", px), ("psi_y_rad", py)):
            value.setflags(write=False)
            object.__setattr__(self, name, value)

    def angles_rad(self, column: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``psi_x``, ``psi_y`` at (fractional) columns, linear between tabulated detectors."""
        col = np.asarray(column, dtype=np.float64)
        return (
            _interp_linear_extrapolated(col, self.column, self.psi_x_rad),
            _interp_linear_extrapolated(col, self.column, self.psi_y_rad),
        )

    def directions(self, column: ArrayLike) -> NDArray[np.float64]:
        """Unit look directions in the sensor frame, shape ``(*column.shape, 3)``."""
        psi_x, psi_y = self.angles_rad(column)
        return look_direction(psi_x, psi_y)

    def column_of_psi_y(self, psi_y_rad: ArrayLike) -> NDArray[np.float64]:
        """Inverse of ``psi_y(column)``: the fractional column that sees across-track ``psi_y``."""
        py = np.asarray(psi_y_rad, dtype=np.float64)
        if self.psi_y_rad[-1] > self.psi_y_rad[0]:
            return _interp_linear_extrapolated(py, self.psi_y_rad, self.column)
        return _interp_linear_extrapolated(py, self.psi_y_rad[::-1], self.column[::-1])

    def butting_columns(self) -> NDArray[np.float64]:
        """Columns on either side of each jump of the along-track look angle (the butting of
        the CCDs): a direct grid must hold both, or its bilinear cells smear the jump (half
        a 7 µrad butting step is 0.29 px at nadir)."""
        d = np.abs(np.diff(self.psi_x_rad))
        typical = np.median(d)
        k = np.flatnonzero(d > 10.0 * typical + 1e-9)  # 1 nrad: far below any butting offset
        return np.union1d(self.column[k], self.column[k + 1])

    def with_mirror(self, mirror_rad: float) -> LookAngleTable:
        """The table seen through the mirror: ``psi_y`` shifted by the mirror angle."""
        return LookAngleTable(
            self.column, self.psi_x_rad, self.psi_y_rad + mirror_rad, self.n_columns
        )


def look_direction(psi_x_rad: ArrayLike, psi_y_rad: ArrayLike) -> NDArray[np.float64]:
    """Unit vector ``normalise(-tan psi_y, tan psi_x, -1)`` in the sensor frame."""
    px = np.asarray(psi_x_rad, dtype=np.float64)
    py = np.asarray(psi_y_rad, dtype=np.float64)
    u = np.stack([-np.tan(py), np.tan(px), -np.ones_like(px)], axis=-1)
    return u / np.linalg.norm(u, axis=-1, keepdims=True)


def butting_columns(look: LookAngleTable) -> NDArray[np.float64]:
    """:meth:`LookAngleTable.butting_columns` of ``look``."""
    return look.butting_columns()
