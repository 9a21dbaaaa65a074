"""COR's geometric resampling into levels 1B and 2A: numba kernels, parallel over lines.

Level 1B (paper ``004_…`` §2.2) offers INPE's two interpolations:

* ``"nearest"``: nearest neighbour for lines and columns: ``f`` says which raw line each
  corrected line repeats (or which raw lines are suppressed), ``g`` which column;
* ``"cubic"``: nearest neighbour for lines, cubic convolution for columns: ``g`` gives,
  within the raw line, the four neighbours of the convolution.

In both, ``h`` shifts each corrected line: its first ``h(I)``-ish pixels see nothing raw,
the black pixels of the left skew (0, not valid).

Level 2A (§3) takes ``(L, C)`` at every output pixel from the inverse grid, bilinearly,
and the raw image there by nearest neighbour, bilinear interpolation or cubic convolution.
The line comes from the grid of the CCD segment of each raw column sampled, so a 4 × 4
cubic window that straddles a butting samples each column at its own line.

Cubic convolution is Keys' kernel with ``a = −½`` (Keys 1981; GDAL's "cubic" is the same).
Every output pixel is computed from its own coordinates only: a scene processed whole or in
tiles gives the same bytes. An output pixel is valid when every raw pixel it uses is valid
and inside the raw image.
"""

from __future__ import annotations

import numba as nb
import numpy as np
from numpy.typing import NDArray

from levels.geo.level1b import Level1BGeometry
from levels.geo.level2a import Level2AGeometry
from levels.geo.level3 import HIDDEN_TOLERANCE_PX, Level3Geometry

__all__ = [
    "INTERPOLATIONS_1B",
    "RESAMPLINGS_2A",
    "resample_1b",
    "resample_2a",
    "resample_3",
    "with_nan",
]

INTERPOLATIONS_1B = ("nearest", "cubic")
RESAMPLINGS_2A = ("nearest", "bilinear", "cubic")
_A = -0.5  # Keys' parameter
#: Fused multiply-adds and reassociation, but NaN kept: NaN marks pixels that are not valid.
_FAST = {"contract", "arcp", "nsz", "reassoc"}


@nb.njit(cache=True, inline="always", fastmath=_FAST)
def _keys(t: float) -> tuple[float, float, float, float]:
    """Keys cubic-convolution weights of the four neighbours at fractional offset t ∈ [0, 1)."""
    t2 = t * t
    t3 = t2 * t
    w0 = _A * (t3 - 2.0 * t2 + t)
    w1 = (_A + 2.0) * t3 - (_A + 3.0) * t2 + 1.0
    w2 = -(_A + 2.0) * t3 + (2.0 * _A + 3.0) * t2 - _A * t
    w3 = _A * (t2 - t3)
    return w0, w1, w2, w3


@nb.njit(cache=True, inline="always", fastmath=_FAST)
def _poly(p: NDArray[np.float64], x: float) -> float:
    """Horner on a stored ``[centre, scale, coef…]`` polynomial."""
    u = (x - p[0]) / p[1]
    acc = 0.0
    for k in range(p.size - 1, 1, -1):
        acc = acc * u + p[k]
    return acc


@nb.njit(cache=True, inline="always", fastmath=_FAST)
def _store(v: float) -> np.uint8:
    if v <= 0.0:
        return np.uint8(0)
    if v >= 255.0:
        return np.uint8(255)
    return np.uint8(np.floor(v + 0.5))


@nb.njit(cache=True, parallel=True, fastmath=_FAST)
def _kernel_1b(img, valid, f, g, h, row0, col0, cubic, out, ok):
    n_lines, n_cols = img.shape
    for r in nb.prange(out.shape[0]):
        i = float(row0 + r)
        line = int(np.floor(_poly(f, i) + 0.5))
        skew = _poly(h, i)
        for k in range(out.shape[1]):
            out[r, k] = 0
            ok[r, k] = False
            if line < 0 or line >= n_lines:
                continue
            c = _poly(g, float(col0 + k) - skew)
            if c < -0.5 or c > n_cols - 0.5:
                continue
            if not cubic:
                ci = min(max(int(np.floor(c + 0.5)), 0), n_cols - 1)
                if valid[line, ci]:
                    out[r, k] = _store(img[line, ci])
                    ok[r, k] = True
                continue
            cf = np.floor(c)
            w = _keys(c - cf)
            acc = 0.0
            good = True
            for m in range(4):
                cm = min(max(int(cf) - 1 + m, 0), n_cols - 1)
                good &= valid[line, cm]
                acc += w[m] * img[line, cm]
            if good:
                out[r, k] = _store(acc)
                ok[r, k] = True


def resample_1b(
    image: NDArray[np.float32],
    valid: NDArray[np.bool_],
    geom: Level1BGeometry,
    interpolation: str = "cubic",
    rows: slice | None = None,
    cols: slice | None = None,
) -> tuple[NDArray[np.uint8], NDArray[np.bool_]]:
    """Level 1B image (or a tile of it: ``rows``, ``cols`` of the output) and its mask."""
    if interpolation not in INTERPOLATIONS_1B:
        raise ValueError(f"1B interpolation {interpolation!r}: expected one of {INTERPOLATIONS_1B}")
    r0, r1, _ = (rows or slice(0, geom.n_rows)).indices(geom.n_rows)
    c0, c1, _ = (cols or slice(0, geom.n_cols)).indices(geom.n_cols)
    out = np.empty((r1 - r0, c1 - c0), dtype=np.uint8)
    ok = np.empty(out.shape, dtype=bool)
    _kernel_1b(
        np.ascontiguousarray(image, dtype=np.float32),
        np.ascontiguousarray(valid),
        geom.f.as_array(),
        geom.g.as_array(),
        geom.h.as_array(),
        r0,
        c0,
        interpolation == "cubic",
        out,
        ok,
    )
    return out, ok


@nb.njit(cache=True, inline="always", fastmath=_FAST)
def _sample_column(img, line, c, n_lines, cubic):
    """One raw column interpolated along track at ``line``: bilinear or Keys (NaN if a pixel
    used is not valid; edge lines replicated)."""
    lf = int(np.floor(line))
    if not cubic:
        t = line - lf
        l0 = min(max(lf, 0), n_lines - 1)
        l1 = min(max(lf + 1, 0), n_lines - 1)
        return (1.0 - t) * img[l0, c] + t * img[l1, c]
    wl = _keys(line - lf)
    acc = 0.0
    for q in range(4):
        acc += wl[q] * img[min(max(lf - 1 + q, 0), n_lines - 1), c]
    return acc


@nb.njit(cache=True, inline="always", fastmath=_FAST)
def _pixel_2a(img, c, b, v, line_row, seg_of, method):
    """Value of one output pixel (NaN if not valid or outside): the raw image at column ``c``
    and, per column sampled, the line of its segment from the row's inverse grid."""
    n_lines, n_cols = img.shape
    nan = np.float32(np.nan)
    if not (c >= -0.5 and c <= n_cols - 0.5):
        return nan
    if method == 0:  # nearest
        ci = min(max(int(np.floor(c + 0.5)), 0), n_cols - 1)
        s = seg_of[ci]
        line = (1.0 - v) * line_row[s, b] + v * line_row[s, b + 1]
        li = int(np.floor(line + 0.5))
        if 0 <= li < n_lines:
            return img[li, ci]
        return nan
    cubic = method == 2
    cf = int(np.floor(c))
    first = cf - 1 if cubic else cf
    last = cf + 2 if cubic else cf + 1
    s0 = seg_of[min(max(first, 0), n_cols - 1)]
    s1 = seg_of[min(max(last, 0), n_cols - 1)]
    line = (1.0 - v) * line_row[s0, b] + v * line_row[s0, b + 1]
    if not (line >= -0.5 and line <= n_lines - 0.5):
        return nan
    lf = int(np.floor(line))
    if cubic:
        wc = _keys(c - cf)
    else:
        wc = (1.0 - (c - cf), c - cf, 0.0, 0.0)
    if s0 == s1 and cubic and first >= 0 and last < n_cols and lf >= 1 and lf + 2 < n_lines:
        # interior, one segment: 4 × 4 separable, row by row (contiguous loads)
        c0, c1, c2, c3 = _keys(c - cf)
        r0, r1, r2, r3 = _keys(line - lf)
        lo = lf - 1
        return (
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
    acc = 0.0
    for m in range(last - first + 1):
        cm = min(max(first + m, 0), n_cols - 1)
        lm = line
        sm = seg_of[cm]
        if sm != s0:
            lm = (1.0 - v) * line_row[sm, b] + v * line_row[sm, b + 1]
        acc += wc[m] * _sample_column(img, lm, cm, n_lines, cubic)
    return acc


#: Output block processed by one task: rows × columns, sized so that the raw pixels it
#: reads stay in cache (the raw footprint of a block is about as large as the block).
_BLOCK_ROWS = 32
_BLOCK_COLS = 256


@nb.njit(cache=True, parallel=True, fastmath=_FAST)
def _kernel_2a(img, step_i, step_j, inv_line, inv_col, seg_of, row0, col0, method, out, ok):
    """``img`` is float32 with NaN where not valid; ``inv_line`` (segments, rows, cols) and
    ``inv_col`` on a grid of integer steps from output pixel (0, 0); ``seg_of`` the segment
    of each raw column.

    Blocks of output rows run in parallel, each swept in blocks of columns. Every pixel's
    value depends only on its own (row, column): tiles give the same bytes as the whole.
    """
    n_seg, na, nb_ = inv_line.shape
    n_out_rows, n_out_cols = out.shape
    n_blocks = (n_out_rows + _BLOCK_ROWS - 1) // _BLOCK_ROWS
    inv_step_i = 1.0 / step_i
    inv_step_j = 1.0 / step_j
    for blk in nb.prange(n_blocks):
        r_lo = blk * _BLOCK_ROWS
        r_hi = min(r_lo + _BLOCK_ROWS, n_out_rows)
        # the inverse grid interpolated to each output row of the block, once per row
        col_rows = np.empty((r_hi - r_lo, nb_))
        line_rows = np.empty((r_hi - r_lo, n_seg, nb_))
        for r in range(r_lo, r_hi):
            a = min((row0 + r) // step_i, na - 2)
            u = (row0 + r - a * step_i) * inv_step_i
            col_rows[r - r_lo] = (1.0 - u) * inv_col[a] + u * inv_col[a + 1]
            for s in range(n_seg):
                line_rows[r - r_lo, s] = (1.0 - u) * inv_line[s, a] + u * inv_line[s, a + 1]
        for k_lo in range(0, n_out_cols, _BLOCK_COLS):
            k_hi = min(k_lo + _BLOCK_COLS, n_out_cols)
            for r in range(r_lo, r_hi):
                col_row = col_rows[r - r_lo]
                line_row = line_rows[r - r_lo]
                # cell by cell, so that the cell index costs no division per pixel
                k = k_lo
                while k < k_hi:
                    b = min((col0 + k) // step_j, nb_ - 2)
                    k_end = k_hi if b == nb_ - 2 else min(k_hi, (b + 1) * step_j - col0)
                    c_b, c_b1 = col_row[b], col_row[b + 1]
                    for kk in range(k, k_end):
                        v = (col0 + kk - b * step_j) * inv_step_j
                        c = (1.0 - v) * c_b + v * c_b1
                        val = _pixel_2a(img, c, b, v, line_row, seg_of, method)
                        if val == val:
                            out[r, kk] = _store(val)
                            ok[r, kk] = True
                        else:
                            out[r, kk] = 0
                            ok[r, kk] = False
                    k = k_end


def with_nan(image: NDArray[np.float32], valid: NDArray[np.bool_]) -> NDArray[np.float32]:
    """The image as the 2A kernel reads it: float32, NaN where not valid."""
    return np.where(valid, image, np.float32(np.nan)).astype(np.float32, copy=False)


def resample_2a(
    image: NDArray[np.float32],
    valid: NDArray[np.bool_] | None,
    geom: Level2AGeometry,
    resampling: str = "cubic",
    rows: slice | None = None,
    cols: slice | None = None,
) -> tuple[NDArray[np.uint8], NDArray[np.bool_]]:
    """Level 2A image (or a tile of it) and its mask, through ``geom``'s inverse grid.

    ``valid=None`` means ``image`` already holds NaN where not valid (:func:`with_nan`),
    which spares a copy when several tiles or levels read the same image.
    """
    if resampling not in RESAMPLINGS_2A:
        raise ValueError(f"2A resampling {resampling!r}: expected one of {RESAMPLINGS_2A}")
    r0, r1, _ = (rows or slice(0, geom.n_rows)).indices(geom.n_rows)
    c0, c1, _ = (cols or slice(0, geom.n_cols)).indices(geom.n_cols)
    out = np.empty((r1 - r0, c1 - c0), dtype=np.uint8)
    ok = np.empty(out.shape, dtype=bool)
    step_i, step_j = geom.inverse_step
    img = image if valid is None else with_nan(image, valid)
    seg_of = geom.segment_of(np.arange(img.shape[1])).astype(np.int64)
    _kernel_2a(
        np.ascontiguousarray(img, dtype=np.float32),
        step_i,
        step_j,
        np.ascontiguousarray(geom.inverse_line),
        np.ascontiguousarray(geom.inverse_column),
        seg_of,
        r0,
        c0,
        RESAMPLINGS_2A.index(resampling),
        out,
        ok,
    )
    return out, ok


@nb.njit(cache=True, inline="always", fastmath=_FAST)
def _sample_at(img, c, seg_lines, seg_of, method):
    """Value at raw column ``c`` where each CCD segment's raw line is ``seg_lines[s]`` (NaN
    if a pixel used is not valid or outside): level 3's sampling, one pixel at a time.

    :func:`_pixel_2a` does the same from a row of the inverse grid, one segment's line at a
    time. Routing its edge and butting path through here gave the same bytes but cost 2A
    5 % in cubic and 12–19 % in nearest and bilinear (one full P scene, one thread): the
    two stay apart."""
    n_lines, n_cols = img.shape
    nan = np.float32(np.nan)
    if not (c >= -0.5 and c <= n_cols - 0.5):
        return nan
    if method == 0:
        ci = min(max(int(np.floor(c + 0.5)), 0), n_cols - 1)
        li = int(np.floor(seg_lines[seg_of[ci]] + 0.5))
        if 0 <= li < n_lines:
            return img[li, ci]
        return nan
    cubic = method == 2
    cf = int(np.floor(c))
    first = cf - 1 if cubic else cf
    last = cf + 2 if cubic else cf + 1
    line0 = seg_lines[seg_of[min(max(first, 0), n_cols - 1)]]
    if not (line0 >= -0.5 and line0 <= n_lines - 0.5):
        return nan
    wc = _keys(c - cf) if cubic else (1.0 - (c - cf), c - cf, 0.0, 0.0)
    acc = 0.0
    for m in range(last - first + 1):
        cm = min(max(first + m, 0), n_cols - 1)
        acc += wc[m] * _sample_column(img, seg_lines[seg_of[cm]], cm, n_lines, cubic)
    return acc


@nb.njit(cache=True, inline="always", fastmath=_FAST)
def _coords_3(
    r, k, step_i, step_j, inv_line, inv_col, heights, dem, dem_rc, dem_step, seg_of, lines
):
    """Raw column of output pixel ``(r, k)`` on the terrain, each segment's line in
    ``lines``, and the terrain height (NaN over a void or outside the DEM): level 3's
    densification (:mod:`levels.geo.level3`: the DEM's own bilinear surface at the DEM
    (row, column) interpolated from ``dem_rc``). The geometry goes in as separate
    arguments: packed in one tuple, the kernel was 12 % slower (16 Mpx, one thread)."""
    n_lev, _n_seg, na, nb_ = inv_line.shape
    x, y = r / dem_step, k / dem_step
    a0 = min(max(int(np.floor(x)), 0), dem_rc.shape[1] - 2)
    b0 = min(max(int(np.floor(y)), 0), dem_rc.shape[2] - 2)
    u, v = x - a0, y - b0
    rr = (1 - v) * ((1 - u) * dem_rc[0, a0, b0] + u * dem_rc[0, a0 + 1, b0]) + v * (
        (1 - u) * dem_rc[0, a0, b0 + 1] + u * dem_rc[0, a0 + 1, b0 + 1]
    )
    cc = (1 - v) * ((1 - u) * dem_rc[1, a0, b0] + u * dem_rc[1, a0 + 1, b0]) + v * (
        (1 - u) * dem_rc[1, a0, b0 + 1] + u * dem_rc[1, a0 + 1, b0 + 1]
    )
    nr, nc = dem.shape
    if not (0.0 <= rr <= nr - 1 and 0.0 <= cc <= nc - 1):
        return np.nan, np.nan
    p0 = min(int(np.floor(rr)), nr - 2)
    q0 = min(int(np.floor(cc)), nc - 2)
    ds, dt = rr - p0, cc - q0
    h = (1 - ds) * ((1 - dt) * dem[p0, q0] + dt * dem[p0, q0 + 1]) + ds * (
        (1 - dt) * dem[p0 + 1, q0] + dt * dem[p0 + 1, q0 + 1]
    )
    if h != h:
        return np.nan, h
    a = min(r // step_i, na - 2)
    b = min(k // step_j, nb_ - 2)
    gu = (r - a * step_i) / step_i
    gv = (k - b * step_j) / step_j
    c = 0.0
    for q in range(n_lev):
        c += _lagrange(h, heights, q) * (
            (1 - gv) * ((1 - gu) * inv_col[q, a, b] + gu * inv_col[q, a + 1, b])
            + gv * ((1 - gu) * inv_col[q, a, b + 1] + gu * inv_col[q, a + 1, b + 1])
        )
    if c != c:
        return c, h
    # only the segments of the columns a cubic kernel around c reads (one, or two at a
    # butting): the others' lines are never read
    n_cols = seg_of.size
    s_lo = seg_of[min(max(int(np.floor(c)) - 1, 0), n_cols - 1)]
    s_hi = seg_of[min(max(int(np.floor(c)) + 2, 0), n_cols - 1)]
    for s in range(s_lo, s_hi + 1):
        lines[s] = 0.0
    for q in range(n_lev):
        w = _lagrange(h, heights, q)
        for s in range(s_lo, s_hi + 1):
            z = inv_line[q, s]
            lines[s] += w * (
                (1 - gv) * ((1 - gu) * z[a, b] + gu * z[a + 1, b])
                + gv * ((1 - gu) * z[a, b + 1] + gu * z[a + 1, b + 1])
            )
    return c, h


@nb.njit(cache=True, inline="always", fastmath=_FAST)
def _lagrange(h, heights, q):
    """Lagrange weight of height level ``q`` at height ``h``."""
    w = 1.0
    for m in range(heights.size):
        if m != q:
            w *= (h - heights[m]) / (heights[q] - heights[m])
    return w


@nb.njit(cache=True, inline="always", fastmath=_FAST)
def _nearest_raw(c, lines, seg_of, n_lines, n_cols):
    """The raw pixel (line, column) nearest to column ``c`` on its segment's line, or
    (−1, −1) outside the raw image."""
    ci = int(np.floor(c + 0.5))
    if 0 <= ci < n_cols:
        li = int(np.floor(lines[seg_of[ci]] + 0.5))
        if 0 <= li < n_lines:
            return li, ci
    return -1, -1


@nb.njit(cache=True, parallel=True, fastmath=_FAST)
def _zbuffer_3(
    zbufs, n_out, step_i, step_j, inv_line, inv_col, heights, dem, dem_rc, dem_step, seg_of
):
    """The highest terrain seen in each raw pixel (every line of sight descends, so the
    highest ground point in a raw pixel is the one it sees), one z-buffer per block of
    output rows (``zbufs``: blocks × raw lines × raw columns, −inf): blocks run in
    parallel without racing, and their maximum is the same whatever the blocks."""
    n_blocks, n_lines, n_cols = zbufs.shape
    per = (n_out[0] + n_blocks - 1) // n_blocks
    for t in nb.prange(n_blocks):
        zbuf = zbufs[t]
        lines = np.empty(inv_line.shape[1])
        for r in range(t * per, min((t + 1) * per, n_out[0])):
            for k in range(n_out[1]):
                c, h = _coords_3(
                    r,
                    k,
                    step_i,
                    step_j,
                    inv_line,
                    inv_col,
                    heights,
                    dem,
                    dem_rc,
                    dem_step,
                    seg_of,
                    lines,
                )
                if c == c:
                    li, ci = _nearest_raw(c, lines, seg_of, n_lines, n_cols)
                    if li >= 0 and h > zbuf[li, ci]:
                        zbuf[li, ci] = h


@nb.njit(cache=True, parallel=True, fastmath=_FAST)
def _kernel_3(
    img,
    step_i,
    step_j,
    inv_line,
    inv_col,
    heights,
    dem,
    dem_rc,
    dem_step,
    seg_of,
    zbuf,
    ztol,
    method,
    out,
    ok,
    hidden,
):
    n_out_rows, n_out_cols = out.shape
    n_lines, n_cols = img.shape
    for r in nb.prange(n_out_rows):
        lines = np.empty(inv_line.shape[1])
        for k in range(n_out_cols):
            c, h = _coords_3(
                r,
                k,
                step_i,
                step_j,
                inv_line,
                inv_col,
                heights,
                dem,
                dem_rc,
                dem_step,
                seg_of,
                lines,
            )
            val = np.float32(np.nan)
            hid = False
            if c == c:
                li, ci = _nearest_raw(c, lines, seg_of, n_lines, n_cols)
                hid = li >= 0 and h < zbuf[li, ci] - ztol
                if not hid:
                    val = _sample_at(img, c, lines, seg_of, method)
            hidden[r, k] = hid
            if val == val:
                out[r, k] = _store(val)
                ok[r, k] = True
            else:
                out[r, k] = 0
                ok[r, k] = False


def resample_3(
    image: NDArray[np.float32],
    valid: NDArray[np.bool_] | None,
    geom: Level3Geometry,
    resampling: str = "cubic",
) -> tuple[NDArray[np.uint8], NDArray[np.bool_], NDArray[np.bool_]]:
    """Level 3 image, its mask and the pixels hidden by the relief (:mod:`levels.geo.level3`).

    Hidden pixels: a z-buffer in the raw image keeps the highest terrain each raw pixel
    sees; an output pixel more than ``HIDDEN_TOLERANCE_PX`` raw pixels of line of sight
    below it is hidden (the tolerance in height from the grids' own relief displacement,
    raw columns per metre: none at nadir).
    """
    if resampling not in RESAMPLINGS_2A:
        raise ValueError(f"level 3 resampling {resampling!r}: expected one of {RESAMPLINGS_2A}")
    g = geom.grid
    step_i, step_j = g.inverse_step
    img = image if valid is None else with_nan(image, valid)
    img = np.ascontiguousarray(img, dtype=np.float32)
    seg_of = g.segment_of(np.arange(img.shape[1])).astype(np.int64)
    inv_line = np.ascontiguousarray(np.stack([lv.inverse_line for lv in geom.levels]))
    inv_col = np.ascontiguousarray(np.stack([lv.inverse_column for lv in geom.levels]))
    heights = np.ascontiguousarray(geom.heights_m, dtype=np.float64)
    dem = np.ascontiguousarray(geom.dem_ellipsoidal_m, dtype=np.float64)
    dem_rc = np.ascontiguousarray(geom.dem_rc, dtype=np.float64)
    step = float(geom.dem_step_px)
    args = (step_i, step_j, inv_line, inv_col, heights, dem, dem_rc, step, seg_of)
    zbufs = np.full((nb.get_num_threads(), *img.shape), -np.inf, dtype=np.float32)
    _zbuffer_3(zbufs, (geom.n_rows, geom.n_cols), *args)
    zbuf = zbufs.max(axis=0)
    del zbufs
    c_per_m = float(np.nanmedian(np.abs(inv_col[-1] - inv_col[0]))) / float(np.ptp(heights))
    ztol = HIDDEN_TOLERANCE_PX / max(c_per_m, 1e-9)
    out = np.empty((geom.n_rows, geom.n_cols), dtype=np.uint8)
    ok = np.empty(out.shape, dtype=bool)
    hidden = np.empty(out.shape, dtype=bool)
    _kernel_3(img, *args, zbuf, ztol, RESAMPLINGS_2A.index(resampling), out, ok, hidden)
    return out, ok, hidden
