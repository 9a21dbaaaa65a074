"""COR for stereo: a raw image resampled onto an epipolar grid, and an epipolar image shifted
along its rows by a disparity field (the sub-pixel refinement of :mod:`levels.stereo`).

Both are numba kernels on threads over rows (:mod:`levels.threads`) with Keys' cubic
convolution (``a = −½``), as the 2A kernel (:mod:`levels.cor.resample`):

* :func:`resample_epipolar`: each output pixel's raw column bilinearly from a node grid of
  columns, then, for each of the four columns of the cubic window, its raw line from the
  node grid of that column's CCD segment (the line seen at a ground point jumps across a
  butting): the 2A kernel's arithmetic on the epipolar grid's nodes;
* :func:`shift_rows`: ``out[v, u] = image[v, u + d[v, u]]``, cubic along the row.

A pixel is NaN (not valid) when any raw pixel it reads is NaN or outside the image.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np
from numpy.typing import NDArray

from levels.cor.resample import _FAST, _keys
from levels.threads import over_blocks

__all__ = ["resample_epipolar", "shift_rows"]

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
