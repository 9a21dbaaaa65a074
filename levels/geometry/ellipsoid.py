"""The WGS84 ellipsoid: geodetic ⇄ ECEF and exact ray intersection at any height.

Angles are radians, heights metres above the ellipsoid; arrays broadcast. Checked against
pyproj (EPSG:4979 ⇄ EPSG:4978) in the tests.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from levels.errors import GeometryError

__all__ = ["WGS84", "Ellipsoid"]


@dataclass(frozen=True)
class Ellipsoid:
    """A reference ellipsoid of revolution.

    Parameters
    ----------
    a_m
        Semi-major axis (m).
    inv_f
        Inverse flattening 1/f.
    """

    a_m: float
    inv_f: float
    name: str = ""

    def __post_init__(self) -> None:
        if not (self.a_m > 0 and self.inv_f > 1):
            raise GeometryError(
                f"ellipsoid a_m={self.a_m}, inv_f={self.inv_f}: need a_m > 0, inv_f > 1"
            )

    @property
    def f(self) -> float:
        return 1.0 / self.inv_f

    @property
    def b_m(self) -> float:
        return self.a_m * (1.0 - self.f)

    @property
    def e2(self) -> float:
        """First eccentricity squared."""
        return self.f * (2.0 - self.f)

    def to_ecef(
        self, lat_rad: ArrayLike, lon_rad: ArrayLike, h_m: ArrayLike = 0.0
    ) -> NDArray[np.float64]:
        """ECEF position (m), shape ``(*broadcast shape, 3)``, of geodetic coordinates."""
        lat, lon, h = np.broadcast_arrays(
            *(np.asarray(x, dtype=np.float64) for x in (lat_rad, lon_rad, h_m))
        )
        sin_lat, cos_lat = np.sin(lat), np.cos(lat)
        n = self.a_m / np.sqrt(1.0 - self.e2 * sin_lat**2)  # prime-vertical radius
        out = np.empty((*lat.shape, 3))
        out[..., 0] = (n + h) * cos_lat * np.cos(lon)
        out[..., 1] = (n + h) * cos_lat * np.sin(lon)
        out[..., 2] = (n * (1.0 - self.e2) + h) * sin_lat
        return out

    def _geodetic(
        self, r_ecef_m: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """``sin φ``, ``cos φ``, the distance to the axis ``p`` and the height of ECEF points.

        Bowring's parametric-latitude iteration, two passes, with every angle carried as
        its unnormalised (cosine, sine) pair: ``tan β = a z / (b p)`` first, then
        ``tan φ = (z + e'² b sin³β) / (p − e² a cos³β)`` and ``tan β = (1 − f) tan φ``. The
        same iterates as with ``arctan2``, ``sin`` and ``cos``, for square roots only.
        """
        x, y, z = r_ecef_m[..., 0], r_ecef_m[..., 1], r_ecef_m[..., 2]
        a, b, e2 = self.a_m, self.b_m, self.e2
        ep2 = e2 / (1.0 - e2)
        p = np.sqrt(x * x + y * y)
        cb, sb = b * p, a * z  # the parametric latitude's first guess
        for _ in range(2):
            q = np.sqrt(cb * cb + sb * sb)
            cb, sb = cb / q, sb / q
            c, s = p - e2 * a * (cb * cb * cb), z + ep2 * b * (sb * sb * sb)
            cb, sb = c, (1.0 - self.f) * s
        q = np.sqrt(c * c + s * s)
        sin_lat, cos_lat = s / q, c / q
        # Height by projection on the normal: well conditioned at every latitude.
        h = p * cos_lat + z * sin_lat - a * np.sqrt(1.0 - e2 * sin_lat**2)
        return sin_lat, cos_lat, p, h

    def to_geodetic(
        self, r_ecef_m: ArrayLike
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """Geodetic latitude, longitude (rad) and height (m) of ECEF points ``(..., 3)``.

        Bowring's parametric-latitude iteration, two passes (:meth:`_geodetic`): 3e-16 rad
        and 5e-9 m from 500 m below the ellipsoid to 1000 km above it (one pass leaves
        1e-9 rad; tested against pyproj).
        """
        r = np.asarray(r_ecef_m, dtype=np.float64)
        sin_lat, cos_lat, _, h = self._geodetic(r)
        return np.arctan2(sin_lat, cos_lat), np.arctan2(r[..., 1], r[..., 0]), h

    def up(self, lat_rad: ArrayLike, lon_rad: ArrayLike) -> NDArray[np.float64]:
        """Unit normal (geodetic up) in ECEF, shape ``(..., 3)``."""
        lat = np.asarray(lat_rad, dtype=np.float64)
        lon = np.asarray(lon_rad, dtype=np.float64)
        return np.stack(
            [np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)], axis=-1
        )

    def intersect(
        self,
        origin_ecef_m: ArrayLike,
        direction_ecef: ArrayLike,
        h_m: ArrayLike = 0.0,
        *,
        tol_m: float = 1e-4,
        max_iter: int = 10,
    ) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        """First intersection of rays with the surface at geodetic height ``h_m``.

        The surface of constant geodetic height is not an ellipsoid: the ellipsoid with
        axes inflated by ``h`` is used only as the first guess (exact at ``h = 0``), then the
        distance along the ray is refined by Newton's method on the geodetic height of the
        point, ``d ← d − (h(P + d u) − h) / (u · n)``, until the step is below ``tol_m``.

        Parameters
        ----------
        origin_ecef_m
            Ray origins, shape ``(N, 3)``, outside the surface.
        direction_ecef
            Ray directions (need not be unit), shape ``(N, 3)``.
        h_m
            Height of the surface above the ellipsoid at each ray (m), broadcast to ``(N,)``.

        Returns
        -------
        point_ecef_m : ndarray, shape ``(N, 3)``
            The intersections; NaN where the ray misses the surface.
        ok : ndarray of bool, shape ``(N,)``
            True where the ray hits and the refinement converged.
        """
        p = np.asarray(origin_ecef_m, dtype=np.float64)
        u = np.asarray(direction_ecef, dtype=np.float64)
        u = u / np.linalg.norm(u, axis=-1, keepdims=True)
        h = np.broadcast_to(np.asarray(h_m, dtype=np.float64), p.shape[:-1])
        a = self.a_m + h
        b = self.b_m + h
        # Quadratic |(P + d u) / (a, a, b)|² = 1 for the inflated ellipsoid.
        qa = (u[..., 0] ** 2 + u[..., 1] ** 2) / a**2 + u[..., 2] ** 2 / b**2
        qb = 2.0 * (
            (p[..., 0] * u[..., 0] + p[..., 1] * u[..., 1]) / a**2 + p[..., 2] * u[..., 2] / b**2
        )
        qc = (p[..., 0] ** 2 + p[..., 1] ** 2) / a**2 + p[..., 2] ** 2 / b**2 - 1.0
        disc = qb * qb - 4.0 * qa * qc
        hit = disc >= 0.0
        with np.errstate(invalid="ignore"):
            # Numerically stable nearer root of the quadratic.
            d = (2.0 * qc) / (-qb + np.sqrt(np.where(hit, disc, np.nan)))
        hit &= d > 0.0
        d = np.where(hit, d, np.nan)
        ok = hit.copy()
        if np.any(h != 0.0):
            ok[:] = False
            for _ in range(max_iter):
                point = p + d[..., None] * u
                sin_lat, cos_lat, axis_m, hp = self._geodetic(point)
                # u · up, up = (cos φ cos λ, cos φ sin λ, sin φ) with cos λ = x / p
                k = np.divide(cos_lat, axis_m, out=np.zeros_like(axis_m), where=axis_m > 0)
                cos_incidence = (
                    k * (u[..., 0] * point[..., 0] + u[..., 1] * point[..., 1])
                    + sin_lat * u[..., 2]
                )
                step = (hp - h) / cos_incidence
                d = d - step
                ok = hit & (np.abs(step) < tol_m)
                if np.all(ok | ~hit):
                    break
        point = p + d[..., None] * u
        return point, ok


#: World Geodetic System 1984.
WGS84 = Ellipsoid(a_m=6378137.0, inv_f=298.257223563, name="WGS84")
