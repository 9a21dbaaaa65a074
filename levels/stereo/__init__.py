"""Stereo: a DEM from two overlapping scenes of different passes (PHOTOMOD, paper ``003_…``),
on their adjusted models (level 2 of a block, :mod:`levels.adjust`).

1. **Epipolar grid from the rigorous model.** Each scene's raw image is resampled onto one
   grid on the plane at the pair's reference height ``h0`` (both level 2s' own), turned so
   that its rows are epipolar lines: a ground point at height ``h`` appears in a scene's
   map image at ``h0`` moved by ``(h − h0)·a`` along its view's horizontal tilt ``a``
   (metres per metre), so between the two by ``(h − h0)·(a_b − a_a)``: the grid's ``u``
   axis is the direction of ``a_b − a_a``, and a point's images differ only in ``u``, by
   the disparity ``d = (h − h0)·|a_b − a_a| / pixel``. ``a`` is measured through the model
   (ground → raw → plane) over the scene; what ``a`` turns across it is the *epipolar
   error* (the ``v``-parallax over the height range, pixels), stored with the pair. The grid
   reaches the raw image through each level 2's inverse grid (the adjusted model at
   ``h0``, :class:`~levels.geo.level2a.Level2AGeometry`), sampled at nodes every
   ``NODE_STEP_PX`` (a CCD segment's lines apart), and both images are resampled with the
   COR kernel (:func:`levels.cor.epipolar.resample_epipolar`): the 2A arithmetic, the raw
   image read once.
2. **Dense matching** by OpenCV's semi-global matching (``StereoSGBM``, Hirschmüller 2008)
   over the disparity range the pair's tie points give, its uniqueness and left–right
   checks and speckle filter; then each pixel's disparity refined to a fraction of a pixel
   by least-squares matching in a ``REFINE_WINDOW_PX`` window (Lucas–Kanade along the row,
   :func:`levels.cor.epipolar.window_solve`): SGBM's 1/16 px parabola is biased toward
   whole pixels ("pixel locking"), the least-squares solution is not. The window is warped
   by each of its pixels' own disparity and fits the disparity as a plane (its value at
   the centre, its two slopes), an offset and a shift across the row (the ``v``-parallax
   the grid leaves): a window that solved for one shift gave the mean of its pixels'
   disparities weighted by their texture, off on every slope (full P pair: 0.34 → 0.22 px
   RMS, docs/stereo.md). Its a posteriori σ (Förstner: the residual variance times the
   shift's term of the inverse normal matrix) is each pixel's matching σ. A pixel is
   refused when SGBM found no unique match, the refinement moved it more than
   ``MAX_REFINE_PX`` or failed, its window is flat, or its σ exceeds ``MAX_SIGMA_PX``.
3. **Triangulation** by the middle of the common perpendicular of the two lines of sight
   (PHOTOMOD), the miss kept per point.
4. **Gridding** onto a north-up map grid of ``cell_px`` pixels: the mean of the points in
   each cell, their count, and the predicted σ of the mean (the points' matching σ times
   the metres of height per pixel of disparity, reduced by the number of independent
   windows in the cell); cells without a point are holes (NaN), never filled.

The package, by stage: :mod:`~levels.stereo.epipolar`, :mod:`~levels.stereo.matching`,
:mod:`~levels.stereo.triangulation`, :mod:`~levels.stereo.dem`.
"""

from levels.stereo.dem import (
    BLUNDER_FLOOR_PX,
    StereoDem,
    blunder_cells,
    dem_grid,
    grid_points,
    stereo_dem,
)
from levels.stereo.epipolar import (
    NODE_STEP_PX,
    EpipolarFrame,
    EpipolarPair,
    StereoView,
    epipolar_pair,
)
from levels.stereo.matching import (
    MAX_REFINE_PX,
    MAX_SIGMA_PX,
    REFINE_WINDOW_PX,
    Disparity,
    coarse_range,
    disparity_range,
    match,
)
from levels.stereo.triangulation import StereoPoints, closest_approach, triangulate, triangulate_raw

__all__ = [
    "BLUNDER_FLOOR_PX",
    "MAX_REFINE_PX",
    "MAX_SIGMA_PX",
    "NODE_STEP_PX",
    "REFINE_WINDOW_PX",
    "Disparity",
    "EpipolarFrame",
    "EpipolarPair",
    "StereoDem",
    "StereoPoints",
    "StereoView",
    "blunder_cells",
    "closest_approach",
    "coarse_range",
    "dem_grid",
    "disparity_range",
    "epipolar_pair",
    "grid_points",
    "match",
    "stereo_dem",
    "triangulate",
    "triangulate_raw",
]
