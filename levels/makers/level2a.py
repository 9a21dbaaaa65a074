"""Level 2A: system-corrected and map-projected through the direct grid of 61 × 61 points
and its inverse (paper ``004_…`` §3, :mod:`levels.geo.level2a`).

Its quality: the inverse mapping against the rigorous model for every inverse method (the
first band's), the one used and, with a checkpoint source, the checkpoint errors per band.
"""

from __future__ import annotations

from levels.choices import InverseMethod, Level
from levels.cor.resample import resample_2a
from levels.geo.level2a import Level2AGeometry
from levels.kinds import Export
from levels.makers.base import BandPixels, LevelMaker, SceneWork
from levels.makers.scene import scene_kind
from levels.makers.steps import (
    checkpoints_2a,
    common_tree,
    first_map_grid,
    geometry_2a,
    radiometry,
)
from levels.products import BandImage, MapGrid

__all__ = ["KIND", "MAKER"]


def _image(work: SceneWork, band: str, px: BandPixels) -> BandImage:
    g = geometry_2a(work)[band]
    return BandImage(*resample_2a(px.values, None, g, work.options.resampling_2a))


def _quality(work: SceneWork) -> dict[str, object]:
    scene = work.scene
    g = geometry_2a(work)[work.bands[0]]
    approx = {
        str(m): g.approximation_error(scene.model, scene.reference_height_m, m)
        for m in InverseMethod
    }
    q: dict[str, object] = {
        "radiometry": radiometry(work),
        "inverse_vs_model": approx,
        "inverse_method": g.method,
    }
    checkpoints = checkpoints_2a(work)
    if checkpoints is not None:
        q["checkpoints"] = checkpoints
    return q


def _geometry_tree(work: SceneWork) -> dict[str, object]:
    return {**common_tree(work), "level_2a": Level2AGeometry.product_tree(geometry_2a(work))}


def _map_grid(work: SceneWork) -> MapGrid:
    return first_map_grid(geometry_2a(work))


MAKER = LevelMaker(
    name=Level.L2A,
    doc="system-corrected, map-projected through the 61 × 61 grid and its inverse",
    image=_image,
    quality=_quality,
    geometry_tree=_geometry_tree,
    prepare=geometry_2a,
    map_grid=_map_grid,
)

#: The level's kind (:mod:`levels.kinds`, named in :mod:`levels.registry`).
KIND = scene_kind(MAKER, Export.MAP, ("scene", "level_2a"))
