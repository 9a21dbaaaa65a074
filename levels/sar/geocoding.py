"""Geocoding a frame onto a map grid (GEC on the ellipsoid, GTC over a DEM): anchors located
exactly every ``ANCHOR_STEP_PX`` output pixels at ``HEIGHT_LEVELS`` heights, polynomials in
height between them, the per-pixel kernel sampling the DEM, the slant image and the masks.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from typing import Any, NamedTuple

import numba as nb
import numpy as np
from numpy.typing import NDArray

from levels.errors import GeometryError
from levels.geo.inverse_grid import bilinear_grid
from levels.geo.maps import MapGrid
from levels.geometry.dem import Dem
from levels.geometry.ellipsoid import WGS84
from levels.sar.annotation import (
    ANCHOR_STEP_PX,
    HEIGHT_LEVELS,
    MASK_TOLERANCE_PX,
    SarAnnotation,
    SarImage,
    _half_span,
    _in_height,
    _to_geo,
)
from levels.sar.masks import _FRAME_MARGIN_PX, _profiles, mask_oversample
from levels.threads import over_blocks


@dataclass(frozen=True, eq=False)
class _Model:
    """The geocoding's model of an image: its anchors' (line, column, look) every ``step``
    output pixels as polynomials in the scaled height (:func:`_in_height`) through the
    height ``levels``, and the image's shape."""

    coef: NDArray[np.float64]
    step: int
    levels: NDArray[np.float64]
    image_shape: tuple[int, int]

    @property
    def h_mid(self) -> float:
        return float(np.mean(self.levels))

    @property
    def inv_span(self) -> float:
        return 1.0 / _half_span(self.levels)

    def at(self, i: NDArray, j: NDArray, h: NDArray) -> tuple[NDArray, NDArray]:
        """(line, column) of output pixels ``(i, j)`` at heights ``h``: the kernel's
        arithmetic in numpy (the anchors bilinearly, the polynomial at ``h``)."""
        rows, cols = (np.arange(n, dtype=np.float64) * self.step for n in self.coef.shape[2:])
        x = (np.asarray(h, dtype=np.float64) - self.h_mid) * self.inv_span
        out = []
        for q in range(2):
            v = np.zeros(np.shape(i))
            for k in range(self.coef.shape[0] - 1, -1, -1):  # Horner
                v = v * x + bilinear_grid(rows, cols, self.coef[k, q], i, j)
            out.append(v)
        return out[0], out[1]


class _Anchors(NamedTuple):
    """The anchors :func:`_kernel_geocode` reads (numba takes a named tuple of arrays and
    numbers as it takes its fields)."""

    step: int  # output pixels between anchors
    coef: NDArray[np.float64]  # (levels, 3, na, nb): line, column, look in height
    h_mid: float  # the height polynomials' centre (m)
    inv_span: float  # 1 / their half-range (m⁻¹)
    xs: NDArray[np.float64]  # the height levels, scaled
    image_shape: tuple[int, int]  # the slant image's lines and samples


class _Surface(NamedTuple):
    """The DEM :func:`_kernel_geocode` samples (``on``), as level 3 does."""

    on: bool
    nodes: NDArray[np.float64]  # (2, na, nb): the DEM's (row, column) at output nodes
    step: int  # output pixels between those nodes
    z: NDArray[np.float64]  # the DEM's heights above the ellipsoid


class _Profiles(NamedTuple):
    """The terrain's profiles each pixel is judged against for the masks (``on``)."""

    on: bool
    profiles: NDArray[np.float32]  # (rows, samples, 3): :func:`levels.sar.masks._profiles`
    frame: NDArray[np.float64]  # (line0, per, u0, du)
    tol_r: float  # range tolerance (columns)
    tol_look: float  # look angle tolerance (rad)


def _geocode_rows(
    model: _Model,
    height: NDArray[np.float32],
    surface: tuple[NDArray, NDArray, float, float] | None = None,
    image: NDArray | None = None,
    out: NDArray[np.float32] | None = None,
    located: tuple[NDArray, NDArray] | None = None,
    masks: tuple[NDArray, NDArray, float, float] | None = None,
) -> tuple[NDArray[np.bool_], NDArray[np.bool_]]:
    """:func:`_kernel_geocode` over the output's rows on threads: the heights from the DEM
    ``surface`` (:func:`_dem_surface`) into ``height``, or read from it; the ``image``
    into ``out``; the location into ``located``; the layover and shadow masks against
    ``masks`` (profiles, frame, tolerances: :func:`_profiles`), returned (1 × 1
    without)."""
    n_rows, n_cols = height.shape
    none2, none3 = np.empty((1, 1)), np.empty((2, 2, 3), dtype=np.float32)
    nodes, z = (surface[0], surface[1]) if surface is not None else (np.zeros((2, 2, 2)), none2)
    profiles, frame, tol_r, tol_look = masks or (none3, np.array([0.0, 1.0, 0.0, 1.0]), 0.0, 0.0)
    shape = (n_rows, n_cols) if masks is not None else (1, 1)
    layover, shadow = np.zeros(shape, dtype=np.bool_), np.zeros(shape, dtype=np.bool_)
    image32 = none2.astype(np.float32) if image is None else image
    from levels.geo.level3 import DEM_COORD_STEP

    over_blocks(
        _kernel_geocode,
        n_rows,
        _Anchors(
            model.step,
            model.coef,
            model.h_mid,
            model.inv_span,
            (model.levels - model.h_mid) * model.inv_span,
            model.image_shape,
        ),
        _Surface(surface is not None, nodes, DEM_COORD_STEP, z),
        _Profiles(masks is not None, profiles, frame, tol_r, tol_look),
        height,
        np.ascontiguousarray(image32, dtype=np.float32),
        out is not None,
        out if out is not None else image32,
        located is not None,
        *(located or (none2, none2)),
        layover,
        shadow,
        grain=64,
    )
    return layover, shadow


@dataclass(frozen=True, eq=False)
class Geocoded:
    """A geocoded SAR image: intensity on a map grid (NaN outside the frame or over a
    void), each pixel's height (float32: a millimetre; NaN outside the frame over a DEM),
    the anchor grid's error (slant pixels), and the layover and shadow masks of the
    terrain the DEM gives (the standard definitions, :mod:`levels.sar.masks`; none on the
    ellipsoid); each pixel's (line, column) in the slant image on first asking (the
    geocoding's own arithmetic, from its anchors: 1.5 GB for a full frame that the
    product does not hold)."""

    grid: MapGrid
    intensity: NDArray[np.float32]
    height_m: NDArray[np.float32]
    kind: str  # "GEC" or "GTC"
    anchor_error: dict[str, float]
    layover: NDArray[np.bool_]
    shadow: NDArray[np.bool_]
    #: the anchors' polynomials in height (the geocoding's model of the image)
    model: _Model = field(repr=False)

    @cached_property
    def _located(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        line, col = (np.empty(self.grid.shape) for _ in range(2))
        _geocode_rows(self.model, self.height_m, located=(line, col))
        return line, col

    @property
    def line(self) -> NDArray[np.float64]:
        """Each pixel's line in the slant image (NaN over a void)."""
        return self._located[0]

    @property
    def column(self) -> NDArray[np.float64]:
        """Each pixel's column in the slant image (NaN over a void)."""
        return self._located[1]


def _exact(
    ann: SarAnnotation,
    grid: MapGrid,
    i: NDArray,
    j: NDArray,
    h: NDArray,
    t0_s: NDArray | None = None,
) -> tuple[NDArray, NDArray, NDArray, NDArray]:
    """The exact (line, column) of output pixels ``(i, j)`` at heights ``h``, the look
    angle there (rad, at the antenna from its geocentric nadir) and the time (s), from
    first guesses ``t0_s`` of it."""
    x, y = grid.map_of(i, j)
    lon, lat = _to_geo(grid).transform(np.ravel(x), np.ravel(y))
    return _exact_geo(ann, np.radians(lat), np.radians(lon), np.ravel(h), np.shape(i), t0_s)


def _exact_geo(
    ann: SarAnnotation,
    lat: NDArray,
    lon: NDArray,
    h: NDArray,
    shape: tuple[int, ...],
    t0_s: NDArray | None = None,
) -> tuple[NDArray, NDArray, NDArray, NDArray]:
    """:func:`_exact` of geodetic points (rad, flat), shaped ``shape``."""
    p = WGS84.to_ecef(lat, lon, h)
    t, r, ok, s = ann._solve(p, t0_s)
    cos_look = np.sum(-s * (p - s), axis=1) / (np.linalg.norm(s, axis=1) * r)
    look = np.arccos(np.clip(cos_look, -1.0, 1.0))
    line = np.where(ok, ann.line_of(t), np.nan).reshape(shape)
    col = np.where(ok, ann.column_of(r), np.nan).reshape(shape)
    return line, col, np.where(ok, look, np.nan).reshape(shape), t.reshape(shape)


def _anchors(
    ann: SarAnnotation, grid: MapGrid, step_px: int, levels: NDArray
) -> NDArray[np.float64]:
    """The exact (line, column, look) of the anchors (every ``step_px`` output pixels, one
    step beyond the grid) at each height level, ``(levels, 3, rows, columns)``. Newton's
    first guesses: every eighth anchor solved from the frame's middle, the times between
    bilinearly; each level then from the level before."""
    na = -(-(grid.n_rows - 1) // step_px) + 2
    nb = -(-(grid.n_cols - 1) // step_px) + 2
    ai, aj = np.meshgrid(
        np.arange(na, dtype=np.float64) * step_px,
        np.arange(nb, dtype=np.float64) * step_px,
        indexing="ij",
    )
    x, y = grid.map_of(ai, aj)
    lon, lat = (np.radians(v) for v in _to_geo(grid).transform(np.ravel(x), np.ravel(y)))
    coarse = (slice(None, None, 8), slice(None, None, 8))
    lat_c, lon_c = (v.reshape(ai.shape)[coarse] for v in (lat, lon))
    h_c = np.full(lat_c.size, levels[0])
    t_c = _exact_geo(ann, lat_c.ravel(), lon_c.ravel(), h_c, lat_c.shape)[3]
    t = None
    if min(t_c.shape) > 1:
        t = bilinear_grid(ai[coarse][:, 0], aj[coarse][0], t_c, ai, aj)
    out = []
    for h in levels:
        *q, t = _exact_geo(ann, lat, lon, np.full(lat.shape, h), ai.shape, t)
        out.append(q)
    return np.array(out, dtype=np.float64)


def _dem_surface(
    dem: Dem, grid: MapGrid
) -> tuple[NDArray[np.float64], NDArray[np.float64], float, float]:
    """The DEM as the geocoding reads it (as level 3 does): its (row, column) through PROJ
    at output pixels every ``DEM_COORD_STEP``, its heights above the ellipsoid, and their
    lowest and highest over the DEM's cells under the grid; :class:`GeometryError` if it
    has none there."""
    from levels.geo.level3 import DEM_COORD_STEP, _dem_coordinates, _ellipsoidal

    nodes = np.ascontiguousarray(_dem_coordinates(dem, grid, DEM_COORD_STEP), dtype=np.float64)
    z = np.ascontiguousarray(_ellipsoidal(dem), dtype=np.float64)
    nr, nc = z.shape
    r0, c0 = (
        int(np.clip(np.floor(np.nanmin(a)), 0, n - 1)) for a, n in zip(nodes, z.shape, strict=True)
    )
    r1, c1 = (
        int(np.clip(np.ceil(np.nanmax(a)), 0, n - 1)) for a, n in zip(nodes, z.shape, strict=True)
    )
    under = z[r0 : r1 + 1, c0 : c1 + 1]
    covers = (
        np.nanmax(nodes[0]) >= 0 and np.nanmin(nodes[0]) <= nr - 1
        and np.nanmax(nodes[1]) >= 0 and np.nanmin(nodes[1]) <= nc - 1
    )  # fmt: skip
    if not covers or not np.isfinite(under).any():
        raise GeometryError("GTC: the DEM does not cover the output grid")
    return nodes, z, float(np.nanmin(under)), float(np.nanmax(under))


@nb.njit(cache=True, nogil=True)
def _kernel_geocode(
    lo, hi, anc, srf, prof, height, image, imaged, out, located, line, col, layover, shadow
):  # fmt: skip
    """Rows ``lo … hi − 1`` of the output: each pixel's (line, column, look) from the
    anchors (bilinear, then the polynomial in height through the levels,
    :func:`_in_height`: ``anchors`` its coefficients, ``x = (h − h_mid) · inv_span``), the
    slant image bilinearly there (NaN outside it or over a void). The anchors are
    interpolated down the row once for each anchor column, then along the row per pixel.
    What is written: the image (``imaged``: ``out``), the location (``located``:
    ``line`` and ``col``), the masks (``masks``).

    ``from_dem``: each pixel's height is the DEM's, written to ``height``, read as level 3
    samples a DEM (its (row, column) bilinearly from ``dem_nodes`` every ``dem_step``
    output pixels, the ellipsoidal heights ``z`` bilinearly there), NaN outside the DEM,
    over a void, or outside the frame: beyond the anchor cells where no height level
    (``xs``, scaled as ``x``) lands within ``_FRAME_MARGIN_PX`` of the slant image of
    ``image_shape`` (a third of a frame's bounding box, not sampled, located nor judged);
    else ``height`` is read.

    ``masks``: each pixel also judged against the terrain's profiles (:func:`_profiles`:
    ``profiles`` their running maxima of the range and look angle outwards and minima
    of the range inwards, rows of lines ``frame[0] + k·frame[1]``, columns of ground
    range ``frame[2] + m·frame[3]``: the column at the middle height): the two rows about
    its line, interpolated, up to the sample before it (from there on after it):
    the standard definitions (:mod:`levels.sar.masks`), ``tol_r`` and ``tol_look`` their
    tolerances; none where a row has no terrain there (the grid's or the DEM's edge).
    The inputs grouped: ``anc`` (:class:`_Anchors`), ``srf`` (:class:`_Surface`),
    ``prof`` (:class:`_Profiles`)."""
    step, anchors, h_mid, inv_span, xs, image_shape = anc
    from_dem, dem_nodes, dem_step, z = srf
    masks, profiles, frame, tol_r, tol_look = prof
    n_lev, _, na, nb = anchors.shape
    n_l, n_s = image_shape
    n_p, n_u = profiles.shape[0], profiles.shape[1]
    nda, ndb = dem_nodes.shape[1], dem_nodes.shape[2]
    nr, nc = z.shape
    n_cols = height.shape[1]
    at_row = np.empty((n_lev, 3, nb))
    dem_row = np.empty((2, ndb))
    inv_step, inv_dem = 1.0 / step, 1.0 / dem_step
    inv_per, inv_du = 1.0 / frame[1], 1.0 / frame[3]
    m = _FRAME_MARGIN_PX
    for i in range(lo, hi):
        a = min(i // step, na - 2)
        fu = (i - a * step) * inv_step
        for k in range(n_lev):
            for c in range(3):
                for b in range(nb):
                    at_row[k, c, b] = (1.0 - fu) * anchors[k, c, a, b] + fu * anchors[
                        k, c, a + 1, b
                    ]
        j_lo, j_hi = 0, n_cols
        if from_dem:  # the anchor columns where the frame is, at some height
            b_lo, b_hi = nb, -1
            for b in range(nb):
                for x in xs:
                    q0 = q1 = 0.0
                    for k in range(n_lev - 1, -1, -1):
                        q0 = q0 * x + at_row[k, 0, b]
                        q1 = q1 * x + at_row[k, 1, b]
                    if -m <= q0 <= n_l - 1 + m and -m <= q1 <= n_s - 1 + m:
                        b_lo, b_hi = min(b_lo, b), max(b_hi, b)
            j_lo = min(max((b_lo - 1) * step, 0), n_cols)
            j_hi = max(min((b_hi + 1) * step + 1, n_cols), j_lo)
        if from_dem:
            da = min(i // dem_step, nda - 2)
            su = (i - da * dem_step) * inv_dem
            for c in range(2):
                for b in range(ndb):
                    dem_row[c, b] = (1.0 - su) * dem_nodes[c, da, b] + su * dem_nodes[c, da + 1, b]
        b = db = 0  # the anchor and DEM node columns about j, and j's offsets from them
        jb = jd = -1
        for j in range(n_cols):
            jb += 1  # (counted, not divided: an integer division per pixel costs)
            if jb == step and b < nb - 2:
                b, jb = b + 1, 0
            jd += 1
            if jd == dem_step and db < ndb - 2:
                db, jd = db + 1, 0
            if j < j_lo or j >= j_hi:
                h = np.nan
            elif from_dem:
                sv = jd * inv_dem
                drow = (1.0 - sv) * dem_row[0, db] + sv * dem_row[0, db + 1]
                dcol = (1.0 - sv) * dem_row[1, db] + sv * dem_row[1, db + 1]
                h = np.nan
                if 0.0 <= drow <= nr - 1 and 0.0 <= dcol <= nc - 1:
                    p0 = min(int(drow), nr - 2)
                    r0 = min(int(dcol), nc - 2)
                    s, t = drow - p0, dcol - r0
                    h = (1 - s) * ((1 - t) * z[p0, r0] + t * z[p0, r0 + 1]) + s * (
                        (1 - t) * z[p0 + 1, r0] + t * z[p0 + 1, r0 + 1]
                    )
            else:
                h = height[i, j]
            if from_dem:
                height[i, j] = h
            if not (h == h):
                if imaged:
                    out[i, j] = np.nan
                if located:
                    line[i, j] = np.nan
                    col[i, j] = np.nan
                continue
            fv = jb * inv_step
            gv = 1.0 - fv
            x = (h - h_mid) * inv_span
            q0 = q1 = q2 = 0.0
            for k in range(n_lev - 1, -1, -1):  # Horner
                q0 = q0 * x + (gv * at_row[k, 0, b] + fv * at_row[k, 0, b + 1])
                q1 = q1 * x + (gv * at_row[k, 1, b] + fv * at_row[k, 1, b + 1])
                q2 = q2 * x + (gv * at_row[k, 2, b] + fv * at_row[k, 2, b + 1])
            if located:
                line[i, j] = q0
                col[i, j] = q1
            if masks:
                y = (q0 - frame[0]) * inv_per
                mid = gv * at_row[0, 1, b] + fv * at_row[0, 1, b + 1]
                x = (mid - frame[2]) * inv_du
                if 0.0 <= y < n_p - 1 and 0.0 <= x < n_u - 1:
                    r0 = int(y)
                    f = y - r0
                    m0 = int(x)
                    g0 = 1.0 - f
                    near_r = g0 * profiles[r0, m0, 0] + f * profiles[r0 + 1, m0, 0]
                    far_r = g0 * profiles[r0, m0 + 1, 1] + f * profiles[r0 + 1, m0 + 1, 1]
                    near_look = g0 * profiles[r0, m0, 2] + f * profiles[r0 + 1, m0, 2]
                    layover[i, j] = q1 < near_r - tol_r or q1 > far_r + tol_r
                    shadow[i, j] = q2 < near_look - tol_look
            if not imaged:
                continue
            if not (0.0 <= q0 <= n_l - 1 and 0.0 <= q1 <= n_s - 1):
                out[i, j] = np.nan
                continue
            l0 = min(int(q0), n_l - 2)
            c0 = min(int(q1), n_s - 2)
            fl, fc = q0 - l0, q1 - c0
            out[i, j] = (1.0 - fl) * ((1.0 - fc) * image[l0, c0] + fc * image[l0, c0 + 1]) + fl * (
                (1.0 - fc) * image[l0 + 1, c0] + fc * image[l0 + 1, c0 + 1]
            )


def geocode(
    image: SarImage,
    grid: MapGrid,
    dem: Dem | None = None,
    reference_height_m: float = 0.0,
    step_px: int = ANCHOR_STEP_PX,
    masks: bool = True,
) -> Geocoded:
    """``image`` on ``grid``: over ``dem`` (GTC), or on the ellipsoid raised to
    ``reference_height_m`` (GEC) (module docstring); ``masks=False``: no layover and
    shadow (all false), the geometry alone. On the ellipsoid nothing folds: no masks."""
    ann = image.annotation
    if dem is None:
        height = np.full(grid.shape, float(reference_height_m), dtype=np.float32)
        levels = np.array([float(reference_height_m)])
        surface = None
        kind = "GEC"
    else:
        surface = _dem_surface(dem, grid)
        height = np.empty(grid.shape, dtype=np.float32)
        levels = np.linspace(surface[2] - 10.0, surface[3] + 10.0, HEIGHT_LEVELS)
        kind = "GTC"
    anchors = _anchors(ann, grid, step_px, levels)
    # (levels, 3, na, nb): the anchors' (line, column, look) as polynomials in height
    model = _Model(
        np.ascontiguousarray(_in_height(anchors, levels)), int(step_px), levels, ann.shape
    )
    del anchors
    intensity = np.empty(grid.shape, dtype=np.float32)
    judged = None
    if masks and dem is not None and surface is not None:
        profiles, frame = _profiles(
            ann,
            grid,
            model.coef,
            levels,
            dem,
            surface[1],
            mask_oversample(dem, grid),
            step_px,
        )
        tol = (MASK_TOLERANCE_PX, MASK_TOLERANCE_PX * ann.range_spacing_m / ann.near_range_m)
        judged = (profiles, frame, *tol)
    layover, shadow = _geocode_rows(
        model, height, surface, image=image.intensity, out=intensity, masks=judged
    )
    if judged is None:  # nothing folds on the ellipsoid, or nothing was asked
        layover = shadow = np.zeros(grid.shape, dtype=np.bool_)
    # the anchor grid's error: a lattice between the anchors, at each pixel's height
    ci, cj = np.meshgrid(
        np.linspace(0.5 * step_px, grid.n_rows - 1, 23),
        np.linspace(0.5 * step_px, grid.n_cols - 1, 23),
        indexing="ij",
    )
    ch = bilinear_grid(
        np.arange(grid.n_rows, dtype=np.float64),
        np.arange(grid.n_cols, dtype=np.float64),
        height,
        ci,
        cj,
    )
    gl, gc = model.at(ci, cj, ch)
    el, ec, _, _ = _exact(ann, grid, ci, cj, ch)
    e = np.hypot(gl - el, gc - ec)
    e = e[np.isfinite(e)]
    err: dict[str, Any] = {
        "points": int(e.size),
        "rms_px": float(np.sqrt(np.mean(e**2))) if e.size else float("nan"),
        "max_px": float(np.max(e)) if e.size else float("nan"),
    }
    return Geocoded(grid, intensity, height, kind, err, layover, shadow, model)
