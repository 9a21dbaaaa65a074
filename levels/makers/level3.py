"""Level 3: the ortho-image, relief displacement removed over a DEM (:mod:`levels.geo.level3`:
anchor grids at heights spanning the DEM under the scene), on level 2's refined model when
level 2 is made too, on the system model otherwise.

Its quality: the anchor grids' error against the rigorous model (every band's), the DEM
used, the share of the scene's pixels hidden by the relief and, with a checkpoint source,
the checkpoint errors on the terrain.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from levels.choices import Level
from levels.cor.ortho import resample_3
from levels.geo.level3 import Level3Geometry
from levels.kinds import Export
from levels.makers.base import BandPixels, LevelMaker, Need, SceneWork
from levels.makers.scene import dem_section, scene_kind
from levels.makers.steps import first_map_grid, geometry_3, radiometry, scene_3
from levels.products import BandImage, MapGrid

__all__ = ["KIND", "MAKER"]


def _image(work: SceneWork, band: str, px: BandPixels) -> BandImage:
    image, ok, hidden = resample_3(
        px.values, None, geometry_3(work)[band], work.options.resampling_2a
    )
    # of the pixels the scene covers, the share hidden by the relief
    work.figures.setdefault("hidden_fraction", {})[band] = float(
        hidden.sum() / max(1, int(ok.sum() + hidden.sum()))
    )
    return BandImage(image, ok)


def _model(work: SceneWork) -> str:
    """Which model the ortho-image was made on."""
    if not work.makes(Level.L2):
        return "system"
    adj = work.ctx.adjustment
    if adj is not None and adj.mode == "block":
        return "level 2 (a block adjustment: control and tie points of several passes)"
    return "level 2 (adjusted on control points)"


def _quality(work: SceneWork) -> dict[str, object]:
    g3, bands = geometry_3(work), work.bands
    g = g3[bands[0]]
    lo, hi = g.terrain_range_m
    q: dict[str, object] = {
        "radiometry": radiometry(work),
        "model": _model(work),
        "anchor_error_px": {b: dict(g3[b].anchor_error_px) for b in bands},
        "anchor_step_px": int(g.template.inverse_step[0]),
        "anchor_heights_m": g.heights_m,
        "dem": {
            "source": Path(g.dem.source).name,
            "vertical": g.dem.vertical,
            "spacing_m": g.dem_spacing_m,
            "void_fraction": g.dem.void_fraction,
            "height_min_m": lo if np.isfinite(lo) else None,
            "height_max_m": hi if np.isfinite(hi) else None,
        },
        "hidden_fraction": work.figures["hidden_fraction"],
    }
    cp, per_side = work.ctx.checkpoints, work.options.checkpoints_per_side
    if cp is not None:
        sg = scene_3(work)
        q["checkpoints"] = {b: cp.level_3(sg, g3[b], k, per_side) for k, b in enumerate(bands)}
    return q


def _geometry_tree(work: SceneWork) -> dict[str, object]:
    tree = {
        **work.ctx.pg.product_tree(scene_3(work)),
        "level_3": Level3Geometry.product_tree(geometry_3(work)),
    }
    if work.makes(Level.L2):  # made on level 2's model
        assert work.ctx.adjustment is not None
        tree["adjustment"] = work.ctx.adjustment.product_tree(work.scene.cut.index)
    return tree


def _map_grid(work: SceneWork) -> MapGrid:
    return first_map_grid(geometry_3(work))


MAKER = LevelMaker(
    name=Level.L3,
    doc="the ortho-image over a DEM",
    image=_image,
    quality=_quality,
    geometry_tree=_geometry_tree,
    prepare=geometry_3,
    map_grid=_map_grid,
    needs=frozenset({Need.DEM}),
)

#: The level's kind (:mod:`levels.kinds`, named in :mod:`levels.registry`).
KIND = scene_kind(MAKER, Export.MAP, ("scene", "level_3"), dem_section)
