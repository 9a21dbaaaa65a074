"""The true layover and shadow of a SAR frame: the standard definitions (Kropatsch & Strobl
1990) on continuous profiles of scattered terrain points, binned along the ground range
(:func:`layover_and_shadow`). The emulator's own (the truth's), on the world's terrain and
the integrated orbit; the processing judges its output pixels on the DEM's profiles
sampled along the image lines (:mod:`levels.sar.masks`). Checked on an analytic ridge
(``tests/test_sar.py``).
"""

from __future__ import annotations

import numba as nb
import numpy as np
from numpy.typing import NDArray

from levels.threads import over_blocks

__all__ = ["layover_and_shadow"]


#: Lattice lines about a strip whose nodes are visited for it (an edge spans at most two
#: lattice lines: one profile per node along the track, the diagonal two).
_STRIP_MARGIN = 4
#: Columns walked together (a row of them is contiguous in memory).
_BLOCK = 16


@nb.njit(cache=True, nogil=True)
def _near(a, b, f):
    """The profile's value between two lattice lines (``f`` of the way to ``b``); one
    lattice line's if the other has none there; NaN if neither."""
    if np.isfinite(a) and np.isfinite(b):
        return (1.0 - f) * a + f * b
    if np.isfinite(a):
        return a
    if np.isfinite(b):
        return b
    return np.nan


@nb.njit(cache=True, nogil=True)
def _reaches(row, j0, j1, inv, l0, first):
    """Whether any line of ``row[j0:j1]`` (scaled) is at ``first`` or beyond."""
    for j in range(j0, j1):
        if row[j] * inv - l0 >= first:
            return True
    return False


@nb.njit(cache=True, nogil=True)
def _kernel_profiles(
    lo, hi, strip, line, u, r, look, ql, qu, qr, qlook, per, l0, u0, bw, n_bins, tol_r,
    tol_look, layover, shadow,
):  # fmt: skip
    """Strips ``lo … hi − 1`` of ``strip`` lattice lines: the profiles of the node grid
    where its edges (right, down) cross each lattice line, binned along the
    ground range ``u``; then each query of the strip against the two lattice lines about
    it (:func:`layover_and_shadow`); lattice line ``k`` is image line ``(k + l0) · per``.
    The lines grow down every column (along the track): each block of ``_BLOCK`` columns
    is walked from where the last strip left it."""
    n_rows, n_cols = line.shape
    q_rows, q_cols = ql.shape
    inv = 1.0 / per
    ptr = np.zeros(-(-n_cols // _BLOCK), dtype=np.int64)
    qptr = np.zeros(-(-q_cols // _BLOCK), dtype=np.int64)
    rmax = np.empty((strip + 1, n_bins), dtype=np.float32)
    rmin = np.empty((strip + 1, n_bins), dtype=np.float32)
    lmax = np.empty((strip + 1, n_bins), dtype=np.float32)
    for s in range(lo, hi):
        base = s * strip
        first, last = base - _STRIP_MARGIN, base + strip + _STRIP_MARGIN
        rmax[:] = -np.inf
        rmin[:] = np.inf
        lmax[:] = -np.inf
        for jb in range(ptr.size):  # blocks of columns: rows of them are contiguous
            j0, j1 = jb * _BLOCK, min((jb + 1) * _BLOCK, n_cols)
            i = ptr[jb]
            while i < n_rows and not _reaches(line[i], j0, j1, inv, l0, first):
                i += 1  # rows wholly before the strip
            ptr[jb] = i
            while i < n_rows:
                seen, beyond = False, True
                for a_j in range(j0, j1):
                    la = line[i, a_j] * inv - l0
                    if not np.isfinite(la):
                        continue
                    seen = True
                    if la <= last:
                        beyond = False
                    if la < first or la > last:
                        continue
                    for e in range(2):  # the right and the lower neighbour
                        c_i = i + e
                        c_j = a_j + 1 - e
                        if c_i >= n_rows or c_j >= n_cols or not np.isfinite(line[c_i, c_j]):
                            continue
                        lc = line[c_i, c_j] * inv - l0
                        k0 = max(int(np.ceil(min(la, lc))), base)
                        k1 = min(int(np.floor(max(la, lc))), base + strip)
                        for k in range(k0, k1 + 1):
                            t = 0.0 if lc == la else (k - la) / (lc - la)
                            uu = u[i, a_j] + t * (u[c_i, c_j] - u[i, a_j])
                            b = int(np.floor((uu - u0) / bw))
                            if b < 0 or b >= n_bins:
                                continue
                            rr = r[i, a_j] + t * (r[c_i, c_j] - r[i, a_j])
                            ll = look[i, a_j] + t * (look[c_i, c_j] - look[i, a_j])
                            row = k - base
                            rmax[row, b] = max(rmax[row, b], rr)
                            rmin[row, b] = min(rmin[row, b], rr)
                            lmax[row, b] = max(lmax[row, b], ll)
                if seen and beyond:
                    break
                i += 1
        for row in range(strip + 1):  # nearer than each bin; farther than each bin
            for b in range(1, n_bins):
                rmax[row, b] = max(rmax[row, b], rmax[row, b - 1])
                lmax[row, b] = max(lmax[row, b], lmax[row, b - 1])
            for b in range(n_bins - 2, -1, -1):
                rmin[row, b] = min(rmin[row, b], rmin[row, b + 1])
        for jb in range(qptr.size):
            j0, j1 = jb * _BLOCK, min((jb + 1) * _BLOCK, q_cols)
            i = qptr[jb]
            while i < q_rows and not _reaches(ql[i], j0, j1, inv, l0, base):
                i += 1
            qptr[jb] = i
            while i < q_rows:
                seen, beyond = False, True
                for j in range(j0, j1):
                    x = ql[i, j] * inv - l0 - base
                    if not np.isfinite(x):
                        continue
                    seen = True
                    if x < strip:
                        beyond = False
                    if x < 0 or x >= strip or not np.isfinite(qu[i, j]):
                        continue
                    row = min(int(np.floor(x)), strip - 1)
                    f = x - row
                    b = int(np.floor((qu[i, j] - u0) / bw))
                    if 0 <= b - 2 < n_bins:  # a bin between: the query's own slope
                        near_r = _near(rmax[row, b - 2], rmax[row + 1, b - 2], f)
                        near_look = _near(lmax[row, b - 2], lmax[row + 1, b - 2], f)
                        if near_r == near_r and qr[i, j] < near_r - tol_r:
                            layover[i, j] = True
                        if near_look == near_look and qlook[i, j] < near_look - tol_look:
                            shadow[i, j] = True
                    if 0 <= b + 2 < n_bins:
                        far_r = _near(rmin[row, b + 2], rmin[row + 1, b + 2], f)
                        if far_r == far_r and qr[i, j] > far_r + tol_r:
                            layover[i, j] = True
                if seen and beyond:
                    break
                i += 1


def _median_step(a: NDArray, axis: int) -> float:
    """The median step of ``a`` between neighbours along ``axis`` (every 8th row or column
    across it: the median of a grid's every step sorts it whole)."""
    a = a[:, ::8] if axis == 0 else a[::8, :]
    return float(np.nanmedian(np.diff(a, axis=axis)))


def layover_and_shadow(
    line: NDArray,
    u: NDArray,
    r: NDArray,
    look_rad: NDArray,
    bin_width: float,
    tol_r: float,
    tol_look_rad: float,
    queries: tuple[NDArray, NDArray, NDArray, NDArray] | None = None,
    lines_per_profile: float = 1.0,
    strip: int = 64,
) -> tuple[NDArray[np.bool_], NDArray[np.bool_]]:
    """Layover and shadow of terrain points by their zero-Doppler profiles, the standard
    definitions (e.g. Kropatsch & Strobl 1990) on a grid of terrain points (2-D, NaN where
    none; the lines growing down its columns, along the track): each point's image
    ``line`` (one profile every ``lines_per_profile`` lines), a ground-range
    coordinate ``u`` (any that grows away from the track), its slant range ``r`` and look
    angle. Along the terrain's profile at the point's line, ordered by ``u``, a point is

    * in **layover** if terrain nearer the track returns from a longer range (beyond
      ``tol_r``) or terrain farther from a shorter one: its range cell also holds another
      patch of terrain (a slope facing the radar steeper than the incidence, the ground
      before it and the slope behind its top);
    * in **shadow** if terrain nearer the track is seen at a larger look angle (beyond
      ``tol_look_rad``): the ray to it passes under that terrain.

    The profiles are the grid's, continuous: for each integer line, where the edges of
    the grid's cells (right, down) cross it, interpolated linearly, binned
    by ``bin_width`` of ``u`` (running maxima of the range and look angle from the track
    outwards, minima of the range inwards); a point reads the two profiles about its
    line, interpolated, beyond the bin next to its own (folds shorter than a bin or two
    are not seen). ``queries``: other points (a 2-D grid of ``line, u, r, look`` turned as
    the nodes' grid) judged on the grid's profiles, else the grid's own nodes. A numba
    kernel over strips of ``strip`` lines on threads, the grids turned so that the lines
    grow down their columns (along the track), each column walked once per chunk of
    strips."""
    line = np.asarray(line, dtype=np.float64)
    # the kernel walks the lines down the columns: the grids turned so that they grow so
    along = [_median_step(line, ax) for ax in (0, 1)]
    axis = int(abs(along[1]) > abs(along[0]))

    def turned(a: NDArray) -> NDArray:
        a = np.asarray(a, dtype=np.float64)
        a = a.T if axis else a
        return np.ascontiguousarray(a[::-1] if along[axis] < 0 else a)

    def back(a: NDArray) -> NDArray:
        a = a[::-1] if along[axis] < 0 else a
        return np.ascontiguousarray(a.T if axis else a)

    nodes = [turned(a) for a in (line, u, r, look_rad)]
    ok = np.isfinite(nodes[0]) & np.isfinite(nodes[1])
    qs = nodes if queries is None else [turned(a) for a in queries]
    layover = np.zeros(qs[0].shape, dtype=np.bool_)
    shadow = np.zeros(qs[0].shape, dtype=np.bool_)
    if ok.any():
        per = float(lines_per_profile)
        l0 = float(np.floor(np.min(nodes[0], where=ok, initial=np.inf) / per))
        n_strips = int((np.max(nodes[0], where=ok, initial=-np.inf) / per - l0) // strip) + 1
        u0 = float(np.min(nodes[1], where=ok, initial=np.inf))
        n_bins = int((np.max(nodes[1], where=ok, initial=-np.inf) - u0) / bin_width) + 1
        over_blocks(
            _kernel_profiles,
            n_strips,
            int(strip),
            *nodes,
            *qs,
            per,
            l0,
            u0,
            float(bin_width),
            n_bins,
            float(tol_r),
            float(tol_look_rad),
            layover,
            shadow,
            grain=4,
        )
    return back(layover), back(shadow)
