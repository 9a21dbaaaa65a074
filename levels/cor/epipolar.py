"""COR for stereo: a raw image resampled onto an epipolar grid, and an epipolar image shifted
along its rows by a disparity field (the sub-pixel refinement of :mod:`levels.stereo`).

Both are numba kernels on threads over rows (:mod:`levels.threads`) with Keys' cubic
convolution (``a = −½``), as the 2A kernel (:mod:`levels.cor.resample`):

* :func:`resample_epipolar`: each output pixel's raw column bilinearly from a node grid of
  columns, then, for each of the four columns of the cubic window, its raw line from the
  node grid of that column's CCD segment (the line seen at a ground point jumps across a
  butting): the 2A kernel's arithmetic on the epipolar grid's nodes;
* :func:`shift_rows`: ``out[v, u] = image[v, u + d[v, u]]``, cubic along the row;
* :func:`window_solve`: each pixel's least-squares window, from the window sums of its
  regressors' products (:data:`WINDOW_SUMS`), solved by a 4 × 4 Cholesky.

A pixel is NaN (not valid) when any raw pixel it reads is NaN or outside the image.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np
from numpy.typing import NDArray

from levels.cor.resample import _FAST, _keys
from levels.threads import over_blocks

__all__ = ["WINDOW_SUMS", "resample_epipolar", "shift_rows", "window_solve"]

#: Rows a thread takes at once.
_BLOCK_ROWS = 32


@nb.njit(cache=True, inline="always", fastmath=_FAST)
def _node(z, a, b, fu, fv):
    """Bilinear interpolation in a node grid, first along rows then columns."""
    at_b = (1.0 - fv) * z[a, b] + fv * z[a + 1, b]
    at_b1 = (1.0 - fv) * z[a, b + 1] + fv * z[a + 1, b + 1]
    return (1.0 - fu) * at_b + fu * at_b1


@nb.njit(cache=True, nogil=True, fastmath=_FAST)
def _kernel_epipolar(lo, hi, img, step, col_nodes, line_nodes, seg_of, out):
    n_lines, n_cols = img.shape
    nv, nu = col_nodes.shape
    for bk in range(lo, hi):
        for v in range(bk * _BLOCK_ROWS, min((bk + 1) * _BLOCK_ROWS, out.shape[0])):
            a = min(v // step, nv - 2)
            fv = (v - a * step) / step
            for u in range(out.shape[1]):
                b = min(u // step, nu - 2)
                fu = (u - b * step) / step
                c = _node(col_nodes, a, b, fu, fv)
                c0 = math.floor(c)
                wc = _keys(c - c0)
                acc = 0.0
                for k in range(4):
                    ck = c0 - 1 + k
                    if ck < 0 or ck >= n_cols:
                        acc = np.nan
                        break
                    line = _node(line_nodes[seg_of[ck]], a, b, fu, fv)
                    l0 = math.floor(line)
                    if l0 < 1 or l0 + 2 >= n_lines:
                        acc = np.nan
                        break
                    wl = _keys(line - l0)
                    s = 0.0
                    for m in range(4):
                        s += wl[m] * img[l0 - 1 + m, ck]
                    acc += wc[k] * s
                out[v, u] = acc


def resample_epipolar(
    image: NDArray[np.float32],
    step: int,
    col_nodes: NDArray[np.float64],
    line_nodes: NDArray[np.float64],
    segment_first_column: NDArray[np.float64],
    shape: tuple[int, int],
) -> NDArray[np.float32]:
    """``image`` (raw, NaN where not valid) on an epipolar grid of ``shape`` whose raw
    column at nodes every ``step`` pixels is ``col_nodes`` (rows, cols) and raw line, per
    CCD segment, ``line_nodes`` (segments, rows, cols)."""
    if line_nodes.shape[1:] != col_nodes.shape or line_nodes.shape[0] != segment_first_column.size:
        raise ValueError(
            f"line nodes {line_nodes.shape} for column nodes {col_nodes.shape} and "
            f"{segment_first_column.size} segments"
        )
    cols = np.arange(image.shape[1], dtype=np.float64)
    seg_of = np.clip(
        np.searchsorted(segment_first_column, cols, side="right") - 1,
        0,
        segment_first_column.size - 1,
    ).astype(np.int64)
    out = np.empty(shape, dtype=np.float32)
    over_blocks(
        _kernel_epipolar,
        -(-shape[0] // _BLOCK_ROWS),
        np.ascontiguousarray(image, dtype=np.float32),
        int(step),
        np.ascontiguousarray(col_nodes, dtype=np.float64),
        np.ascontiguousarray(line_nodes, dtype=np.float64),
        seg_of,
        out,
    )
    return out


@nb.njit(cache=True, nogil=True, fastmath=_FAST)
def _kernel_shift(lo, hi, img, shift, out):
    n_cols = img.shape[1]
    for bk in range(lo, hi):
        for v in range(bk * _BLOCK_ROWS, min((bk + 1) * _BLOCK_ROWS, out.shape[0])):
            for u in range(out.shape[1]):
                x = u + shift[v, u]
                if not (x == x):
                    out[v, u] = np.nan
                    continue
                x0 = math.floor(x)
                if x0 < 1 or x0 + 2 >= n_cols:
                    out[v, u] = np.nan
                    continue
                w = _keys(x - x0)
                out[v, u] = (
                    w[0] * img[v, x0 - 1]
                    + w[1] * img[v, x0]
                    + w[2] * img[v, x0 + 1]
                    + w[3] * img[v, x0 + 2]
                )


def shift_rows(image: NDArray[np.float32], shift: NDArray[np.float32]) -> NDArray[np.float32]:
    """``out[v, u] = image[v, u + shift[v, u]]`` by cubic convolution along the row; NaN
    where the shift is NaN or reads outside the row or a NaN."""
    if shift.shape != image.shape:
        raise ValueError(f"shift {shift.shape} for an image {image.shape}")
    out = np.empty(image.shape, dtype=np.float32)
    over_blocks(
        _kernel_shift,
        -(-image.shape[0] // _BLOCK_ROWS),
        np.ascontiguousarray(image, dtype=np.float32),
        np.ascontiguousarray(shift, dtype=np.float32),
        out,
    )
    return out


#: The window sums :func:`window_solve` takes, in its order: ``g`` the row gradient and
#: ``gv`` the column gradient of the warped right image, ``y`` the observation, ``x`` and
#: ``z`` a pixel's column and row offsets from the window's centre; all zero on the pixels
#: the window leaves out, and ``"yy"`` is followed by ``"n"``, the pixels it keeps.
WINDOW_SUMS = (
    "g", "gx", "gz", "gv", "y",
    "gg", "ggx", "ggz", "ggxx", "ggxz", "ggzz",
    "ggv", "ggvx", "ggvz", "gvgv",
    "gy", "gyx", "gyz", "gvy", "yy", "n",
)  # fmt: skip


@nb.njit(cache=True, nogil=True, fastmath=_FAST)
def _kernel_window(lo, hi, s, least, out, var, s2):
    nn = np.empty((4, 4))
    r = np.empty(4)
    m = np.empty(4)
    low = np.empty((4, 4))
    w = np.empty(4)
    for bk in range(lo, hi):
        for i in range(bk * _BLOCK_ROWS, min((bk + 1) * _BLOCK_ROWS, out.shape[0])):
            for j in range(out.shape[1]):
                n = s[20, i, j]
                if n < least:
                    out[i, j] = np.nan
                    var[i, j] = np.nan
                    s2[i, j] = np.nan
                    continue
                # regressors, the shift's last: g·x, g·z, gv, g (its Cholesky pivot is then
                # the shift's own: θ₃ = w₃ / L₃₃, var(θ₃) = 1 / L₃₃²)
                m[0] = s[1, i, j]
                m[1] = s[2, i, j]
                m[2] = s[3, i, j]
                m[3] = s[0, i, j]
                sy = s[4, i, j]
                nn[0, 0] = s[8, i, j]
                nn[0, 1] = s[9, i, j]
                nn[0, 2] = s[12, i, j]
                nn[0, 3] = s[6, i, j]
                nn[1, 1] = s[10, i, j]
                nn[1, 2] = s[13, i, j]
                nn[1, 3] = s[7, i, j]
                nn[2, 2] = s[14, i, j]
                nn[2, 3] = s[11, i, j]
                nn[3, 3] = s[5, i, j]
                r[0] = s[16, i, j]
                r[1] = s[17, i, j]
                r[2] = s[18, i, j]
                r[3] = s[15, i, j]
                ok = True
                for a in range(4):
                    r[a] -= m[a] * sy / n
                    for b in range(a, 4):
                        nn[a, b] -= m[a] * m[b] / n
                for a in range(4):  # Cholesky, lower
                    for b in range(a + 1):
                        acc = nn[b, a]
                        for k in range(b):
                            acc -= low[a, k] * low[b, k]
                        if a == b:
                            if acc <= 1e-9 * max(nn[a, a], 1e-30):
                                ok = False
                                break
                            low[a, a] = math.sqrt(acc)
                        else:
                            low[a, b] = acc / low[b, b]
                    if not ok:
                        break
                if not ok:
                    out[i, j] = np.nan
                    var[i, j] = np.nan
                    s2[i, j] = np.nan
                    continue
                ww = 0.0
                for a in range(4):
                    acc = r[a]
                    for k in range(a):
                        acc -= low[a, k] * w[k]
                    w[a] = acc / low[a, a]
                    ww += w[a] * w[a]
                out[i, j] = w[3] / low[3, 3]
                var[i, j] = 1.0 / (low[3, 3] * low[3, 3])
                s2[i, j] = max(s[19, i, j] - sy * sy / n - ww, 0.0) / (n - 5.0)


def window_solve(
    sums: NDArray[np.float32], least: int
) -> tuple[NDArray[np.float32], NDArray[np.float32], NDArray[np.float32]]:
    """Each pixel's window solved by least squares: ``y = c + g·(θ₃ + θ₀·x + θ₁·z) + θ₂·gv``
    (an offset, an affine shift along the row, a shift across it), from the window sums
    ``sums[k]`` of :data:`WINDOW_SUMS`. Returns the shift at the centre ``θ₃``, its
    variance per unit weight (``(N⁻¹)₃₃``, the offset eliminated) and the residual variance
    (``n − 5`` degrees of freedom); NaN where the window is singular or keeps fewer than
    ``least`` pixels."""
    if sums.shape[0] != len(WINDOW_SUMS):
        raise ValueError(f"{sums.shape[0]} window sums, not {len(WINDOW_SUMS)}")
    rows, cols = int(sums.shape[1]), int(sums.shape[2])
    out = np.empty((rows, cols), dtype=np.float32)
    var = np.empty_like(out)
    s2 = np.empty_like(out)
    over_blocks(
        _kernel_window,
        -(-rows // _BLOCK_ROWS),
        np.ascontiguousarray(sums, dtype=np.float32),
        float(max(least, 6)),
        out,
        var,
        s2,
    )
    return out, var, s2
