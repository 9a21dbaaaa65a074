"""COR's geometric resampling into levels 1B and 2A (level 3's: :mod:`levels.cor.ortho`):
numba kernels, on threads over lines (:mod:`levels.threads`).

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

from levels.choices import Interpolation1B, Resampling
from levels.geo.level1b import Level1BGeometry
from levels.geo.level2a import Level2AGeometry
from levels.threads import over_blocks

__all__ = [
    "INTERPOLATIONS_1B",
    "RESAMPLINGS_2A",
    "resample_1b",
    "resample_2a",
    "with_nan",
]

#: The choices, from their enums (:mod:`levels.choices`); the kernels take a resampling's index.
INTERPOLATIONS_1B = tuple(str(m) for m in Interpolation1B)
RESAMPLINGS_2A = tuple(str(m) for m in Resampling)
_A = -0.5  # Keys' parameter
#: Pixels of margin when a span's two ends decide for all its pixels (all are linear along
#: it, up to rounding: far more than enough).
_MARGIN = 1e-3
#: Pixels a vectorised loop of the 2A span path takes at once (8 float64: an AVX-512
#: register; on narrower machines a multiple of theirs): 0.38 -> 0.36 s for the default
#: scene's cubic 2A on one thread, 2026-11-25.
_LANES = 8
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
def _byte(v: float) -> tuple[np.uint8, bool]:
    """An output pixel's byte and validity from its value: rounded and clipped to 0–255;
    NaN (a raw pixel read not valid, or outside) gives 0, not valid. Branch-free, so that
    the loops storing spans vectorise."""
    good = v == v
    x = min(max(v, 0.0), 255.0) if good else 0.0
    return np.uint8(np.int32(x + 0.5)), good  # x + 0.5 ≥ 0: truncation is floor


@nb.njit(cache=True, inline="always", fastmath=_FAST)
def _on_line(flat, base, c, n_cols, cubic):
    """Raw line ``base / n_cols`` at column ``c`` (inside the line): Keys or nearest, the
    edge columns replicated."""
    if cubic:
        cf = np.floor(c)
        w0, w1, w2, w3 = _keys(c - cf)
        ic = int(cf)
        acc = 0.0
        acc += w0 * flat[base + min(max(ic - 1, 0), n_cols - 1)]
        acc += w1 * flat[base + min(max(ic, 0), n_cols - 1)]
        acc += w2 * flat[base + min(max(ic + 1, 0), n_cols - 1)]
        acc += w3 * flat[base + min(max(ic + 2, 0), n_cols - 1)]
        return acc
    return flat[base + min(max(int(np.floor(c + 0.5)), 0), n_cols - 1)]


@nb.njit(cache=True, nogil=True, fastmath=_FAST)
def _kernel_1b(lo, hi, img, f, g, h, row0, col0, cubic, cubic_lines, out, ok):
    """Rows ``lo … hi − 1`` of a 1B image: ``img`` float32 with NaN where not valid (a pixel
    is valid if every raw pixel it reads is). A row reads the raw line ``f(I)`` at columns
    ``g(J − h(I))``: ``cubic_lines``, Keys' cubic convolution of the four lines about it
    (the edge lines replicated); else the nearest line, ``f(I)`` rounded (INPE's: lines
    repeated or suppressed). The columns come first, in one loop the compiler vectorises;
    then each pixel's taps (edge columns replicated) and a branch-free store."""
    n_lines, n_cols = img.shape
    n_out = out.shape[1]
    flat = img.reshape(img.size)
    cs = np.empty(n_out)
    for r in range(lo, hi):
        i = float(row0 + r)
        fl = _poly(f, i)
        line = int(np.floor(fl + 0.5))
        if line < 0 or line >= n_lines:
            for k in range(n_out):
                out[r, k] = 0
                ok[r, k] = False
            continue
        skew = _poly(h, i)
        for k in range(n_out):
            cs[k] = _poly(g, float(col0 + k) - skew)
        lf = np.floor(fl)
        v0, v1, v2, v3 = _keys(fl - lf)
        il = int(lf)
        b0 = min(max(il - 1, 0), n_lines - 1) * n_cols
        b1 = min(max(il, 0), n_lines - 1) * n_cols
        b2 = min(max(il + 1, 0), n_lines - 1) * n_cols
        b3 = min(max(il + 2, 0), n_lines - 1) * n_cols
        base = line * n_cols
        for k in range(n_out):
            c = cs[k]
            inside = c >= -0.5 and c <= n_cols - 0.5
            cc = c if inside else 0.0
            if cubic_lines:
                acc = v0 * _on_line(flat, b0, cc, n_cols, cubic)
                acc += v1 * _on_line(flat, b1, cc, n_cols, cubic)
                acc += v2 * _on_line(flat, b2, cc, n_cols, cubic)
                acc += v3 * _on_line(flat, b3, cc, n_cols, cubic)
            else:
                acc = _on_line(flat, base, cc, n_cols, cubic)
            out[r, k], ok[r, k] = _byte(acc if inside else np.nan)


def resample_1b(
    image: NDArray[np.float32],
    valid: NDArray[np.bool_] | None,
    geom: Level1BGeometry,
    interpolation: str = "cubic",
    rows: slice | None = None,
    cols: slice | None = None,
    lines: str = "cubic",
) -> tuple[NDArray[np.uint8], NDArray[np.bool_]]:
    """Level 1B image (or a tile of it: ``rows``, ``cols`` of the output) and its mask;
    ``interpolation`` along the rows (the columns), ``lines`` across them (the nearest
    line: INPE's 1B, paper ``004_…`` §3.2; cubic: the rows on the continuous line the
    1B's geometry and RPCs describe).

    ``valid=None`` means ``image`` already holds NaN where not valid (:func:`with_nan`), as
    for :func:`resample_2a`: the scene's 1B and map levels read one such image.
    """
    for what in (interpolation, lines):
        if what not in INTERPOLATIONS_1B:
            raise ValueError(f"1B interpolation {what!r}: expected one of {INTERPOLATIONS_1B}")
    r0, r1, _ = (rows or slice(0, geom.n_rows)).indices(geom.n_rows)
    c0, c1, _ = (cols or slice(0, geom.n_cols)).indices(geom.n_cols)
    out = np.empty((r1 - r0, c1 - c0), dtype=np.uint8)
    ok = np.empty(out.shape, dtype=bool)
    over_blocks(
        _kernel_1b,
        out.shape[0],
        np.ascontiguousarray(image if valid is None else with_nan(image, valid), dtype=np.float32),
        geom.f.as_array(),
        geom.g.as_array(),
        geom.h.as_array(),
        r0,
        c0,
        interpolation == "cubic",
        lines == "cubic",
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
    line = (1.0 - v) * line_row[s0, b] + v * line_row[s0, b + 1]
    if not (line >= -0.5 and line <= n_lines - 0.5):
        return nan
    if cubic:
        wc = _keys(c - cf)
    else:
        wc = (1.0 - (c - cf), c - cf, 0.0, 0.0)
    acc = 0.0
    for m in range(last - first + 1):
        cm = min(max(first + m, 0), n_cols - 1)
        lm = line
        sm = seg_of[cm]
        if sm != s0:
            lm = (1.0 - v) * line_row[sm, b] + v * line_row[sm, b + 1]
        acc += wc[m] * _sample_column(img, lm, cm, n_lines, cubic)
    return acc


@nb.njit(cache=True, inline="always", fastmath=_FAST)
def _lerp(x0, x1, f):
    return (1.0 - f) * x0 + f * x1


@nb.njit(cache=True, inline="always", fastmath=_FAST)
def _span_outside(v_a, v_z, c_a, c_z, b, line_row, shape):
    """Whether the output pixels of a span (one row within one grid cell, from ``v_a`` to
    ``v_z`` of the cell, columns ``c_a`` to ``c_z``) all fall outside the raw image
    (:func:`_pixel_2a` would give each NaN): their column, or their line in every segment,
    beyond the same edge at both ends (all are linear along the span)."""
    n_lines, n_cols = shape
    if max(c_a, c_z) < -0.5 - _MARGIN or min(c_a, c_z) > n_cols - 0.5 + _MARGIN:
        return True
    for s in range(line_row.shape[0]):
        l_a = _lerp(line_row[s, b], line_row[s, b + 1], v_a)
        l_z = _lerp(line_row[s, b], line_row[s, b + 1], v_z)
        above = max(l_a, l_z) < -0.5 - _MARGIN
        below = min(l_a, l_z) > n_lines - 0.5 + _MARGIN
        if not (above or below):
            return False
    return True


@nb.njit(cache=True, inline="always", fastmath=_FAST)
def _span_point(o, j, inv_step, c_b, c_b1, l_0, l_1):
    """Raw column and line of pixel ``j`` of a span starting ``o`` pixels into its cell:
    the inverse grid's bilinear interpolation, as :func:`_kernel_2a` does it per pixel."""
    v = (o + j) * inv_step
    return _lerp(c_b, c_b1, v), _lerp(l_0, l_1, v)


@nb.njit(cache=True, inline="always", fastmath=_FAST)
def _span_inside(
    img,
    flat,
    c_b,
    c_b1,
    b,
    o,
    inv_step,
    n,
    c_a,
    c_z,
    line_row,
    seg_of,
    method,
    out,
    ok,
    r,
    k,
    scratch,
    bases,
):
    """The ``n`` output pixels of a span (one row within one grid cell, starting ``o``
    pixels into it, columns ``c_a`` to ``c_z``), when every one of them reads raw pixels
    inside the image and within one segment (most of a scene); False (nothing written)
    otherwise, for :func:`_pixel_2a` to take them one by one.

    ``c`` and the segment's line are linear along the span, so its two ends bound them all
    (with two pixels of margin, whatever the method). The weights and addresses of the
    span come first, in one loop the compiler vectorises; then the loads and products of
    each pixel; then the stores, branch-free. The arithmetic is :func:`_pixel_2a`'s, term
    for term: the same bytes.
    """
    n_lines, n_cols = img.shape
    c_lo = min(c_a, c_z)
    c_hi = max(c_a, c_z)
    if not (c_lo >= 2.0 and c_hi < n_cols - 4.0):
        return False
    s = seg_of[int(c_lo) - 2]
    if seg_of[int(c_hi) + 3] != s:
        return False
    l_0 = line_row[s, b]
    l_1 = line_row[s, b + 1]
    _, l_a = _span_point(o, 0, inv_step, c_b, c_b1, l_0, l_1)
    _, l_z = _span_point(o, n - 1, inv_step, c_b, c_b1, l_0, l_1)
    if not (min(l_a, l_z) >= 2.0 and max(l_a, l_z) < n_lines - 4.0):
        return False
    # one loop per method, each with no branch: the compiler vectorises them (a branch on
    # the method inside one loop cost 25 %), over whole vectors of _LANES pixels: the ones
    # past the span are computed and never read (a scalar tail was 7 % of the kernel)
    n_lanes = (n + _LANES - 1) // _LANES * _LANES
    if method == 2:
        for j in range(n_lanes):
            c, line = _span_point(o, j, inv_step, c_b, c_b1, l_0, l_1)
            cf = np.floor(c)
            lf = np.floor(line)
            scratch[0, j], scratch[1, j], scratch[2, j], scratch[3, j] = _keys(c - cf)
            scratch[4, j], scratch[5, j], scratch[6, j], scratch[7, j] = _keys(line - lf)
            bases[j] = np.uint64((np.int64(lf) - 1) * n_cols + np.int64(cf) - 1)
    elif method == 1:
        for j in range(n_lanes):
            c, line = _span_point(o, j, inv_step, c_b, c_b1, l_0, l_1)
            cf = np.floor(c)
            lf = np.floor(line)
            scratch[0, j], scratch[1, j] = 1.0 - (c - cf), c - cf
            scratch[4, j] = line - lf
            bases[j] = np.uint64(np.int64(lf) * n_cols + np.int64(cf))
    else:
        for j in range(n_lanes):
            c, line = _span_point(o, j, inv_step, c_b, c_b1, l_0, l_1)
            bases[j] = np.uint64(
                np.int64(np.floor(line + 0.5)) * n_cols + np.int64(np.floor(c + 0.5))
            )
    # unsigned addresses: no negative-index wraparound in the loads
    u1, u2, u3 = np.uint64(1), np.uint64(2), np.uint64(3)
    n1, n2, n3 = np.uint64(n_cols), np.uint64(2 * n_cols), np.uint64(3 * n_cols)
    if method == 0:
        for j in range(n):
            scratch[8, j] = flat[bases[j]]
    elif method == 1:
        for j in range(n):
            p = bases[j]
            t = scratch[4, j]
            acc = 0.0
            acc += scratch[0, j] * ((1.0 - t) * flat[p] + t * flat[p + n1])
            acc += scratch[1, j] * ((1.0 - t) * flat[p + u1] + t * flat[p + n1 + u1])
            scratch[8, j] = acc
    else:
        for j in range(n):
            p = bases[j]
            c0, c1, c2, c3 = scratch[0, j], scratch[1, j], scratch[2, j], scratch[3, j]
            r0, r1, r2, r3 = scratch[4, j], scratch[5, j], scratch[6, j], scratch[7, j]
            scratch[8, j] = (
                c0 * (r0 * flat[p] + r1 * flat[p + n1] + r2 * flat[p + n2] + r3 * flat[p + n3])
                + c1
                * (
                    r0 * flat[p + u1]
                    + r1 * flat[p + n1 + u1]
                    + r2 * flat[p + n2 + u1]
                    + r3 * flat[p + n3 + u1]
                )
                + c2
                * (
                    r0 * flat[p + u2]
                    + r1 * flat[p + n1 + u2]
                    + r2 * flat[p + n2 + u2]
                    + r3 * flat[p + n3 + u2]
                )
                + c3
                * (
                    r0 * flat[p + u3]
                    + r1 * flat[p + n1 + u3]
                    + r2 * flat[p + n2 + u3]
                    + r3 * flat[p + n3 + u3]
                )
            )
    for j in range(n):
        out[r, k + j], ok[r, k + j] = _byte(scratch[8, j])
    return True


#: Output block processed by one task: rows × columns, sized so that the raw pixels it
#: reads stay in cache (the raw footprint of a block is about as large as the block).
_BLOCK_ROWS = 32
_BLOCK_COLS = 256
#: Pixels of a piece, when a span across a CCD butting or an image edge is cut so that
#: most of it still goes by the span path (8: 5 % faster on the default scene; 4: no
#: faster than whole spans pixel by pixel, 2026-11-25).
_PIECE = 8


@nb.njit(cache=True, nogil=True, fastmath=_FAST)
def _kernel_2a(lo, hi, img, step_i, step_j, inv_line, inv_col, seg_of, row0, col0, method, out, ok):
    """``img`` is float32 with NaN where not valid; ``inv_line`` (segments, rows, cols) and
    ``inv_col`` on a grid of integer steps from output pixel (0, 0); ``seg_of`` the segment
    of each raw column.

    Blocks of output rows run in parallel, each swept in blocks of columns. Every pixel's
    value depends only on its own (row, column): tiles give the same bytes as the whole.
    """
    n_seg, na, nb_ = inv_line.shape
    n_out_rows, n_out_cols = out.shape
    inv_step_i = 1.0 / step_i
    inv_step_j = 1.0 / step_j
    flat = img.reshape(img.size)
    for blk in range(lo, hi):
        r_lo = blk * _BLOCK_ROWS
        r_hi = min(r_lo + _BLOCK_ROWS, n_out_rows)
        # the inverse grid interpolated to each output row of the block, once per row
        col_rows = np.empty((r_hi - r_lo, nb_))
        # a span's weights, its value (row 8) and its addresses (_span_inside)
        scratch = np.empty((9, max(step_j, _BLOCK_COLS) + _LANES))
        bases = np.empty(max(step_j, _BLOCK_COLS) + _LANES, dtype=np.uint64)
        line_rows = np.empty((r_hi - r_lo, n_seg, nb_))
        for r in range(r_lo, r_hi):
            a = min((row0 + r) // step_i, na - 2)
            u = (row0 + r - a * step_i) * inv_step_i
            # loops, not array expressions: numba would compile their shape-mismatch
            # message (station/telemetry/rs.py's note)
            for q in range(nb_):
                col_rows[r - r_lo, q] = (1.0 - u) * inv_col[a, q] + u * inv_col[a + 1, q]
                for s in range(n_seg):
                    line_rows[r - r_lo, s, q] = (1.0 - u) * inv_line[s, a, q] + u * inv_line[
                        s, a + 1, q
                    ]
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
                    # the span's two ends decide for all of it (_span_outside, _span_inside)
                    o = col0 + k - b * step_j
                    n = k_end - k
                    v_a = o * inv_step_j
                    v_z = (o + n - 1) * inv_step_j
                    c_a, c_z = _lerp(c_b, c_b1, v_a), _lerp(c_b, c_b1, v_z)
                    if _span_outside(v_a, v_z, c_a, c_z, b, line_row, img.shape):
                        out[r, k:k_end] = 0
                        ok[r, k:k_end] = False
                        k = k_end
                        continue
                    # the span whole, and if it reads across a butting or an image edge,
                    # pieces of it (most still read inside the image and one segment);
                    # what is left pixel by pixel (_pixel_2a: each tap column on its own
                    # segment's line)
                    size, p_lo = n, k
                    while p_lo < k_end:
                        p_hi = min(p_lo + size, k_end)
                        o_p = o + p_lo - k
                        n_p = p_hi - p_lo
                        if not _span_inside(
                            img,
                            flat,
                            c_b,
                            c_b1,
                            b,
                            o_p,
                            inv_step_j,
                            n_p,
                            _lerp(c_b, c_b1, o_p * inv_step_j),
                            _lerp(c_b, c_b1, (o_p + n_p - 1) * inv_step_j),
                            line_row,
                            seg_of,
                            method,
                            out,
                            ok,
                            r,
                            p_lo,
                            scratch,
                            bases,
                        ):
                            if size > _PIECE:
                                size = _PIECE
                                continue
                            for kk in range(p_lo, p_hi):
                                v = (col0 + kk - b * step_j) * inv_step_j
                                c = (1.0 - v) * c_b + v * c_b1
                                val = _pixel_2a(img, c, b, v, line_row, seg_of, method)
                                out[r, kk], ok[r, kk] = _byte(val)
                        p_lo = p_hi
                    k = k_end


@nb.njit(cache=True, nogil=True)
def _kernel_nan(lo, hi, image, valid, out):
    """Rows ``lo … hi − 1`` of :func:`with_nan`."""
    nan = np.float32(np.nan)
    for i in range(lo, hi):
        for j in range(image.shape[1]):
            out[i, j] = image[i, j] if valid[i, j] else nan


def with_nan(image: NDArray[np.float32], valid: NDArray[np.bool_]) -> NDArray[np.float32]:
    """The image as the 2A kernel reads it: float32, NaN where not valid (a full P scene:
    0.017 s on one thread, ``np.where`` 0.030 s)."""
    if image.dtype != np.float32 or image.ndim != 2 or valid.shape != image.shape:
        return np.where(valid, image, np.float32(np.nan)).astype(np.float32, copy=False)
    out = np.empty(image.shape, dtype=np.float32)
    over_blocks(_kernel_nan, image.shape[0], image, valid.astype(bool, copy=False), out, grain=64)
    return out


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
    r0, r1, _ = (rows or slice(0, geom.map_grid.n_rows)).indices(geom.map_grid.n_rows)
    c0, c1, _ = (cols or slice(0, geom.map_grid.n_cols)).indices(geom.map_grid.n_cols)
    out = np.empty((r1 - r0, c1 - c0), dtype=np.uint8)
    ok = np.empty(out.shape, dtype=bool)
    step_i, step_j = geom.inverse_step
    img = image if valid is None else with_nan(image, valid)
    seg_of = geom.segment_of(np.arange(img.shape[1])).astype(np.int64)
    over_blocks(
        _kernel_2a,
        -(-out.shape[0] // _BLOCK_ROWS),
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
