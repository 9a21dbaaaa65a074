"""Layover and shadow by their standard definitions on the terrain's zero-Doppler profiles
sampled along each image line (judged per pixel by the geocoding kernel). The truth's own,
on continuous binned profiles of the world's terrain, is
:func:`station.spacecraft.sar_masks.layover_and_shadow`.
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
    them with (:func:`_profile_extent`).
    Returns the profiles ``(rows, samples, 3)`` and ``(line0, per, u0, du)``."""
    line0, per, u0, du, n_p, n_u = _profile_extent(ann, coef, levels, per_node, step_px)
    s_a, s_b = PROFILE_LATTICE_STEP
    la = line0 + np.arange(-(-(n_p - 1) // s_a) + 2) * s_a * per
    lb = u0 + np.arange(-(-(n_u - 1) // s_b) + 2) * s_b * du
    h_mid = float(np.mean(levels))
    lattice = _lattice(ann, grid, dem, coef, levels, la, lb, step_px)
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


def _profile_extent(
    ann: SarAnnotation,
    coef: NDArray[np.float64],
    levels: NDArray[np.float64],
    per_node: int,
    step_px: int,
) -> tuple[float, float, float, float, int, int]:
    """The profiles' rows and samples (:func:`_profiles`): ``(line0, per, u0, du)`` and
    their numbers, the samples covering the image's columns and what the relief can fold
    onto them or hide them with."""
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
    return line0, per, u0, du, n_p, n_u


def _lattice(
    ann: SarAnnotation,
    grid: MapGrid,
    dem: Dem,
    coef: NDArray[np.float64],
    levels: NDArray[np.float64],
    la: NDArray[np.floating],
    lb: NDArray[np.floating],
    step_px: int,
) -> NDArray[np.float64]:
    """The profiles' lattice of exact points (lines ``la`` × ground ranges ``lb``): each
    point's output row and column, DEM row and column, and the anchors' coefficients
    there, stacked for :func:`_kernel_profile_rows`."""
    ll, uu = np.meshgrid(la, lb, indexing="ij")
    lat, lon = ann.ground_of_image(ll, uu, float(np.mean(levels)))
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
    return np.ascontiguousarray(np.stack([li, lj, dr, dc, *at_anchors]), dtype=np.float64)
