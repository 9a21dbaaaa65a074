"""COR's resampling into level 3, the ortho-image: the raw image sampled through level 3's
anchor grids at the terrain's height under each output pixel (:mod:`levels.geo.level3`), the
pixels the relief hides found by a z-buffer along each raw line, on threads over lines.

The raw image is sampled as level 2A samples it (:mod:`levels.cor.resample`: Keys' cubic
convolution, each column at its own segment's line); an output pixel is valid when every raw
pixel it uses is valid, inside the raw image, and not hidden.
"""

from __future__ import annotations

from typing import NamedTuple

import numba as nb
import numpy as np
from numpy.typing import NDArray

from levels.cor.resample import (
    _BLOCK_COLS,
    _BLOCK_ROWS,
    _FAST,
    RESAMPLINGS_2A,
    _byte,
    _keys,
    _lerp,
    _sample_column,
    with_nan,
)
from levels.geo.level3 import HIDDEN_TOLERANCE_PX, Level3Geometry
from levels.threads import over_blocks, thread_count

__all__ = ["Terrain3", "resample_3"]


#: Coefficients of level 3's height polynomial per grid node (:func:`_height_polynomials`):
#: quadratic, through ``levels.geo.level3.HEIGHT_LEVELS`` = 3 levels at most.
_N_POW = 3


@nb.njit(cache=True, inline="always", fastmath=_FAST)
def _quadratic(a0, a1, a2, b0, b1, b2, gv, t):
    """The height polynomial at scaled height ``t``, its coefficients at fraction ``gv``
    between two grid columns (``a`` and ``b``): Horner's rule."""
    return (_lerp(a2, b2, gv) * t + _lerp(a1, b1, gv)) * t + _lerp(a0, b0, gv)


class Terrain3(NamedTuple):
    """What level 3's kernels read of the terrain and the anchor grids, one object for all
    of them (numba takes a named tuple of arrays and numbers as it takes its fields)."""

    step_i: int  # rows of the inverse grid's step
    poly_line: NDArray[np.float64]  # (segments, rows, cols, powers): the line in height
    poly_col: NDArray[np.float64]  # (rows, cols, powers): the column in height
    dem_rc: NDArray[np.float64]  # (2, na, nb): the DEM's (row, column) at output nodes
    inv_dem_step: float  # 1 / the output pixels between those nodes
    cols: NDArray[np.float64]  # (4, output cols): grid cell and fraction, DEM cell and fraction
    dem: NDArray[np.float64]  # the DEM's heights above the ellipsoid
    h0: float  # the height polynomials' centre (m)
    inv_hs: float  # 1 / their half-range (m⁻¹)
    seg_of: NDArray[np.int64]  # the butting segment of each raw column


@nb.njit(cache=True, inline="always", fastmath=_FAST)
def _row_3(r, t, line_row, col_row, rc_row):
    """Level 3's tables of output row ``r`` (``t``: :class:`Terrain3`): the height
    polynomials' coefficients along the row at the inverse grid's columns (per segment for
    the lines), and the DEM (row, column) at the DEM nodes' columns; linear between grid
    rows."""
    step_i, poly_line, poly_col, dem_rc = t.step_i, t.poly_line, t.poly_col, t.dem_rc
    inv_dem_step = t.inv_dem_step
    n_seg, na, nb_, n_pow = poly_line.shape
    a = min(r // step_i, na - 2)
    u = (r - a * step_i) / step_i
    for b in range(nb_):  # loops, not array expressions (as in _kernel_2a)
        for p in range(n_pow):
            col_row[b, p] = (1.0 - u) * poly_col[a, b, p] + u * poly_col[a + 1, b, p]
            for s in range(n_seg):
                line_row[s, b, p] = (1.0 - u) * poly_line[s, a, b, p] + u * poly_line[
                    s, a + 1, b, p
                ]
    x = r * inv_dem_step
    a0 = min(max(int(np.floor(x)), 0), dem_rc.shape[1] - 2)
    w = x - a0
    for q in range(dem_rc.shape[2]):
        for m in range(2):
            rc_row[m, q] = (1.0 - w) * dem_rc[m, a0, q] + w * dem_rc[m, a0 + 1, q]


#: The rows of a level 3 span (:func:`_coords_span`): one quantity of its pixels each.
_S_COLUMN = 0  # raw column
_S_HEIGHT = 1  # terrain height (NaN over a void or outside the DEM or the grid)
_S_SEGMENT = 2  # the first segment a cubic kernel around the column reads
_S_LINE = 3  # that segment's raw line
_S_LINE_NEXT = 4  # the next segment's line (the same unless at a butting)
_S_LINE_NEAREST = 5  # the line at the nearest column
_S_DEM_ROW = _S_LINE  # while the heights are found: the DEM's row, then its column
_S_DEM_COL = _S_LINE_NEXT
_SPAN_ROWS = 6


@nb.njit(cache=True, fastmath=_FAST)
def _coords_span(k_lo, k_hi, line_row, col_row, rc_row, t, span):
    """Output pixels ``k_lo … k_hi − 1`` of the row whose tables are given (:func:`_row_3`;
    ``t``: :class:`Terrain3`),
    on the terrain, into ``span[:, : k_hi − k_lo]`` (:data:`_SPAN_ROWS` × n, its rows named
    ``_S_…``): raw column, terrain height (NaN over a void or outside the DEM or the grid),
    the first segment a cubic kernel around the column reads, its line, the line of the
    next segment (the same line unless at a butting), and the line at the nearest column.

    ``cols`` holds, per output column, the inverse grid's cell and fraction and the DEM
    nodes' cell and fraction. The pixels go by spans, not one call each (a call with arrays
    per pixel costs their reference counts), and each quantity in a loop of its own over
    the span (independent iterations: 35 % faster than one loop with each pixel's chain
    DEM → height → column → segment → line)."""
    cols, dem, h0, inv_hs, seg_of = t.cols, t.dem, t.h0, t.inv_hs, t.seg_of
    nr, nc = dem.shape
    n_cols = seg_of.size
    for k in range(k_lo, k_hi):  # the DEM (row, column), in the line rows for now
        b0 = int(cols[2, k])
        v = cols[3, k]
        span[_S_DEM_ROW, k - k_lo] = _lerp(rc_row[0, b0], rc_row[0, b0 + 1], v)
        span[_S_DEM_COL, k - k_lo] = _lerp(rc_row[1, b0], rc_row[1, b0 + 1], v)
    for j in range(k_hi - k_lo):  # the terrain height: the DEM's bilinear surface
        rr = span[_S_DEM_ROW, j]
        cc = span[_S_DEM_COL, j]
        h = np.nan
        if 0.0 <= rr <= nr - 1 and 0.0 <= cc <= nc - 1:
            p0 = min(int(rr), nr - 2)
            q0 = min(int(cc), nc - 2)
            ds, dt = rr - p0, cc - q0
            h = _lerp(
                _lerp(dem[p0, q0], dem[p0, q0 + 1], dt),
                _lerp(dem[p0 + 1, q0], dem[p0 + 1, q0 + 1], dt),
                ds,
            )
        span[_S_HEIGHT, j] = h
    for k in range(k_lo, k_hi):  # the raw column
        b = int(cols[0, k])
        span[_S_COLUMN, k - k_lo] = _quadratic(
            col_row[b, 0],
            col_row[b, 1],
            col_row[b, 2],
            col_row[b + 1, 0],
            col_row[b + 1, 1],
            col_row[b + 1, 2],
            cols[1, k],
            (span[_S_HEIGHT, k - k_lo] - h0) * inv_hs,
        )
    for k in range(k_lo, k_hi):  # the segments read and their lines
        j = k - k_lo
        c = span[_S_COLUMN, j]
        s0 = 0
        l0 = np.nan
        l1 = np.nan
        if c == c:
            b = int(cols[0, k])
            gv = cols[1, k]
            t = (span[_S_HEIGHT, j] - h0) * inv_hs
            # only the segments of the columns a cubic kernel around c reads (one, or
            # two at a butting): the others' lines are never read
            cf = int(np.floor(c))
            s0 = seg_of[min(max(cf - 1, 0), n_cols - 1)]
            s1 = seg_of[min(max(cf + 2, 0), n_cols - 1)]
            l0 = _quadratic(
                line_row[s0, b, 0],
                line_row[s0, b, 1],
                line_row[s0, b, 2],
                line_row[s0, b + 1, 0],
                line_row[s0, b + 1, 1],
                line_row[s0, b + 1, 2],
                gv,
                t,
            )
            l1 = l0
            if s1 != s0:
                l1 = _quadratic(
                    line_row[s1, b, 0],
                    line_row[s1, b, 1],
                    line_row[s1, b, 2],
                    line_row[s1, b + 1, 0],
                    line_row[s1, b + 1, 1],
                    line_row[s1, b + 1, 2],
                    gv,
                    t,
                )
        span[_S_SEGMENT, j] = s0
        span[_S_LINE, j] = l0
        span[_S_LINE_NEXT, j] = l1
        ci = min(max(int(np.floor(c + 0.5)), 0), n_cols - 1) if c == c else 0
        span[_S_LINE_NEAREST, j] = l0 if seg_of[ci] == s0 else l1


@nb.njit(cache=True, inline="always", fastmath=_FAST)
def _nearest_raw(line, c, n_lines, n_cols):
    """The raw pixel (line, column) nearest to ``(line, c)``, or (−1, −1) outside the raw
    image (NaN: outside)."""
    if c == c and line == line:
        ci = int(np.floor(c + 0.5))
        li = int(np.floor(line + 0.5))
        if 0 <= ci < n_cols and 0 <= li < n_lines:
            return li, ci
    return -1, -1


@nb.njit(cache=True, inline="always", fastmath=_FAST)
def _gap(l1, c1, l2, c2):
    """Raw pixels between two raw positions, along the longer axis (0 if one is NaN)."""
    d = max(abs(l2 - l1), abs(c2 - c1))
    return int(np.ceil(d)) if d == d else 0


@nb.njit(cache=True, fastmath=_FAST)
def _raise_segment(zbuf, n, l1, c1, h1, l2, c2, h2):
    """The terrain between two neighbouring output pixels that land ``n`` raw pixels apart
    (a steep face toward the sensor, a cliff): the raw pixels along the segment between
    them get the heights in between (the DEM surface there, to first order)."""
    n_lines, n_cols = zbuf.shape
    for m in range(1, n):
        f = m / n
        li, ci = _nearest_raw(l1 + f * (l2 - l1), c1 + f * (c2 - c1), n_lines, n_cols)
        if li >= 0:
            z = np.float32(h1 + f * (h2 - h1))
            if z > zbuf[li, ci]:
                zbuf[li, ci] = z


@nb.njit(cache=True, fastmath=_FAST)
def _raise_row(zbuf, span, prev, cur, own):
    """One output row into the z-buffer: each pixel raises its nearest raw pixel to its
    height, and the segments to its left and upper neighbours (``prev``, the row above:
    raw line, column, height) raise the raw pixels between (:func:`_raise_segment`). ``cur``
    receives this row's; ``own=False`` for the row above a block (its neighbours only)."""
    n_lines, n_cols = zbuf.shape
    for k in range(span.shape[1]):
        c = span[_S_COLUMN, k]
        h = span[_S_HEIGHT, k]
        line = span[_S_LINE_NEAREST, k]
        li, ci = _nearest_raw(line, c, n_lines, n_cols)
        if li < 0:
            c = line = h = np.nan
        cur[0, k] = line
        cur[1, k] = c
        cur[2, k] = h
        if not own or li < 0:
            continue
        if h > zbuf[li, ci]:
            zbuf[li, ci] = h
        if k > 0:
            n = _gap(cur[0, k - 1], cur[1, k - 1], line, c)
            if n >= 2:
                _raise_segment(zbuf, n, cur[0, k - 1], cur[1, k - 1], cur[2, k - 1], line, c, h)
        n = _gap(prev[0, k], prev[1, k], line, c)
        if n >= 2:
            _raise_segment(zbuf, n, prev[0, k], prev[1, k], prev[2, k], line, c, h)


@nb.njit(cache=True, nogil=True, fastmath=_FAST)
def _zbuffer_3(lo, hi, zbufs, n_rows, terrain):
    """The highest terrain seen in each raw pixel (every line of sight descends, so the
    highest ground point in a raw pixel is the one it sees), one z-buffer per block of
    output rows (``zbufs``: blocks × raw lines × raw columns, −inf): blocks run in
    parallel without racing, and their maximum is the same whatever the blocks.

    The faces between output pixels count (:func:`_raise_row`): a vertical face has no
    output pixel of its own, but it hides the ground behind it. ``terrain``: :class:`Terrain3`."""
    n_blocks = zbufs.shape[0]
    n_out_cols = terrain.cols.shape[1]
    n_seg, _na, nb_, n_pow = terrain.poly_line.shape
    per = (n_rows + n_blocks - 1) // n_blocks
    for t in range(lo, hi):
        line_row = np.empty((n_seg, nb_, n_pow))
        col_row = np.empty((nb_, n_pow))
        rc_row = np.empty((2, terrain.dem_rc.shape[2]))
        span = np.empty((_SPAN_ROWS, n_out_cols))
        prev = np.full((3, n_out_cols), np.nan)  # (line, column, height) of the row above
        cur = np.full((3, n_out_cols), np.nan)
        r_lo, r_hi = t * per, min((t + 1) * per, n_rows)
        for r in range(max(r_lo - 1, 0), r_hi):
            _row_3(r, terrain, line_row, col_row, rc_row)
            _coords_span(0, n_out_cols, line_row, col_row, rc_row, terrain, span)
            _raise_row(zbufs[t], span, prev, cur, r >= r_lo)
            prev, cur = cur, prev


@nb.njit(cache=True, fastmath=_FAST)
def _sample_span(img, seg_of, span, r, k_lo, k_hi, method, zbuf, ztol, out, ok, hidden):
    """Level 3's values of output pixels ``(r, k_lo … k_hi − 1)`` from their ``span``
    (:func:`_coords_span`) into ``out``, ``ok`` and ``hidden``: hidden when more than
    ``ztol`` below the z-buffer's height in its nearest raw pixel, else the raw image
    there (nearest, bilinear or Keys cubic; the line of each column sampled from its own
    segment). NaN or an invalid pixel used: not valid."""
    n_lines, n_cols = img.shape
    for k in range(k_lo, k_hi):
        j = k - k_lo
        c = span[_S_COLUMN, j]
        h = span[_S_HEIGHT, j]
        s0 = int(span[_S_SEGMENT, j])
        l0 = span[_S_LINE, j]
        l1 = span[_S_LINE_NEXT, j]
        val = np.nan
        li, ci = _nearest_raw(span[_S_LINE_NEAREST, j], c, n_lines, n_cols)
        hid = li >= 0 and h < zbuf[li, ci] - ztol
        if hid or not (c >= -0.5 and c <= n_cols - 0.5):
            pass
        elif method == 0:
            if li >= 0:
                val = img[li, ci]
        elif l0 >= -0.5 and l0 <= n_lines - 0.5:
            cubic = method == 2
            cf = int(np.floor(c))
            first = cf - 1 if cubic else cf
            last = cf + 2 if cubic else cf + 1
            lf = int(np.floor(l0))
            if cubic and l1 == l0 and first >= 0 and last < n_cols and lf >= 1 and lf + 2 < n_lines:
                # interior, one segment: 4 × 4 separable, row by row (contiguous loads); the
                # same sum as _pixel_2a's, written out again: a helper taking the image per
                # pixel would pay its reference count per pixel
                c0, c1, c2, c3 = _keys(c - cf)
                r0, r1, r2, r3 = _keys(l0 - lf)
                lo = lf - 1
                val = (
                    r0
                    * (
                        c0 * img[lo, first]
                        + c1 * img[lo, first + 1]
                        + c2 * img[lo, first + 2]
                        + c3 * img[lo, first + 3]
                    )
                    + r1
                    * (
                        c0 * img[lo + 1, first]
                        + c1 * img[lo + 1, first + 1]
                        + c2 * img[lo + 1, first + 2]
                        + c3 * img[lo + 1, first + 3]
                    )
                    + r2
                    * (
                        c0 * img[lo + 2, first]
                        + c1 * img[lo + 2, first + 1]
                        + c2 * img[lo + 2, first + 2]
                        + c3 * img[lo + 2, first + 3]
                    )
                    + r3
                    * (
                        c0 * img[lo + 3, first]
                        + c1 * img[lo + 3, first + 1]
                        + c2 * img[lo + 3, first + 2]
                        + c3 * img[lo + 3, first + 3]
                    )
                )
            else:
                wc = _keys(c - cf) if cubic else (1.0 - (c - cf), c - cf, 0.0, 0.0)
                acc = 0.0
                for m in range(last - first + 1):
                    cm = min(max(first + m, 0), n_cols - 1)
                    line = l0 if seg_of[cm] == s0 else l1
                    acc += wc[m] * _sample_column(img, line, cm, n_lines, cubic)
                val = acc
        hidden[r, k] = hid
        out[r, k], ok[r, k] = _byte(val)


@nb.njit(cache=True, nogil=True, fastmath=_FAST)
def _kernel_3(lo, hi, img, t, zbuf, ztol, method, out, ok, hidden):
    """Level 3's resampling (``t``: :class:`Terrain3`), in blocks of output rows × columns
    as 2A's kernel (the raw pixels a block reads stay in cache); every pixel from its own
    (row, column) only."""
    n_out_rows, n_out_cols = out.shape
    n_seg, _na, nb_, n_pow = t.poly_line.shape
    for blk in range(lo, hi):
        r_lo = blk * _BLOCK_ROWS
        r_hi = min(r_lo + _BLOCK_ROWS, n_out_rows)
        line_rows = np.empty((r_hi - r_lo, n_seg, nb_, n_pow))
        col_rows = np.empty((r_hi - r_lo, nb_, n_pow))
        rc_rows = np.empty((r_hi - r_lo, 2, t.dem_rc.shape[2]))
        span = np.empty((_SPAN_ROWS, _BLOCK_COLS))
        for r in range(r_lo, r_hi):
            _row_3(r, t, line_rows[r - r_lo], col_rows[r - r_lo], rc_rows[r - r_lo])
        for k_lo in range(0, n_out_cols, _BLOCK_COLS):
            k_hi = min(k_lo + _BLOCK_COLS, n_out_cols)
            for r in range(r_lo, r_hi):
                i = r - r_lo
                _coords_span(k_lo, k_hi, line_rows[i], col_rows[i], rc_rows[i], t, span)
                _sample_span(
                    img, t.seg_of, span, r, k_lo, k_hi, method, zbuf, ztol, out, ok, hidden
                )


def _height_polynomials(
    grids: NDArray[np.float64], heights: NDArray[np.float64]
) -> tuple[NDArray[np.float64], float, float]:
    """The anchor grids at ``heights`` (first axis) as the coefficients of the polynomial
    in the scaled height ``t = (h − h0) / hs`` through them (``t`` ∈ [−1, 1] over the
    levels), on a last axis of ``_N_POW``: the same Lagrange interpolation
    (:func:`levels.geo.level3.lagrange_weights`), evaluated per pixel by Horner's rule
    without a weight to compute."""
    n = heights.size
    if not 1 <= n <= _N_POW:
        raise ValueError(f"level 3 resampling: 1 to {_N_POW} height levels, not {n}")
    h0 = 0.5 * float(heights[0] + heights[-1])
    hs = max(0.5 * float(heights[-1] - heights[0]), 1e-9)
    to_coefficients = np.linalg.inv(np.vander((heights - h0) / hs, increasing=True))
    poly = np.zeros((*grids.shape[1:], _N_POW))
    poly[..., :n] = np.moveaxis(np.tensordot(to_coefficients, grids, axes=(1, 0)), 0, -1)
    return poly, h0, 1.0 / hs


def resample_3(
    image: NDArray[np.float32],
    valid: NDArray[np.bool_] | None,
    geom: Level3Geometry,
    resampling: str = "cubic",
) -> tuple[NDArray[np.uint8], NDArray[np.bool_], NDArray[np.bool_]]:
    """Level 3 image, its mask and the pixels hidden by the relief (:mod:`levels.geo.level3`).

    Hidden pixels: a z-buffer in the raw image keeps the highest terrain each raw pixel
    sees (the faces between output pixels included: :func:`_zbuffer_3`); an output pixel
    more than ``HIDDEN_TOLERANCE_PX`` raw pixels of line of sight below it is hidden (the
    tolerance in height from the grids' own relief displacement, raw columns per metre:
    none at nadir).
    """
    if resampling not in RESAMPLINGS_2A:
        raise ValueError(f"level 3 resampling {resampling!r}: expected one of {RESAMPLINGS_2A}")
    g = geom.template
    step_i, step_j = g.inverse_step
    img = image if valid is None else with_nan(image, valid)
    img = np.ascontiguousarray(img, dtype=np.float32)
    seg_of = g.segment_of(np.arange(img.shape[1])).astype(np.int64)
    heights = np.asarray(geom.heights_m, dtype=np.float64)
    inv_col = np.stack([lv.inverse_column for lv in geom.levels])
    poly_line, h0, inv_hs = _height_polynomials(
        np.stack([lv.inverse_line for lv in geom.levels]), heights
    )
    poly_col, _, _ = _height_polynomials(inv_col, heights)
    dem = np.ascontiguousarray(geom.dem_ellipsoidal_m, dtype=np.float64)
    dem_rc = np.ascontiguousarray(geom.dem_rc, dtype=np.float64)
    # per output column: the inverse grid's cell and fraction, the DEM nodes' cell and
    # fraction (shared by every row: no division in the kernels)
    k = np.arange(geom.map_grid.n_cols, dtype=np.float64)
    cell = np.minimum(k // step_j, poly_col.shape[1] - 2)
    y = k / geom.dem_step_px
    dem_cell = np.clip(np.floor(y), 0, dem_rc.shape[2] - 2)
    cols = np.ascontiguousarray(
        np.stack([cell, (k - cell * step_j) / step_j, dem_cell, y - dem_cell])
    )
    terrain = Terrain3(
        step_i, poly_line, poly_col, dem_rc, 1.0 / geom.dem_step_px, cols, dem, h0, inv_hs, seg_of
    )
    zbufs = np.full((thread_count(), *img.shape), -np.inf, dtype=np.float32)
    over_blocks(_zbuffer_3, zbufs.shape[0], zbufs, geom.map_grid.n_rows, terrain)
    zbuf = zbufs.max(axis=0)
    del zbufs
    c_per_m = float(np.nanmedian(np.abs(inv_col[-1] - inv_col[0]))) / float(np.ptp(heights))
    ztol = HIDDEN_TOLERANCE_PX / max(c_per_m, 1e-9)
    out = np.empty((geom.map_grid.n_rows, geom.map_grid.n_cols), dtype=np.uint8)
    ok = np.empty(out.shape, dtype=bool)
    hidden = np.empty(out.shape, dtype=bool)
    n_blocks = -(-geom.map_grid.n_rows // _BLOCK_ROWS)
    over_blocks(
        _kernel_3,
        n_blocks,
        img,
        terrain,
        zbuf,
        ztol,
        RESAMPLINGS_2A.index(resampling),
        out,
        ok,
        hidden,
    )
    return out, ok, hidden
