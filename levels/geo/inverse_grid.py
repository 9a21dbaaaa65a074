"""The 2A inverse grid's kernels: the raw ``(L, C)`` of output points from the four nearest
points of the direct grid (paper ``004_…`` §3, "nearest4"), and the bilinear reading of a grid.

The direct grid maps raw breakpoints ``(L, C)`` to output pixels ``(I, J)``; each of its
cells is inverted by Newton on its bilinear map (:func:`_walk`), moving cell by cell. The
raw image is cut at the CCD buttings into column segments, and each segment's line is
found over its own cells only (the line jumps across a butting). Numba kernels: a scene's
inverse grid is tens of thousands of nodes, a checkpoint lattice hundreds of points.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numba as nb
import numpy as np
from numpy.typing import ArrayLike, NDArray

from levels.errors import GeometryError

__all__ = ["bilinear_grid", "invert_nodes", "invert_scattered", "segment_cells"]


@nb.njit(cache=True, nogil=True)
def _cell_coefficients(gi, gj):
    """The bilinear map of every direct-grid cell ``(a, b)`` as
    ``I = i0 + iu·u + iv·v + iuv·u·v`` and the same for ``J``: the eight numbers
    ``(i0, iu, iv, iuv, j0, ju, jv, juv)``, side by side (one cache line) for the walk."""
    na, nb_ = gi.shape
    k = np.empty((na - 1, nb_ - 1, 8))
    for a in range(na - 1):
        for b in range(nb_ - 1):
            for f, g in ((0, gi), (4, gj)):
                k[a, b, f] = g[a, b]
                k[a, b, f + 1] = g[a + 1, b] - g[a, b]
                k[a, b, f + 2] = g[a, b + 1] - g[a, b]
                k[a, b, f + 3] = (g[a + 1, b + 1] - g[a + 1, b]) - (g[a, b + 1] - g[a, b])
    return k


@nb.njit(cache=True, nogil=True)
def _walk(gl, gc, k, ip, jp, a, b, u, v, b_lo, b_hi, max_moves):
    """Raw ``(L, C)`` of output point ``(ip, jp)``: Newton on the bilinear map of direct-grid
    cell ``(a, b)`` (its coefficients ``k[a, b]``, :func:`_cell_coefficients`) from local
    coordinates ``(u, v)``, moving to the neighbouring cell while they fall outside [0, 1].
    Cells are kept within rows ``0 .. na − 2`` and columns ``b_lo .. b_hi − 1`` (a CCD
    segment's own columns); beyond them the edge cell is extrapolated. The walk moves one
    cell at a time: a butting cell is one pixel wide, and its bilinear map extrapolated far
    from it has spurious roots that a jump of several cells would take. Returns
    ``(L, C, a, b, u, v)``."""
    last_row = k.shape[0] - 1
    for _move in range(max_moves):
        i0, iu, iv, iuv = k[a, b, 0], k[a, b, 1], k[a, b, 2], k[a, b, 3]
        j0, ju, jv, juv = k[a, b, 4], k[a, b, 5], k[a, b, 6], k[a, b, 7]
        for _it in range(6):
            # the Jacobian [[a11, a12], [a21, a22]] of (I, J) in (u, v)
            a11, a12 = iu + iuv * v, iv + iuv * u
            a21, a22 = ju + juv * v, jv + juv * u
            ri = ip - (i0 + a11 * u + iv * v)
            rj = jp - (j0 + a21 * u + jv * v)
            inv_det = 1.0 / (a11 * a22 - a12 * a21)
            du = (a22 * ri - a12 * rj) * inv_det
            dv = (a11 * rj - a21 * ri) * inv_det
            u += du
            v += dv
            if abs(du) + abs(dv) < 1e-7:
                break  # Newton's quadratic convergence: what remains is below 1e-14
        na_ = min(max(a + (1 if u >= 1.0 else (-1 if u < 0.0 else 0)), 0), last_row)
        nb2 = min(max(b + (1 if v >= 1.0 else (-1 if v < 0.0 else 0)), b_lo), b_hi - 1)
        if na_ == a and nb2 == b:
            break
        u -= na_ - a
        v -= nb2 - b
        a, b = na_, nb2
    return gl[a] + u * (gl[a + 1] - gl[a]), gc[b] + v * (gc[b + 1] - gc[b]), a, b, u, v


@nb.njit(cache=True, nogil=True)
def _segment_line(gl, gc, k, ip, jp, line, a, b, u, v, b0, b1):
    """The line of segment ``b0 .. b1 − 1`` at output point ``(ip, jp)``, from the whole
    grid's walk (``line`` in cell ``(a, b)`` at ``(u, v)``): the same if that cell is the
    segment's, else a walk over the segment's cells from its nearest one."""
    if b0 <= b < b1:
        return line
    bs = min(max(b, b0), b1 - 1)
    moves = k.shape[0] + k.shape[1] + 2
    return _walk(gl, gc, k, ip, jp, a, bs, u, v + b - bs, b0, b1, moves)[0]


@nb.njit(cache=True, nogil=True)
def _invert_points(gl, gc, gi, gj, i_pts, j_pts, a0, b0, seg_b0, seg_b1, lines, col):
    """:func:`_walk` for scattered points, each from its own first-guess cell ``(a0, b0)``,
    over the whole grid (``col``) and over each segment's cells ``seg_b0[s] .. seg_b1[s] − 1``
    (``lines[s]``); a point whose whole-grid cell lies in the segment has the segment's
    answer already."""
    n_seg = lines.shape[0]
    na, nb_ = gi.shape
    k = _cell_coefficients(gi, gj)
    for p in range(i_pts.size):
        line, c, a, b, u, v = _walk(
            gl, gc, k, i_pts[p], j_pts[p], a0[p], b0[p], 0.5, 0.5, 0, nb_ - 1, na + nb_
        )
        col[p] = c
        for s in range(n_seg):
            lines[s, p] = _segment_line(
                gl, gc, k, i_pts[p], j_pts[p], line, a, b, u, v, seg_b0[s], seg_b1[s]
            )


@nb.njit(cache=True, nogil=True)
def invert_nodes(gl, gc, gi, gj, rows, cols, seg_b0, seg_b1, seg_lo, seg_hi, lines, col):
    """The inverse grid by :func:`_walk`, row by row, each node starting from the cell of
    the node before it, at the cell coordinates extrapolated from the two nodes before it:
    a step of the inverse grid is a fraction of a direct-grid cell, so a walk rarely moves
    and Newton starts close (a row's first node starts from the centre of the grid).
    Serial: a scene's grid takes a few milliseconds, and scenes are the unit of
    parallelism (``levels.tasks``).

    A segment's line is taken exactly (over its own columns, extrapolated beyond) at the
    nodes of every inverse-grid cell whose column range meets the raw columns that belong
    to the segment, ``[seg_lo[s], seg_hi[s])``: those are the nodes the 2A kernel's
    bilinear interpolation reads for it. Elsewhere the field holds the whole grid's line,
    the line of the CCD that does see there.
    """
    n_seg = lines.shape[0]
    na, nb_ = gi.shape
    nr, nc = rows.size, cols.size
    k = _cell_coefficients(gi, gj)
    cell_a = np.empty((nr, nc), dtype=np.int64)
    cell_b = np.empty((nr, nc), dtype=np.int64)
    cell_u = np.empty((nr, nc))
    cell_v = np.empty((nr, nc))
    whole = np.empty((nr, nc))
    for r in range(nr):
        a, b, u, v = (na - 1) // 2, (nb_ - 1) // 2, 0.5, 0.5
        x1 = y1 = x2 = y2 = 0.0  # global cell coordinates of the two nodes before
        for c in range(nc):
            if c >= 2:  # linear prediction in global cell coordinates
                pu, pv = 2.0 * x1 - x2, 2.0 * y1 - y2
                a = min(max(int(np.floor(pu)), 0), na - 2)
                b = min(max(int(np.floor(pv)), 0), nb_ - 2)
                u, v = pu - a, pv - b
            moves = na + nb_ if c == 0 else 16
            line, cc, a, b, u, v = _walk(gl, gc, k, rows[r], cols[c], a, b, u, v, 0, nb_ - 1, moves)
            whole[r, c], col[r, c] = line, cc
            cell_a[r, c], cell_b[r, c], cell_u[r, c], cell_v[r, c] = a, b, u, v
            x2, y2, x1, y1 = x1, y1, a + u, b + v
    # The raw columns the cells around a node span: the range of its 3 × 3 nodes (2 × 2
    # cells, fewer at the edges), first along rows, then along columns.
    row_lo = np.empty((nr, nc))
    row_hi = np.empty((nr, nc))
    for r in range(nr):
        for c in range(nc):
            c0, c1 = max(c - 1, 0), min(c + 1, nc - 1)
            row_lo[r, c] = min(min(col[r, c0], col[r, c]), col[r, c1])
            row_hi[r, c] = max(max(col[r, c0], col[r, c]), col[r, c1])
    lo = np.empty((nr, nc))
    hi = np.empty((nr, nc))
    for r in range(nr):
        r0, r1 = max(r - 1, 0), min(r + 1, nr - 1)
        for c in range(nc):
            lo[r, c] = min(min(row_lo[r0, c], row_lo[r, c]), row_lo[r1, c])
            hi[r, c] = max(max(row_hi[r0, c], row_hi[r, c]), row_hi[r1, c])
    # Each segment: the whole grid's line first, then a walk at the few nodes (a strip
    # along each butting) where the segment is needed but the whole grid's cell is not
    # its own. Two passes: the walk inlined in the first would slow every node.
    walks = np.empty(nr * nc, dtype=np.int64)
    for s in range(n_seg):
        n_walks = 0
        for r in range(nr):
            for c in range(nc):
                lines[s, r, c] = whole[r, c]
                b = cell_b[r, c]
                if lo[r, c] < seg_hi[s] and hi[r, c] >= seg_lo[s]:
                    if b < seg_b0[s] or b >= seg_b1[s]:
                        walks[n_walks] = r * nc + c
                        n_walks += 1
        for w in range(n_walks):
            r, c = walks[w] // nc, walks[w] % nc
            lines[s, r, c] = _segment_line(
                gl,
                gc,
                k,
                rows[r],
                cols[c],
                whole[r, c],
                cell_a[r, c],
                cell_b[r, c],
                cell_u[r, c],
                cell_v[r, c],
                seg_b0[s],
                seg_b1[s],
            )


def segment_cells(
    grid_column: NDArray[np.float64], segment_first_column: NDArray[np.float64]
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Direct-grid column indices of each segment's first and last detector: segment ``s``
    owns the cells ``first[s] .. last[s] − 1``. The cell across a butting gap, between the
    last detector of one CCD and the first of the next, belongs to neither."""
    ends = np.append(segment_first_column[1:] - 1, grid_column[-1])
    first = np.searchsorted(grid_column, segment_first_column)
    last = np.searchsorted(grid_column, ends)
    if not (
        np.all(grid_column[first] == segment_first_column) and np.all(grid_column[last] == ends)
    ):
        raise GeometryError("the direct grid must hold both sides of every CCD butting")
    return first.astype(np.int64), last.astype(np.int64)


def invert_scattered(
    gl: NDArray[np.float64],
    gc: NDArray[np.float64],
    gi: NDArray[np.float64],
    gj: NDArray[np.float64],
    segment_first_column: NDArray[np.float64],
    i: ArrayLike,
    j: ArrayLike,
    first_guess: tuple[NDArray, NDArray],
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Line per segment ``(segments, N)`` and column ``(N,)`` of scattered output points
    ``(I, J)``, from the four nearest direct-grid points: each point starts in the cell of
    its ``first_guess`` ``(L, C)`` and walks (:func:`_walk`); points beyond the grid are
    extrapolated from the edge cell."""
    i_a, j_a = (
        np.ascontiguousarray(x, dtype=np.float64).ravel() for x in np.broadcast_arrays(i, j)
    )
    na, nb_ = gi.shape
    a = np.clip(np.searchsorted(gl, np.ravel(first_guess[0])) - 1, 0, na - 2)
    b = np.clip(np.searchsorted(gc, np.ravel(first_guess[1])) - 1, 0, nb_ - 2)
    seg_b0, seg_b1 = segment_cells(gc, segment_first_column)
    lines = np.empty((segment_first_column.size, i_a.size))
    col = np.empty(i_a.size)
    _invert_points(
        np.asarray(gl, float),
        np.asarray(gc, float),
        np.ascontiguousarray(gi, dtype=np.float64),
        np.ascontiguousarray(gj, dtype=np.float64),
        i_a,
        j_a,
        a.astype(np.int64),
        b.astype(np.int64),
        seg_b0,
        seg_b1,
        lines,
        col,
    )
    return lines, col


def bilinear_grid(
    rows: NDArray[np.float64],
    cols: NDArray[np.float64],
    z: NDArray[np.floating[Any]],
    i: ArrayLike,
    j: ArrayLike,
) -> NDArray[np.float64]:
    """Bilinear interpolation of a field on a grid of integer steps from (0, 0), extrapolated
    at the far edges: the arithmetic of the 2A kernel, first along rows then columns, so that
    checks and products agree to the last bit."""
    i_a, j_a = np.broadcast_arrays(np.asarray(i, dtype=np.float64), np.asarray(j, dtype=np.float64))
    step_i, step_j = rows[1] - rows[0], cols[1] - cols[0]
    # a NaN position (a point over a DEM void) gives NaN: its node is any, its weight NaN
    a = np.clip(np.floor(np.nan_to_num(i_a / step_i)).astype(np.int64), 0, rows.size - 2)
    b = np.clip(np.floor(np.nan_to_num(j_a / step_j)).astype(np.int64), 0, cols.size - 2)
    u = (i_a - a * step_i) * (1.0 / step_i)
    v = (j_a - b * step_j) * (1.0 / step_j)
    at_b = (1.0 - u) * z[a, b] + u * z[a + 1, b]
    at_b1 = (1.0 - u) * z[a, b + 1] + u * z[a + 1, b + 1]
    return (1.0 - v) * at_b + v * at_b1


def invert_by_newton(
    raw_of: Callable[[NDArray[np.float64], NDArray[np.float64]], tuple[NDArray, NDArray]],
    line: ArrayLike,
    column: ArrayLike,
    first_guess: tuple[NDArray, NDArray],
    iterations: int,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Output ``(I, J)`` that ``raw_of`` sends to raw ``(L, C)``: Newton from
    ``first_guess``, the Jacobian by forward differences of a quarter pixel."""
    la, ca = (np.asarray(x, dtype=np.float64).ravel() for x in (line, column))
    i, j = (np.asarray(x, dtype=np.float64).ravel().copy() for x in first_guess)
    eps = 0.25
    for _ in range(iterations):
        lo, co = raw_of(i, j)
        li, ci = raw_of(i + eps, j)
        lj, cj = raw_of(i, j + eps)
        a11, a12 = (li - lo) / eps, (lj - lo) / eps
        a21, a22 = (ci - co) / eps, (cj - co) / eps
        det = a11 * a22 - a12 * a21
        rl, rc = la - lo, ca - co
        i = i + (a22 * rl - a12 * rc) / det
        j = j + (-a21 * rl + a11 * rc) / det
    return i, j
