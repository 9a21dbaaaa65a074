"""The photogrammetric model of a pushbroom line scanner: image ⇄ ground.

INPE's GEO "photogrammetric model" (paper ``004_…`` §2.1) is a system of two equations:
the straight line from the satellite position along a detector's sight direction, and the
reference surface. The sight direction goes from the imager frame to the Greenwich
geocentric frame "in three steps, through boresight and attitude angles, and ephemeris
data"; Shu Ning (paper ``002_…`` §2) writes the same collinearity condition for linear
arrays, one projection centre per line::

    G = P(t) + d · ecef_from_orbital(P, V) · orbital_from_body(roll, pitch, yaw) · u(c)

with ``t`` the time of line ``L``, ``P, V`` the interpolated ephemeris, ``u(c)`` the look
direction of column ``c`` (``levels.geometry.sensor``) and ``d`` the distance to the surface
at height ``h`` (``Ellipsoid.intersect``, exact at any height).

The inverse, ground → image, has no closed form: the line is found by iteration, as Shu Ning
and PHOTOMOD (paper ``003_…``) do. For a trial line the ground point is expressed in the
sensor frame of that line; its across-track angle gives the column through the look-angle
table, and the difference between its along-track angle and the detector's ``psi_x`` is the
residual, driven to zero by the secant method on the line number, vectorised over points.
It stops on step size; points whose iteration does not converge (outside the ephemeris span,
behind the sensor, no root) come back flagged, never silently.

Image coordinates are 0-based with integer values at pixel centres: line 0 is the first raw
line, column 0 the first detector. Readers convert from 1-based conventions (DIMAP).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from levels.errors import GeometryError
from levels.geometry.attitude import Attitude
from levels.geometry.ellipsoid import WGS84, Ellipsoid
from levels.geometry.ephemeris import Ephemeris
from levels.geometry.frames import apply, apply_inverse, ecef_from_orbital, orbital_from_body
from levels.geometry.sensor import LookAngleTable
from levels.geometry.times import Epoch

__all__ = ["GroundPoints", "ImagePoints", "LineClock", "PushbroomModel"]


@dataclass(frozen=True)
class LineClock:
    """Time of each image line: ``t(L) = t_ref_s + (L − line_ref) · period_s``.

    Parameters
    ----------
    t_ref_s
        Time of the reference line, seconds since the model's epoch.
    line_ref
        The reference line (0-based, may be fractional).
    period_s
        Line period (s): 1.504 ms for HRV P, 3.008 ms for XS.
    """

    t_ref_s: float
    line_ref: float
    period_s: float

    def __post_init__(self) -> None:
        if not (self.period_s > 0 and np.isfinite(self.t_ref_s) and np.isfinite(self.line_ref)):
            raise GeometryError(
                f"line clock t_ref_s={self.t_ref_s}, line_ref={self.line_ref}, "
                f"period_s={self.period_s}: need finite values and period_s > 0"
            )

    def time_s(self, line: ArrayLike) -> NDArray[np.float64]:
        """Seconds since the epoch at which (fractional) ``line`` was acquired."""
        return self.t_ref_s + (np.asarray(line, dtype=np.float64) - self.line_ref) * self.period_s

    def line(self, t_s: ArrayLike) -> NDArray[np.float64]:
        """Fractional line acquired at ``t_s``."""
        return self.line_ref + (np.asarray(t_s, dtype=np.float64) - self.t_ref_s) / self.period_s


@dataclass(frozen=True)
class GroundPoints:
    """Located ground points: geodetic latitude, longitude (rad), height (m); ``ok`` flags."""

    lat_rad: NDArray[np.float64]
    lon_rad: NDArray[np.float64]
    h_m: NDArray[np.float64]
    ok: NDArray[np.bool_]


@dataclass(frozen=True)
class ImagePoints:
    """Image coordinates found by iteration (0-based, pixel centres at integers).

    ``converged`` is False where the iteration did not meet its tolerance (line and column are
    then NaN or the last iterate); ``iterations`` counts the secant updates of each point.
    """

    line: NDArray[np.float64]
    column: NDArray[np.float64]
    converged: NDArray[np.bool_]
    iterations: NDArray[np.int64]


@dataclass(frozen=True, eq=False)
class PushbroomModel:
    """Rigorous geometry of one pushbroom image (a scene, or a strip of a pass).

    Parameters
    ----------
    epoch
        Origin of every ``t_s`` in the model.
    clock
        Line times.
    ephemeris
        Satellite positions and velocities (ECEF).
    attitude
        Roll, pitch, yaw in SPOT's convention (``levels.geometry.frames``).
    look_angles
        The look-angle table of the band (mirror included).
    n_lines
        Number of lines of the image (for ``inside`` tests and reports).
    ellipsoid
        Reference surface, WGS84 by default.
    """

    epoch: Epoch
    clock: LineClock
    ephemeris: Ephemeris
    attitude: Attitude
    look_angles: LookAngleTable
    n_lines: int
    ellipsoid: Ellipsoid = WGS84

    def __post_init__(self) -> None:
        if self.n_lines < 1:
            raise GeometryError(f"n_lines={self.n_lines}: need at least 1")

    @property
    def n_columns(self) -> int:
        return self.look_angles.n_columns

    def _orientation(
        self, t_s: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """Position ``(N, 3)``, ``ecef_from_orbital`` and ``orbital_from_body`` ``(N, 3, 3)``.

        The one place where ephemeris and attitude meet; callers apply the two rotations in
        turn rather than forming their product.
        """
        r, v = self.ephemeris.interpolate(t_s)
        angles = self.attitude.angles_rad(t_s)
        body = orbital_from_body(angles[:, 0], angles[:, 1], angles[:, 2])
        return r, ecef_from_orbital(r, v), body

    def sight(
        self, line: ArrayLike, column: ArrayLike
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Projection centre and unit line of sight in ECEF of image points, each ``(N, 3)``."""
        line_a, col_a = np.broadcast_arrays(
            np.atleast_1d(np.asarray(line, dtype=np.float64)),
            np.atleast_1d(np.asarray(column, dtype=np.float64)),
        )
        # grids repeat each line and column many times: orient each distinct time once,
        # and look along each distinct column once
        t_u, at = np.unique(self.clock.time_s(line_a.ravel()), return_inverse=True)
        r, axes, body = (x[at] for x in self._orientation(t_u))
        c_u, ac = np.unique(col_a.ravel(), return_inverse=True)
        u = self.look_angles.directions(c_u)[ac]
        los = apply(axes, apply(body, u))
        return r, los

    def image_to_ground(
        self, line: ArrayLike, column: ArrayLike, height_m: ArrayLike = 0.0
    ) -> GroundPoints:
        """Locate image points on the surface at ``height_m`` above the ellipsoid.

        Parameters
        ----------
        line, column
            0-based image coordinates, broadcast together to ``N`` points.
        height_m
            Height of the ground above the ellipsoid at each point (m).

        Returns
        -------
        GroundPoints
            Flattened to ``(N,)``; ``ok`` is False (and coordinates NaN) where the line of
            sight misses the surface or the time lies outside the ephemeris.
        """
        line_a, col_a, h = (
            a.ravel()
            for a in np.broadcast_arrays(
                *(np.atleast_1d(np.asarray(x, dtype=np.float64)) for x in (line, column, height_m))
            )
        )
        r, los = self.sight(line_a, col_a)
        point, ok = self.ellipsoid.intersect(r, los, h)
        lat, lon, hp = self.ellipsoid.to_geodetic(point)
        ok = ok & np.isfinite(lat)
        return GroundPoints(lat, lon, hp, ok)

    def _residual(
        self, line: NDArray[np.float64], g_ecef_m: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Along-track angle residual and column of ground points seen from ``line``."""
        r, axes, body = self._orientation(self.clock.time_s(line))
        # sensor_from_ecef = bodyᵀ · axesᵀ, applied in turn
        w = apply_inverse(body, apply_inverse(axes, g_ecef_m - r))
        with np.errstate(invalid="ignore", divide="ignore"):
            # Look direction ∝ (−tan ψy, tan ψx, −1): divide by −w_z (> 0 below the sensor).
            depth = -w[:, 2]
            psi_x = np.arctan(w[:, 1] / depth)
            psi_y = np.arctan(-w[:, 0] / depth)
            column = self.look_angles.column_of_psi_y(psi_y)
            table_psi_x, _ = self.look_angles.angles_rad(column)
            residual = np.where(depth > 0, psi_x - table_psi_x, np.nan)
        return residual, column

    def ground_to_image(
        self,
        lat_rad: ArrayLike,
        lon_rad: ArrayLike,
        height_m: ArrayLike = 0.0,
        *,
        tol_px: float = 1e-5,
        max_iter: int = 10,
        first_line: ArrayLike | None = None,
    ) -> ImagePoints:
        """Find the image line and column that see ground points, by secant iteration.

        Parameters
        ----------
        lat_rad, lon_rad, height_m
            Geodetic coordinates, broadcast together to ``N`` points.
        tol_px
            Stop when the line step falls below this (pixels); the secant method converges
            superlinearly, so the error then is far smaller than the last step.
        max_iter
            Secant updates allowed; points that need more are returned with
            ``converged = False``.
        first_line
            Starting guess of the line (default: the image's middle line).

        Returns
        -------
        ImagePoints
            Flattened to ``(N,)``.
        """
        lat, lon, h = np.broadcast_arrays(
            *(np.atleast_1d(np.asarray(x, dtype=np.float64)) for x in (lat_rad, lon_rad, height_m))
        )
        g = self.ellipsoid.to_ecef(lat.ravel(), lon.ravel(), h.ravel())
        n = g.shape[0]
        if first_line is None:
            l0 = np.full(n, 0.5 * (self.n_lines - 1))
        else:
            l0 = np.broadcast_to(np.asarray(first_line, dtype=np.float64).ravel(), (n,)).copy()
        f0, _ = self._residual(l0, g)
        l1 = l0 + 1.0
        f1, col1 = self._residual(l1, g)
        line = l1.copy()
        column = col1.copy()
        converged = np.zeros(n, dtype=bool)
        iterations = np.zeros(n, dtype=np.int64)
        active = np.flatnonzero(np.isfinite(f0) & np.isfinite(f1))
        la, fa, lb, fb = l0[active], f0[active], l1[active], f1[active]
        for _ in range(max_iter):
            if active.size == 0:
                break
            slope = (fb - fa) / (lb - la)
            with np.errstate(invalid="ignore", divide="ignore"):
                step = np.where(fb == 0.0, 0.0, -fb / slope)
            lc = lb + step
            iterations[active] += 1
            fc, colc = self._residual(lc, g[active])
            line[active] = lc
            column[active] = colc
            ok = np.isfinite(fc)
            done = ok & (np.abs(step) < tol_px)
            converged[active[done]] = True
            keep = ok & ~done
            active = active[keep]
            la, fa, lb, fb = lb[keep], fb[keep], lc[keep], fc[keep]
        bad = ~converged & ~np.isfinite(line)
        column[bad] = np.nan
        return ImagePoints(line, column, converged, iterations)
