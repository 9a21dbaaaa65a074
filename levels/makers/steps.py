"""The steps several levels share (:func:`levels.makers.base.scene_step`): made once per
scene for whichever level asks first.

- the map CRS of the scene, and the ``geometry`` tree every level's product shares;
- the radiometry of the resampled levels (the deconvolution and the MTF it gives);
- the geometry of each level: 1B's polynomials, 2A's grids (which level 2 also reads for
  its "before" checkpoints), level 2's refined model (which level 3 uses when level 2 is
  made too) and grids, level 3's anchor grids (whose heights bound the RPCs of 1A and 1B);
- the RPCs of the image-geometry levels.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import pyproj

from levels.choices import Level
from levels.cor.radiometry import fir_response, mtf
from levels.geo.level1b import Level1BGeometry, level1b_geometry
from levels.geo.level2a import Level2AGeometry, level2a_geometry
from levels.geo.level3 import Level3Geometry, level3_geometry
from levels.geo.maps import MapGrid, ascending_node_lon_rad, map_crs
from levels.geo.rpc import RPC_HEIGHT_MARGIN_M, Rpc, rpc_of_1b, rpc_of_model
from levels.geo.scenes import SceneGeometry
from levels.makers.base import SceneWork, per_band, scene_step

__all__ = [
    "checkpoints_2a",
    "common_tree",
    "first_map_grid",
    "geometry_1b",
    "geometry_2",
    "geometry_2a",
    "geometry_3",
    "radiometry",
    "refined_scene",
    "rpc_1a",
    "rpc_1b",
    "rpc_heights",
    "scene_3",
    "scene_crs",
]


@scene_step
def common_tree(work: SceneWork) -> dict[str, object]:
    """The part of the ``geometry`` tree the system-corrected levels share
    (:meth:`levels.geo.scenes.PassGeometry.product_tree`)."""
    return work.ctx.pg.product_tree(work.scene)


@scene_step
def scene_crs(work: SceneWork) -> pyproj.CRS:
    """The map CRS of the scene's map levels (``[processing] crs``), at the system scene's
    centre."""
    opt, scene = work.options, work.scene
    node = ascending_node_lon_rad(work.ctx.pg.ephemeris) if opt.crs == "som" else None
    return map_crs(opt.crs, scene.centre_lat_rad, scene.centre_lon_rad, node)


@scene_step
def radiometry(work: SceneWork) -> dict[str, object]:
    """The deconvolution of the resampled levels, and the MTF at Nyquist before and after."""
    taps = work.ctx.taps
    nyquist = np.array([0.5])
    before = float(mtf(nyquist, work.options.psf_fwhm_px)[0])
    return {
        "deconvolution_taps": taps,
        "mtf_at_nyquist_before": before,
        "mtf_at_nyquist_after": before * abs(float(fir_response(taps, nyquist)[0])),
    }


@scene_step
def geometry_1b(work: SceneWork) -> dict[str, Level1BGeometry]:
    """1B's tangent plane and polynomials f, g, h per band (:mod:`levels.geo.level1b`)."""
    scene, res = work.scene, work.ctx.pixel_size_m
    return per_band(scene, lambda b, like: level1b_geometry(scene, res, band=b, like=like))


def _grid_choices(work: SceneWork) -> dict[str, Any]:
    """How the direct grids of the map levels are laid (``[processing] grid_rows``,
    ``grid_columns``)."""
    return {"grid_rows": work.options.grid_rows, "grid_columns": work.options.grid_columns}


def _map_geometry(work: SceneWork, sg: SceneGeometry) -> dict[str, Level2AGeometry]:
    opt, res, crs = work.options, work.ctx.pixel_size_m, scene_crs(work)
    return per_band(
        sg,
        lambda b, like: level2a_geometry(
            sg,
            res,
            crs,
            opt.inverse_2a,
            band=b,
            like=like,
            **_grid_choices(work),
        ),
    )


@scene_step
def geometry_2a(work: SceneWork) -> dict[str, Level2AGeometry]:
    """2A's direct grids and their inverse per band, on the system model."""
    return _map_geometry(work, work.scene)


@scene_step
def checkpoints_2a(work: SceneWork) -> dict[str, Any] | None:
    """The checkpoint errors of 2A's grids per band, when there is a checkpoint source:
    level 2A's, and level 2's "before"."""
    cp = work.ctx.checkpoints
    if cp is None:
        return None
    g2a, per_side = geometry_2a(work), work.options.checkpoints_per_side
    return {b: cp.level_2a(work.scene, g2a[b], k, per_side) for k, b in enumerate(work.bands)}


@scene_step
def refined_scene(work: SceneWork) -> SceneGeometry:
    """The scene on the ephemeris and attitude refined by level 2's adjustment."""
    adjustment = work.ctx.adjustment
    if adjustment is None:
        raise AssertionError("a level that needs the adjustment was planned without one")
    return adjustment.refine(work.ctx.pg, work.scene)


@scene_step
def geometry_2(work: SceneWork) -> dict[str, Level2AGeometry]:
    """Level 2's grids per band: 2A's, on the refined model."""
    return _map_geometry(work, refined_scene(work))


def scene_3(work: SceneWork) -> SceneGeometry:
    """The model level 3 is made on: level 2's refined one when level 2 is made too, the
    system model otherwise."""
    return refined_scene(work) if work.makes(Level.L2) else work.scene


@scene_step
def geometry_3(work: SceneWork) -> dict[str, Level3Geometry]:
    """Level 3's anchor grids over the DEM per band (:mod:`levels.geo.level3`)."""
    opt, res, crs, dem = work.options, work.ctx.pixel_size_m, scene_crs(work), work.ctx.dem
    if dem is None:
        raise AssertionError("level 3 was planned without a DEM")
    sg = scene_3(work)
    return per_band(
        sg,
        lambda b, like: level3_geometry(
            sg,
            dem,
            res,
            crs,
            opt.inverse_2a,
            band=b,
            like=like,
            **_grid_choices(work),
        ),
    )


def rpc_heights(work: SceneWork) -> tuple[float, float]:
    """The heights the RPCs of 1A and 1B are fitted over: those of level 3's DEM under the
    scene when level 3 is made, else the reference height ± ``RPC_HEIGHT_MARGIN_M``."""
    if work.makes(Level.L3):
        h = next(iter(geometry_3(work).values())).heights_m
        return float(h[0]), float(h[-1])
    ref = work.options.reference_height_m
    return ref - RPC_HEIGHT_MARGIN_M, ref + RPC_HEIGHT_MARGIN_M


@scene_step
def rpc_1a(work: SceneWork) -> dict[str, Rpc]:
    """The RPCs of 1A per band, fitted to the rigorous model (:mod:`levels.geo.rpc`)."""
    heights = rpc_heights(work)
    return {b: rpc_of_model(m, heights) for b, m in work.scene.models.items()}


@scene_step
def rpc_1b(work: SceneWork) -> dict[str, Rpc]:
    """The RPCs of 1B per band: the rigorous model through 1B's polynomials."""
    heights, g1b, models = rpc_heights(work), geometry_1b(work), work.scene.models
    return {b: rpc_of_1b(models[b], g1b[b], heights) for b in models}


def first_map_grid(bands: Mapping[str, Level2AGeometry | Level3Geometry]) -> MapGrid:
    """The output grid of a map level: the first band's (the others share it)."""
    first: Level2AGeometry | Level3Geometry = next(iter(bands.values()))
    return first.map_grid
