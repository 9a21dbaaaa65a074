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

__all__ = ["INTERPOLATIONS_1B", "RESAMPLINGS_2A", "resample_1b", "resample_2a"]

INTERPOLATIONS_1B = ("nearest", "cubic")
RESAMPLINGS_2A = ("nearest", "bilinear", "cubic")
_A = -0.5  # Keys' parameter


@nb.njit(cache=True, inline="always")
def _keys(t: float) -> tuple[float, float, float, float]:
    """Keys cubic-convolution weights of the four neighbours at fractional offset t ∈ [0, 1)."""
    t2 = t * t
    t3 = t2 * t
    w0 = _A * (t3 - 2.0 * t2 + t)
    w1 = (_A + 2.0) * t3 - (_A + 3.0) * t2 + 1.0
    w2 = -(_A + 2.0) * t3 + (2.0 * _A + 3.0) * t2 - _A * t
    w3 = _A * (t2 - t3)
    return w0, w1, w2, w3


@nb.njit(cache=True, inline="always")
def _poly(p: NDArray[np.float64], x: float) -> float:
    """Horner on a stored ``[centre, scale, coef…]`` polynomial."""
    u = (x - p[0]) / p[1]
    acc = 0.0
    for k in range(p.size - 1, 1, -1):
        acc = acc * u + p[k]
    return acc


@nb.njit(cache=True, inline="always")
def _store(v: float) -> np.uint8:
    if v <= 0.0:
        return np.uint8(0)
    if v >= 255.0:
        return np.uint8(255)
    return np.uint8(np.floor(v + 0.5))


@nb.njit(cache=True, parallel=True)
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


def resample_1b(image: NDArray[np.float32], valid: NDArray[np.bool_], geom: Level1BGeometry,
                interpolation: str = "cubic", rows: slice | None = None,
                cols: slice | None = None) -> tuple[NDArray[np.uint8], NDArray[np.bool_]]:
    """Level 1B image (or a tile of it: ``rows``, ``cols`` of the output) and its mask."""
    if interpolation not in INTERPOLATIONS_1B:
        raise ValueError(f"1B interpolation {interpolation!r}: expected one of "
                         f"{INTERPOLATIONS_1B}")
    r0, r1, _ = (rows or slice(0, geom.n_rows)).indices(geom.n_rows)
    c0, c1, _ = (cols or slice(0, geom.n_cols)).indices(geom.n_cols)
    out = np.empty((r1 - r0, c1 - c0), dtype=np.uint8)
    ok = np.empty(out.shape, dtype=bool)
    _kernel_1b(np.ascontiguousarray(image, dtype=np.float32), np.ascontiguousarray(valid),
               geom.f.as_array(), geom.g.as_array(), geom.h.as_array(), r0, c0,
               interpolation == "cubic", out, ok)
    return out, ok


@nb.njit(cache=True, inline="always")
def _grid(z, a, b, u, v):
    return ((1.0 - u) * ((1.0 - v) * z[a, b] + v * z[a, b + 1])
            + u * ((1.0 - v) * z[a + 1, b] + v * z[a + 1, b + 1]))


@nb.njit(cache=True, inline="always")
def _segment(seg_first, c):
    s = 0
    for k in range(1, seg_first.size):
        if c >= seg_first[k]:
            s = k
    return s


@nb.njit(cache=True, parallel=True)
def _kernel_2a(img, valid, rows0, step_i, cols0, step_j, inv_line, inv_col, seg_first,
               row0, col0, method, out, ok):
    n_lines, n_cols = img.shape
    _n_seg, na, nb_ = inv_line.shape
    for r in nb.prange(out.shape[0]):
        i = float(row0 + r)
        a = min(max(int(np.floor((i - rows0) / step_i)), 0), na - 2)
        u = (i - (rows0 + a * step_i)) / step_i
        for k in range(out.shape[1]):
            out[r, k] = 0
            ok[r, k] = False
            j = float(col0 + k)
            b = min(max(int(np.floor((j - cols0) / step_j)), 0), nb_ - 2)
            v = (j - (cols0 + b * step_j)) / step_j
            c = _grid(inv_col, a, b, u, v)
            if c < -0.5 or c > n_cols - 0.5:
                continue
            if method == 0:  # nearest
                ci = min(max(int(np.floor(c + 0.5)), 0), n_cols - 1)
                line = _grid(inv_line[_segment(seg_first, ci)], a, b, u, v)
                li = int(np.floor(line + 0.5))
                if 0 <= li < n_lines and valid[li, ci]:
                    out[r, k] = _store(img[li, ci])
                    ok[r, k] = True
                continue
            cf = int(np.floor(c))
            n_taps = 2 if method == 1 else 4
            first = cf if method == 1 else cf - 1
            if method == 1:
                t = c - cf
                wc = (1.0 - t, t, 0.0, 0.0)
            else:
                wc = _keys(c - cf)
            s_prev = -1
            line = 0.0
            acc = 0.0
            good = True
            for m in range(n_taps):
                cm = min(max(first + m, 0), n_cols - 1)
                s = _segment(seg_first, cm)
                if s != s_prev:
                    line = _grid(inv_line[s], a, b, u, v)
                    s_prev = s
                if line < -0.5 or line > n_lines - 0.5:
                    good = False
                    break
                lf = int(np.floor(line))
                col_acc = 0.0
                if method == 1:
                    t = line - lf
                    l0 = min(max(lf, 0), n_lines - 1)
                    l1 = min(max(lf + 1, 0), n_lines - 1)
                    good &= valid[l0, cm] & valid[l1, cm]
                    col_acc = (1.0 - t) * img[l0, cm] + t * img[l1, cm]
                else:
                    wl = _keys(line - lf)
                    for q in range(4):
                        lq = min(max(lf - 1 + q, 0), n_lines - 1)
                        good &= valid[lq, cm]
                        col_acc += wl[q] * img[lq, cm]
                acc += wc[m] * col_acc
            if good:
                out[r, k] = _store(acc)
                ok[r, k] = True


def resample_2a(image: NDArray[np.float32], valid: NDArray[np.bool_], geom: Level2AGeometry,
                resampling: str = "cubic", rows: slice | None = None,
                cols: slice | None = None) -> tuple[NDArray[np.uint8], NDArray[np.bool_]]:
    """Level 2A image (or a tile of it) and its mask, through ``geom``'s inverse grid."""
    if resampling not in RESAMPLINGS_2A:
        raise ValueError(f"2A resampling {resampling!r}: expected one of {RESAMPLINGS_2A}")
    r0, r1, _ = (rows or slice(0, geom.n_rows)).indices(geom.n_rows)
    c0, c1, _ = (cols or slice(0, geom.n_cols)).indices(geom.n_cols)
    out = np.empty((r1 - r0, c1 - c0), dtype=np.uint8)
    ok = np.empty(out.shape, dtype=bool)
    ri, ci = geom.inverse_rows, geom.inverse_cols
    _kernel_2a(np.ascontiguousarray(image, dtype=np.float32), np.ascontiguousarray(valid),
               float(ri[0]), float(ri[1] - ri[0]), float(ci[0]), float(ci[1] - ci[0]),
               np.ascontiguousarray(geom.inverse_line), np.ascontiguousarray(geom.inverse_column),
               geom.segment_first_column.astype(np.float64), r0, c0,
               RESAMPLINGS_2A.index(resampling), out, ok)
    return out, ok
