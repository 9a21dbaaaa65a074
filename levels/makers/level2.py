"""Level 2: 2A on the model refined with control points (Westin's adjustment,
:mod:`levels.adjust`), the precision product of paper ``004_…`` §1.

Its quality: the inverse against the refined model, the control points of the scene after
the adjustment (used, rejected as blunders, their RMS residual), the accuracy the
adjustment predicts and, with a checkpoint source, the checkpoint errors after (on the
refined model) and before (2A's, at the same points).
"""

from __future__ import annotations

import numpy as np

from levels.choices import Level
from levels.cor.resample import resample_2a
from levels.geo.level2a import Level2AGeometry
from levels.kinds import Export
from levels.makers.base import BandPixels, LevelMaker, Need, SceneWork
from levels.makers.scene import adjustment_section, scene_kind
from levels.makers.steps import (
    checkpoints_2a,
    first_map_grid,
    geometry_2,
    radiometry,
    refined_scene,
)
from levels.products import BandImage, MapGrid

__all__ = ["KIND", "MAKER"]


def _image(work: SceneWork, band: str, px: BandPixels) -> BandImage:
    g = geometry_2(work)[band]
    return BandImage(*resample_2a(px.values, None, g, work.options.resampling_2a))


def _adjustment_figures(work: SceneWork) -> dict[str, object]:
    adjustment = work.ctx.adjustment
    assert adjustment is not None  # Need.ADJUSTMENT: the driver made it
    k = adjustment.of_scene(work.scene.cut.index)
    mine = adjustment.point_scene == work.scene.cut.index
    status = np.array(adjustment.point_status)
    used = mine & (status == "used")
    after = np.hypot(*adjustment.residual_after_px[used].T)
    sigma = adjustment.predicted_sigma_m[k]
    return {
        "predicted_sigma_m": {
            "east": float(sigma[0]),
            "north": float(sigma[1]),
            "horizontal": float(sigma[2]),
            "prior_horizontal": float(adjustment.prior_sigma_m[k, 2]),
        },
        "control_points": {
            "used": int(used.sum()),
            "rejected": int(np.sum(mine & (status == "rejected"))),
            "residual_rms_px": float(np.sqrt(np.mean(after**2))) if after.size else None,
        },
    }


def _quality(work: SceneWork) -> dict[str, object]:
    refined, g2 = refined_scene(work), geometry_2(work)
    g = g2[work.bands[0]]
    q: dict[str, object] = {
        "inverse_vs_model": {
            g.method: g.approximation_error(refined.model, refined.reference_height_m, g.method)
        },
        "inverse_method": g.method,
        "radiometry": radiometry(work),
        **_adjustment_figures(work),
    }
    cp, per_side = work.ctx.checkpoints, work.options.checkpoints_per_side
    if cp is not None:
        q["checkpoints"] = {
            b: cp.level_2a(refined, g2[b], i, per_side) for i, b in enumerate(work.bands)
        }
        q["checkpoints_2a"] = checkpoints_2a(work)
    return q


def _geometry_tree(work: SceneWork) -> dict[str, object]:
    adjustment = work.ctx.adjustment
    assert adjustment is not None
    return {
        **work.ctx.pg.product_tree(refined_scene(work)),
        "level_2a": Level2AGeometry.product_tree(geometry_2(work)),
        "adjustment": adjustment.product_tree(work.scene.cut.index),
    }


def _map_grid(work: SceneWork) -> MapGrid:
    return first_map_grid(geometry_2(work))


MAKER = LevelMaker(
    name=Level.L2,
    doc="2A on the model refined with control points",
    image=_image,
    quality=_quality,
    geometry_tree=_geometry_tree,
    prepare=geometry_2,
    map_grid=_map_grid,
    needs=frozenset({Need.ADJUSTMENT}),
)

#: The level's kind (:mod:`levels.kinds`, named in :mod:`levels.registry`).
KIND = scene_kind(MAKER, Export.MAP, ("scene", "level_2a", "adjustment"), adjustment_section)
