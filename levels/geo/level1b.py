"""Level 1B geometry: INPE's one-dimensional inverse mapping in a tangent plane.

Paper ``004_…`` §2.1. The corrected image lies in the plane tangent to the reference surface
at the scene centre. Its axes: ``Y`` along the centre line projected on the plane, eastward;
``X`` orthogonal to it in the plane, southward. Corrected lines run along ``Y`` and columns
along ``X``, at the nominal resolution. The inverse mapping from a corrected pixel ``(I, J)``
to the raw image ``(L, C)`` is one-dimensional::

    L = f(I)            # INPE eq. (1): every raw line is a straight line of the plane
    C = g(J − h(I))     # INPE eq. (2), with the skew of eq. (3)
    ΔJ = h(I)           # INPE eq. (3): the shift of each line (Earth rotation, attitude)

``f`` and ``h`` are cubic polynomials fitted on 61 breakpoints along the raw centre column,
``g`` on 61 along the raw centre line, each breakpoint located by the photogrammetric model
intersected with the plane. ``h`` is also how many black pixels the corrected line begins
with (the left skew).

Corrected image coordinates: ``I = x / res − i_origin``, ``J = y / res − j_origin`` with
``(x, y)`` metres along ``X`` and ``Y`` from the tangency point; integer ``(I, J)`` are pixel
centres, ``(0, 0)`` the first pixel of the first line.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from levels.errors import GeometryError, ProductError
from levels.geo.misfit import raw_error_stats
from levels.geo.polynomial import Poly1D
from levels.geo.scenes import SceneGeometry
from levels.geometry.model import PushbroomModel
from levels.threads import one_blas_thread

__all__ = ["N_BREAKPOINTS", "Level1BGeometry", "TangentPlane", "level1b_geometry", "raw_border"]

#: INPE's two sets of 61 breakpoints.
N_BREAKPOINTS = 61


@dataclass(frozen=True, eq=False)
class TangentPlane:
    """A plane through ``origin_ecef_m`` with unit axes ``x_axis`` (south), ``y_axis``
    (east) and ``normal`` (up), all ECEF."""

    origin_ecef_m: NDArray[np.float64]
    x_axis: NDArray[np.float64]
    y_axis: NDArray[np.float64]
    normal: NDArray[np.float64]

    def intersect(
        self, r_ecef_m: NDArray[np.float64], los_ecef: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Plane coordinates ``x, y`` (m) where the rays ``r + t·los`` meet the plane."""
        with np.errstate(divide="ignore", invalid="ignore"):
            t = ((self.origin_ecef_m - r_ecef_m) @ self.normal) / (los_ecef @ self.normal)
        d = r_ecef_m + t[:, None] * los_ecef - self.origin_ecef_m
        bad = ~(t > 0)
        x, y = d @ self.x_axis, d @ self.y_axis
        x[bad] = np.nan
        y[bad] = np.nan
        return x, y

    def to_ecef(self, x_m: ArrayLike, y_m: ArrayLike) -> NDArray[np.float64]:
        """ECEF points of plane coordinates, shape ``(N, 3)``."""
        x = np.atleast_1d(np.asarray(x_m, dtype=np.float64)).ravel()
        y = np.atleast_1d(np.asarray(y_m, dtype=np.float64)).ravel()
        return self.origin_ecef_m + x[:, None] * self.x_axis + y[:, None] * self.y_axis

    def as_array(self) -> NDArray[np.float64]:
        """Rows origin, X, Y, normal: shape (4, 3)."""
        return np.stack([self.origin_ecef_m, self.x_axis, self.y_axis, self.normal])

    @classmethod
    def from_array(cls, a: ArrayLike) -> TangentPlane:
        """The inverse of :meth:`as_array`."""
        a = np.asarray(a, dtype=np.float64)
        if a.shape != (4, 3):
            raise ValueError(f"a tangent plane is 4 × 3 numbers, got {a.shape}")
        return cls(*(row.copy() for row in a))


def raw_border(
    n_lines: int, n_columns: int, per_side: int = N_BREAKPOINTS
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Lines and columns of points along the four edges of a raw image."""
    s = np.linspace(0.0, 1.0, per_side)
    nl, nc = n_lines - 1.0, n_columns - 1.0
    line = np.concatenate([0 * s, s * nl, 0 * s + nl, s * nl])
    col = np.concatenate([s * nc, 0 * s + nc, s * nc, 0 * s])
    return line, col


@dataclass(frozen=True, eq=False)
class Level1BGeometry:
    """Everything COR needs for level 1B, and what it was fitted on.

    ``centre_column_breakpoints`` and ``centre_line_breakpoints`` have columns
    ``(L, C, I, J)``, one row per breakpoint.
    """

    plane: TangentPlane
    pixel_size_m: float
    n_rows: int
    n_cols: int
    i_origin: float
    j_origin: float
    f: Poly1D
    g: Poly1D
    h: Poly1D
    centre_column_breakpoints: NDArray[np.float64]
    centre_line_breakpoints: NDArray[np.float64]
    n_raw_lines: int
    n_raw_columns: int

    def raw_of(self, i: ArrayLike, j: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Raw ``(L, C)`` of corrected pixels ``(I, J)`` (INPE eqs. 1–3)."""
        i_a, j_a = np.broadcast_arrays(
            np.asarray(i, dtype=np.float64), np.asarray(j, dtype=np.float64)
        )
        return self.f(i_a), self.g(j_a - self.h(i_a))  # INPE eqs. (1)–(3)

    def corrected_of(
        self, line: ArrayLike, column: ArrayLike
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Corrected ``(I, J)`` of raw pixels ``(L, C)``: the polynomials inverted."""
        la, ca = np.broadcast_arrays(
            np.asarray(line, dtype=np.float64), np.asarray(column, dtype=np.float64)
        )
        bl, bc = self.centre_column_breakpoints, self.centre_line_breakpoints
        i = self.f.solve(la, np.interp(la, bl[:, 0], bl[:, 2]))
        if bc[-1, 1] > bc[0, 1]:
            j0 = np.interp(ca, bc[:, 1], bc[:, 3])
        else:
            j0 = np.interp(ca, bc[::-1, 1], bc[::-1, 3])
        j = self.g.solve(ca, j0) + self.h(i)
        return i, j

    def plane_xy(
        self, i: ArrayLike, j: ArrayLike
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Plane coordinates (m) of corrected pixels."""
        return (
            (np.asarray(i, dtype=np.float64) + self.i_origin) * self.pixel_size_m,
            (np.asarray(j, dtype=np.float64) + self.j_origin) * self.pixel_size_m,
        )

    def ij_of_plane(
        self, x_m: ArrayLike, y_m: ArrayLike
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Corrected pixel coordinates of plane points."""
        return (
            np.asarray(x_m, dtype=np.float64) / self.pixel_size_m - self.i_origin,
            np.asarray(y_m, dtype=np.float64) / self.pixel_size_m - self.j_origin,
        )

    @staticmethod
    def product_tree(bands: dict[str, Level1BGeometry]) -> dict[str, object]:
        """The ``geometry/level_1b`` tree of a product whose bands have these geometries
        (they share the first band's plane and grid; ``docs/products.md``)."""
        g = next(iter(bands.values()))
        return {
            "pixel_size_m": g.pixel_size_m,
            "i_origin": g.i_origin,
            "j_origin": g.j_origin,
            "n_rows": g.n_rows,
            "n_cols": g.n_cols,
            "n_raw_lines": g.n_raw_lines,
            "n_raw_columns": g.n_raw_columns,
            "plane_ecef_m": g.plane.as_array(),
            "plane_note": "rows: origin, X (south), Y (east), normal (up); ECEF",
            "polynomial_note": "[centre, scale, c0..c3]: p(x) = sum c_k ((x - centre)/"
            "scale)^k; L = f(I), C = g(J - h(I))",
            "breakpoints_note": "columns L, C, I, J",
            "bands": {
                b: {
                    "f": band.f.as_array(),
                    "g": band.g.as_array(),
                    "h": band.h.as_array(),
                    "centre_column_breakpoints": band.centre_column_breakpoints,
                    "centre_line_breakpoints": band.centre_line_breakpoints,
                }
                for b, band in bands.items()
            },
        }

    @classmethod
    def from_tree(cls, tree: dict[str, Any], band: str | None = None) -> Level1BGeometry:
        """The geometry of ``band`` (the first by default) from a product's
        ``geometry/level_1b`` tree; :class:`ProductError` names what is missing or bad."""
        try:
            bands = tree["bands"]
            b = bands[band if band is not None else next(iter(bands))]
            return cls(
                plane=TangentPlane.from_array(tree["plane_ecef_m"]),
                pixel_size_m=float(tree["pixel_size_m"]),
                n_rows=int(tree["n_rows"]),
                n_cols=int(tree["n_cols"]),
                i_origin=float(tree["i_origin"]),
                j_origin=float(tree["j_origin"]),
                f=Poly1D.from_array(b["f"]),
                g=Poly1D.from_array(b["g"]),
                h=Poly1D.from_array(b["h"]),
                centre_column_breakpoints=b["centre_column_breakpoints"],
                centre_line_breakpoints=b["centre_line_breakpoints"],
                n_raw_lines=int(tree["n_raw_lines"]),
                n_raw_columns=int(tree["n_raw_columns"]),
            )
        except (KeyError, TypeError, ValueError, StopIteration) as exc:
            raise ProductError(
                f"level 1B geometry tree is incomplete or damaged ({type(exc).__name__}: {exc})"
            ) from None

    def approximation_error(self, model: PushbroomModel, per_side: int = 41) -> dict[str, float]:
        """How far the polynomials put raw pixels from the rigorous model, in raw pixels.

        A lattice of corrected pixels is mapped by the polynomials to ``(L, C)`` and, by the
        model, from its plane point back to the raw image by iteration; points whose
        polynomial ``(L, C)`` falls outside the raw image are left out.
        """
        i, j = np.meshgrid(
            np.linspace(0, self.n_rows - 1, per_side),
            np.linspace(0, self.n_cols - 1, per_side),
            indexing="ij",
        )
        lp, cp = self.raw_of(i.ravel(), j.ravel())
        inside = (
            (lp >= 0) & (lp <= self.n_raw_lines - 1) & (cp >= 0) & (cp <= self.n_raw_columns - 1)
        )
        x, y = self.plane_xy(i.ravel()[inside], j.ravel()[inside])
        lat, lon, h = model.ellipsoid.to_geodetic(self.plane.to_ecef(x, y))
        exact = model.ground_to_image(lat, lon, h, first_line=lp[inside])
        dl = lp[inside] - exact.line
        dc = cp[inside] - exact.column
        ok = exact.converged
        return raw_error_stats(dl[ok], dc[ok])


@one_blas_thread
def level1b_geometry(
    scene: SceneGeometry,
    pixel_size_m: float,
    n_breakpoints: int = N_BREAKPOINTS,
    band: str | None = None,
    like: Level1BGeometry | None = None,
) -> Level1BGeometry:
    """GEO for level 1B: tangent plane, breakpoints, polynomials f, g, h, image size.

    ``band`` names the band whose model is fitted (the first by default). ``like``, the
    geometry of another band of the scene, gives the plane and the output grid to share:
    the XS bands of a product are then registered on one grid, each through its own f, g,
    h (their look angles differ by a few tenths of a pixel).
    """
    model = scene.models[band] if band is not None else scene.model
    nl, nc = scene.cut.n_lines, model.n_columns
    lc, cc = scene.cut.centre_line, 0.5 * (nc - 1)
    k = np.linspace(0.0, 1.0, n_breakpoints)
    # centre line breakpoints fix Y (INPE: "Y axis corresponding to the center line")
    line_c = np.full(n_breakpoints, lc)
    col_c = k * (nc - 1)
    line_k = k * (nl - 1)
    bl, bc = raw_border(nl, nc)
    # centre line, centre column and border, sighted in one call
    r, los = model.sight(
        np.concatenate([line_c, line_k, bl]),
        np.concatenate([col_c, np.full(n_breakpoints, cc), bc]),
    )
    n = n_breakpoints
    plane = _tangent_plane(scene, model, r[:n], los[:n]) if like is None else like.plane
    x, y = plane.intersect(r, los)
    xl, yl, xk, yk, xb, yb = x[:n], y[:n], x[n : 2 * n], y[n : 2 * n], x[2 * n :], y[2 * n :]
    if not np.all(np.isfinite(np.concatenate([xl, yl, xk, yk, xb, yb]))):
        raise GeometryError("level 1B: a breakpoint's line of sight misses the tangent plane")
    res = float(pixel_size_m)
    if like is None:
        i_origin = float(np.floor(xb.min() / res))
        j_origin = float(np.floor(yb.min() / res))
        n_rows = int(np.floor(xb.max() / res) - i_origin) + 1
        n_cols = int(np.floor(yb.max() / res) - j_origin) + 1
    else:
        if like.pixel_size_m != res:
            raise GeometryError(
                f"level 1B: pixel size {res} m differs from the shared grid's {like.pixel_size_m} m"
            )
        i_origin, j_origin, n_rows, n_cols = like.i_origin, like.j_origin, like.n_rows, like.n_cols
    ik, jk = xk / res - i_origin, yk / res - j_origin
    il, jl = xl / res - i_origin, yl / res - j_origin
    f = Poly1D.fit(ik, line_k, 3)  # INPE eq. (1): L = f(I)
    h = Poly1D.fit(ik, jk - (-j_origin), 3)  # INPE eq. (3): ΔJ = h(I), from J_centre
    g = Poly1D.fit(jl - h(il), col_c, 3)  # INPE eq. (2): C = g(J − h(I))
    return Level1BGeometry(
        plane=plane,
        pixel_size_m=res,
        n_rows=n_rows,
        n_cols=n_cols,
        i_origin=i_origin,
        j_origin=j_origin,
        f=f,
        g=g,
        h=h,
        centre_column_breakpoints=np.stack([line_k, np.full(n_breakpoints, cc), ik, jk], 1),
        centre_line_breakpoints=np.stack([line_c, col_c, il, jl], 1),
        n_raw_lines=nl,
        n_raw_columns=nc,
    )


def _tangent_plane(
    scene: SceneGeometry, model: PushbroomModel, r: NDArray[np.float64], los: NDArray[np.float64]
) -> TangentPlane:
    """The plane tangent to the reference surface at the scene centre, Y along the centre
    line (``r``, ``los``: its breakpoints' sight) eastward, X = Y × up southward."""
    ell = model.ellipsoid
    origin = ell.to_ecef(
        scene.centre_lat_rad, scene.centre_lon_rad, scene.reference_height_m
    ).reshape(3)
    up = ell.up(scene.centre_lat_rad, scene.centre_lon_rad).reshape(3)
    east = np.array([-np.sin(scene.centre_lon_rad), np.cos(scene.centre_lon_rad), 0.0])
    draft = TangentPlane(origin, np.cross(east, up), east, up)
    x0, y0 = draft.intersect(r, los)
    d = draft.to_ecef(x0[-1], y0[-1])[0] - draft.to_ecef(x0[0], y0[0])[0]
    y_axis = d - (d @ up) * up
    y_axis /= np.linalg.norm(y_axis)
    if y_axis @ east < 0:
        y_axis = -y_axis
    return TangentPlane(origin, np.cross(y_axis, up), y_axis, up)
