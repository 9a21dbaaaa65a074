"""Layover and shadow by their standard definitions on the terrain's zero-Doppler profiles:
the levels' profiles sampled along each image line (judged per pixel by the geocoding
kernel), and the truth's continuous binned profiles (:func:`layover_and_shadow`).
"""

from __future__ import annotations

import numba as nb
import numpy as np
import pyproj
from numpy.typing import NDArray

from levels.geo.inverse_grid import bilinear_grid
from levels.geo.maps import MapGrid
from levels.geometry.dem import Dem
from levels.geometry.ellipsoid import WGS84
from levels.sar.annotation import SarAnnotation, _half_span, _to_geo
from levels.threads import over_blocks

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


@nb.njit(cache=True, nogil=True)
def _kernel_profile_rows(
    lo, hi, lattice, s_a, s_b, per, line0, n_rows, n_cols, z, h_mid, inv_span, profiles
):  # fmt: skip
    """Rows ``lo … hi − 1`` of the terrain's profiles (:func:`_profiles`): row ``k`` the
    zero-Doppler line ``line0 + k·per``, its samples the terrain there at ground ranges
    evenly spaced. ``lattice`` (every ``s_a`` rows and ``s_b`` samples), bilinearly: each
    sample's output pixel (row, column) and DEM (row, column) at the middle height, and
    the anchors' (line, column, look) there as polynomials in height (:func:`_in_height`,
    the coefficients of each after the four). The DEM's height read there (bilinearly;
    outside or over a void, none), the sample is moved along the lattice by what that
    height shifts its line (the zero-Doppler plane leans a little from the vertical:
    0.14 line a kilometre for ERS-1), its height following the DEM cell's bilinear
    surface; its column and look angle at that height. Then each row's running maxima
    outwards (range, look: ``profiles[..., 0]``, ``[..., 2]``) and minima inwards (range:
    ``[..., 1]``); −∞ and +∞ where no terrain is yet; samples outside the output grid or
    the DEM skipped."""
    n_q, nla, nlb = lattice.shape
    n_lev = (n_q - 4) // 3
    nr, nc = z.shape
    n_u = profiles.shape[1]
    raw = np.empty((2, n_u))  # the row's ranges and looks
    val = np.empty((n_q, nlb))  # the lattice down to the row, and its change per row
    dval = np.empty((n_q, nlb))
    inv_a, inv_b = 1.0 / s_a, 1.0 / s_b
    inv_per = 1.0 / per
    for kr in range(lo, hi):
        a = min(kr // s_a, nla - 2)
        fu = (kr - a * s_a) * inv_a
        for q in range(n_q):
            for b in range(nlb):
                val[q, b] = (1.0 - fu) * lattice[q, a, b] + fu * lattice[q, a + 1, b]
                dval[q, b] = (lattice[q, a + 1, b] - lattice[q, a, b]) * inv_a
        target = line0 + kr * per
        b, mb = 0, -1  # the lattice column about m, and m's offset from it (counted)
        for m in range(n_u):
            mb += 1
            if mb == s_b and b < nlb - 2:
                b, mb = b + 1, 0
            fv = mb * inv_b
            gv = 1.0 - fv
            r_out = np.nan
            look_out = np.nan
            pi = gv * val[0, b] + fv * val[0, b + 1]
            pj = gv * val[1, b] + fv * val[1, b + 1]
            drow = gv * val[2, b] + fv * val[2, b + 1]
            dcol = gv * val[3, b] + fv * val[3, b + 1]
            if (
                0.0 <= pi <= n_rows - 1
                and 0.0 <= pj <= n_cols - 1
                and 0.0 <= drow <= nr - 1
                and 0.0 <= dcol <= nc - 1
            ):
                p0 = min(int(drow), nr - 2)
                q0 = min(int(dcol), nc - 2)
                s, t = drow - p0, dcol - q0
                z00, z01 = z[p0, q0], z[p0, q0 + 1]
                z10, z11 = z[p0 + 1, q0], z[p0 + 1, q0 + 1]
                h = (1 - s) * ((1 - t) * z00 + t * z01) + s * ((1 - t) * z10 + t * z11)
                if h == h:
                    x = (h - h_mid) * inv_span
                    line_h = 0.0
                    for k in range(n_lev - 1, -1, -1):
                        line_h = line_h * x + (gv * val[4 + k, b] + fv * val[4 + k, b + 1])
                    shift = (target - line_h) * inv_per  # rows along the lattice onto the line
                    ds = shift * (gv * dval[2, b] + fv * dval[2, b + 1])
                    dt = shift * (gv * dval[3, b] + fv * dval[3, b + 1])
                    h += ds * ((1 - t) * (z10 - z00) + t * (z11 - z01)) + dt * (
                        (1 - s) * (z01 - z00) + s * (z11 - z10)
                    )
                    x = (h - h_mid) * inv_span
                    r_out = 0.0
                    look_out = 0.0
                    for k in range(n_lev - 1, -1, -1):
                        c = 4 + n_lev + k
                        r_out = r_out * x + (
                            gv * (val[c, b] + shift * dval[c, b])
                            + fv * (val[c, b + 1] + shift * dval[c, b + 1])
                        )
                        c += n_lev
                        look_out = look_out * x + (
                            gv * (val[c, b] + shift * dval[c, b])
                            + fv * (val[c, b + 1] + shift * dval[c, b + 1])
                        )
            raw[0, m] = r_out
            raw[1, m] = look_out
        near_r = near_look = -np.inf
        for m in range(n_u):  # outwards: the farthest range and the largest look so far
            v = raw[0, m]
            if v == v:
                near_r = max(near_r, v)
                near_look = max(near_look, raw[1, m])
            profiles[kr, m, 0] = near_r
            profiles[kr, m, 2] = near_look
        far_r = np.inf
        for m in range(n_u - 1, -1, -1):  # inwards: the nearest range so far
            v = raw[0, m]
            if v == v:
                far_r = min(far_r, v)
            profiles[kr, m, 1] = far_r


def mask_oversample(dem: Dem, grid: MapGrid, most: int = 4) -> int:
    """Profile samples per output pixel (each way) that the layover and shadow profiles
    take to follow the DEM's own resolution: the output pixel over half the DEM's spacing
    (metres; degrees at the grid's latitude; the bilinear surface bends at the DEM's
    nodes, and samples twice as fine catch a cliff's edge), rounded up, at most ``most``."""
    sx, sy = dem.spacing
    if pyproj.CRS.from_wkt(dem.crs_wkt).is_geographic:
        x, y = grid.map_of(np.array([grid.n_rows / 2]), np.array([grid.n_cols / 2]))
        _, lat = _to_geo(grid).transform(x, y)
        m = np.radians(1.0) * WGS84.a_m
        sx, sy = sx * m * np.cos(np.radians(float(lat[0]))), sy * m
    return int(min(most, max(1, np.ceil(2 * grid.pixel_size_m / min(sx, sy) - 1e-6))))


#: Slant pixels beyond the image within which an output pixel is still geocoded (and
#: an anchor cell more about it): the frame's edge and its interpolation.
_FRAME_MARGIN_PX = 2.0
#: Profile rows and samples between the exact points of the profiles' lattice (the
#: ground under a line is nearly straight, across it a hyperbola: 2e-3 px at most
#: interpolated on ERS-1's 100 km frame at 12.5 m).
PROFILE_LATTICE_STEP = (64, 16)


def _profiles(
    ann: SarAnnotation,
    grid: MapGrid,
    coef: NDArray[np.float64],
    levels: NDArray[np.float64],
    dem: Dem,
    z: NDArray[np.float64],
    per_node: int,
    step_px: int,
) -> tuple[NDArray[np.float32], NDArray[np.float64]]:
    """The terrain's zero-Doppler profiles for the layover and shadow masks: a row per
    image line ``line0 + k·per`` (one per output pixel along the track, ``per_node`` times
    finer: :func:`mask_oversample`), the terrain along it sampled at ground ranges
    ``u0 + m·du`` (``u``: the column at the middle height, ``per_node`` samples per output
    pixel across the track); each sample's range (columns) and look angle, as running
    maxima and minima (:func:`_kernel_profile_rows`). The rows cover the image's lines;
    the samples its columns and, beyond them, what the relief can fold onto them or hide
    them with (below).
    Returns the profiles ``(rows, samples, 3)`` and ``(line0, per, u0, du)``."""
    n_l, n_s = ann.shape
    u = coef[0, 1]  # the column at the middle height
    du_px = np.hypot(np.diff(u, axis=0)[:, :-1], np.diff(u, axis=1)[:-1, :]) / step_px
    line_px = (
        np.hypot(np.diff(coef[0, 0], axis=0)[:, :-1], np.diff(coef[0, 0], axis=1)[:-1, :]) / step_px
    )
    inside = (u[:-1, :-1] >= 0) & (u[:-1, :-1] <= n_s - 1)
    du = float(np.nanmedian(du_px[inside] if inside.any() else du_px)) / per_node
    per = float(np.nanmax(line_px)) / per_node
    # what can fold onto or hide a pixel of the image, in columns (flat Earth, 10 % over):
    # a pixel's column lies within half the relief of its column at the middle height;
    # a fold's range lies in the image; what hides a pixel stands within relief · tan θ
    # of it on the ground, relief · tan θ · sin θ in range (θ the incidence, largest at
    # the far range)
    h_mid = float(np.mean(levels))
    far = ann.ground_of_image(np.array([0.5 * (n_l - 1)]), np.array([n_s - 1.0]), h_mid)
    inc = float(ann.incidence(*far, np.array([h_mid]))[0])
    relief = 1.1 * float(levels[-1] - levels[0]) / ann.range_spacing_m
    u_lo = max(float(np.nanmin(u)), -(0.5 + np.tan(inc) * np.sin(inc)) * relief - 4.0)
    u_hi = min(float(np.nanmax(u)), n_s - 1 + 0.5 * relief + 4.0)
    line0, u0 = -per, u_lo - 2.0 * du
    n_p = int(np.ceil((n_l - 1 - line0) / per)) + 2
    n_u = int(np.ceil((u_hi - u0) / du)) + 3
    s_a, s_b = PROFILE_LATTICE_STEP
    la = line0 + np.arange(-(-(n_p - 1) // s_a) + 2) * s_a * per
    lb = u0 + np.arange(-(-(n_u - 1) // s_b) + 2) * s_b * du
    ll, uu = np.meshgrid(la, lb, indexing="ij")
    lat, lon = ann.ground_of_image(ll, uu, h_mid)
    to_map = pyproj.Transformer.from_crs(
        pyproj.CRS.from_epsg(4326), pyproj.CRS.from_wkt(grid.crs_wkt), always_xy=True
    )
    e, n = to_map.transform(np.degrees(lon), np.degrees(lat))
    li, lj = grid.ij_of_map(e, n)
    to_dem = pyproj.Transformer.from_crs(
        pyproj.CRS.from_epsg(4326), pyproj.CRS.from_wkt(dem.crs_wkt), always_xy=True
    )
    dr, dc = dem.pixel_of(
        *(np.asarray(v) for v in to_dem.transform(np.degrees(lon), np.degrees(lat)))
    )
    rows = np.arange(coef.shape[2], dtype=np.float64) * step_px
    cols = np.arange(coef.shape[3], dtype=np.float64) * step_px
    at_anchors = [
        bilinear_grid(rows, cols, coef[k, c], li, lj) for c in range(3) for k in range(levels.size)
    ]
    lattice = np.ascontiguousarray(np.stack([li, lj, dr, dc, *at_anchors]), dtype=np.float64)
    profiles = np.empty((n_p, n_u, 3), dtype=np.float32)
    over_blocks(
        _kernel_profile_rows,
        n_p,
        lattice,
        s_a,
        s_b,
        per,
        line0,
        grid.n_rows,
        grid.n_cols,
        z,
        h_mid,
        1.0 / _half_span(levels),
        profiles,
        grain=16,
    )
    return profiles, np.array([line0, per, u0, du])
