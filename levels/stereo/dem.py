"""The pair's DEM: the triangulated points gridded on a map grid, blunder cells removed, and
:func:`stereo_dem`, the chain from epipolar images to the DEM.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from levels.geo.maps import MapGrid
from levels.stereo.epipolar import EpipolarPair
from levels.stereo.matching import REFINE_WINDOW_PX, Disparity, coarse_range, match
from levels.stereo.triangulation import StereoPoints, _mean_correlation, triangulate

_log = logging.getLogger(__name__)


def grid_points(
    points: StereoPoints, grid: MapGrid, window: int = REFINE_WINDOW_PX
) -> tuple[NDArray[np.float32], NDArray[np.uint16], NDArray[np.float32]]:
    """Heights (NaN: a hole), point counts and predicted σ (m) on ``grid`` (step 4)."""
    i, j = grid.ij_of_map(points.x_m, points.y_m)
    i, j = np.rint(i).astype(np.int64), np.rint(j).astype(np.int64)
    inside = (i >= 0) & (i < grid.n_rows) & (j >= 0) & (j < grid.n_cols) & np.isfinite(points.h_m)
    k = i[inside] * grid.n_cols + j[inside]
    size = grid.n_rows * grid.n_cols
    n = np.bincount(k, minlength=size)
    s = np.bincount(k, points.h_m[inside], minlength=size)
    s2 = np.bincount(k, points.sigma_h_m[inside] ** 2, minlength=size)
    with np.errstate(invalid="ignore", divide="ignore"):
        h = np.where(n > 0, s / n, np.nan)
        var = s2 / n  # the points' mean variance
    m = max(1, round(abs(grid.geotransform[1]) / (points.pixel_m * points.stride)))
    rho = _mean_correlation(m, points.stride, window)
    sigma = np.sqrt(var * (rho + (1.0 - rho) / np.maximum(n, 1)))
    shape = (grid.n_rows, grid.n_cols)
    return (
        h.reshape(shape).astype(np.float32),
        np.minimum(n, 65535).reshape(shape).astype(np.uint16),
        np.where(n > 0, sigma, np.nan).reshape(shape).astype(np.float32),
    )


@dataclass(frozen=True, eq=False)
class StereoDem:
    """A pair's DEM: heights on a map grid (NaN: holes), points per cell, predicted σ, and
    the pair, its disparity, its points and timings."""

    grid: MapGrid
    height_m: NDArray[np.float32]
    count: NDArray[np.uint16]
    sigma_m: NDArray[np.float32]
    pair: EpipolarPair
    disparity: Disparity
    points: StereoPoints
    disparity_range_px: tuple[float, float]
    timings_s: dict[str, float]
    anchor_error_m: float  # the triangulation grid's largest error on its checks


def stereo_dem(
    pair: EpipolarPair,
    d_range: tuple[float, float],
    cell_px: int = 2,
    stride: int = 1,
) -> StereoDem:
    """The pair's DEM (module docstring): epipolar images, matching over ``d_range``,
    triangulation of every ``stride``-th pixel, gridding on ``cell_px`` pixels."""
    import time

    t: dict[str, float] = {}
    t0 = time.perf_counter()
    left, right = pair.image(0), pair.image(1)
    t["resample"] = time.perf_counter() - t0
    _log.info(
        "stereo: epipolar images %d × %d resampled in %.1f s; matching",
        *left.shape,
        t["resample"],
    )
    t0 = time.perf_counter()
    d_range = coarse_range(left, right, d_range)
    disparity = match(left, right, *d_range)
    t["match"] = time.perf_counter() - t0
    _log.info(
        "stereo: %d pixels matched in %.1f s (disparity %.1f to %.1f px); triangulating",
        disparity.counts.get("valid", 0),
        t["match"],
        *d_range,
    )
    t0 = time.perf_counter()
    points, anchor_error = triangulate(pair, disparity, d_range, stride)
    t["triangulate"] = time.perf_counter() - t0
    _log.info("stereo: triangulated in %.1f s; gridding", t["triangulate"])
    t0 = time.perf_counter()
    grid = dem_grid(points, pair.frame.crs_wkt, cell_px * pair.frame.pixel_m)
    h, n, sigma = grid_points(points, grid)
    wild = blunder_cells(h, BLUNDER_FLOOR_PX * pair.height_per_px_m)
    h[wild], sigma[wild], n[wild] = np.nan, np.nan, 0
    disparity.counts["blunder_cells"] = int(wild.sum())
    t["grid"] = time.perf_counter() - t0
    return StereoDem(grid, h, n, sigma, pair, disparity, points, d_range, t, anchor_error)


#: Blunder cells (:func:`blunder_cells`): the reference surface's block (cells), and how far
#: from it a cell may lie, in robust σ of all cells' deviations, and at least in pixels of
#: disparity.
BLUNDER_BLOCK = 8
BLUNDER_SIGMAS = 6.0
BLUNDER_FLOOR_PX = 3.0


def blunder_cells(h: NDArray[np.float32], floor_m: float) -> NDArray[np.bool_]:
    """Cells of a gridded DEM far off the surface of their neighbourhood: wrong matches that
    survived the matcher's tests (a patch matched at the end of the search range). The
    surface: the median of each ``BLUNDER_BLOCK``² block's valid cells, bilinear between
    blocks; a cell is a blunder beyond ``BLUNDER_SIGMAS`` robust σ of every cell's
    deviation from it, and beyond ``floor_m``."""
    from scipy import ndimage

    b = BLUNDER_BLOCK
    rows, cols = h.shape
    pad = np.full((-(-rows // b) * b, -(-cols // b) * b), np.nan, dtype=np.float32)
    pad[:rows, :cols] = h
    blocks = pad.reshape(pad.shape[0] // b, b, pad.shape[1] // b, b).transpose(0, 2, 1, 3)
    with np.errstate(all="ignore"):
        import warnings

        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN blocks
            med = np.nanmedian(blocks.reshape(*blocks.shape[:2], -1), axis=2)
    have = np.isfinite(med)
    if not have.any():
        return np.zeros(h.shape, dtype=bool)
    # empty blocks take their nearest block's median
    near = ndimage.distance_transform_edt(~have, return_distances=False, return_indices=True)
    med = med[tuple(near)]
    r = (np.arange(rows) + 0.5) / b - 0.5
    c = (np.arange(cols) + 0.5) / b - 0.5
    rr, cc = np.meshgrid(r, c, indexing="ij")
    surface = ndimage.map_coordinates(med, [rr, cc], order=1, mode="nearest")
    dev = h - surface
    ok = np.isfinite(dev)
    if not ok.any():
        return np.zeros(h.shape, dtype=bool)
    spread = 1.4826 * float(np.median(np.abs(dev[ok])))
    return ok & (np.abs(dev) > max(BLUNDER_SIGMAS * spread, floor_m))


def dem_grid(points: StereoPoints, crs_wkt: str, cell_m: float) -> MapGrid:
    """A north-up grid of ``cell_m`` over the points, its nodes on multiples of it."""
    x0 = np.floor(np.nanmin(points.x_m) / cell_m) * cell_m
    x1 = np.ceil(np.nanmax(points.x_m) / cell_m) * cell_m
    y0 = np.floor(np.nanmin(points.y_m) / cell_m) * cell_m
    y1 = np.ceil(np.nanmax(points.y_m) / cell_m) * cell_m
    rows, cols = round((y1 - y0) / cell_m) + 1, round((x1 - x0) / cell_m) + 1
    return MapGrid.north_up(crs_wkt, x0 - cell_m / 2, y1 + cell_m / 2, cell_m, rows, cols)
