"""Level 1A: the raw image calibrated, in the geometry of the raw pixels (paper ``004_…``
§2.2: COR's radiometric correction of the detectors' gains and offsets; no resampling).

Its quality is the stripe level before and after calibration; its geometry tree carries the
pass's shared tree and RPCs fitted to the rigorous model, so that GDAL can orthorectify it.
"""

from __future__ import annotations

from levels.choices import Level
from levels.cor.radiometry import stripe_level, to_counts
from levels.kinds import Export
from levels.makers.base import BandPixels, LevelMaker, Reads, SceneWork
from levels.makers.scene import rpc_section, scene_kind
from levels.makers.steps import common_tree, rpc_1a
from levels.products import BandImage

__all__ = ["KIND", "MAKER"]


def _image(work: SceneWork, band: str, px: BandPixels) -> BandImage:
    work.figures.setdefault("stripe_level", {})[band] = {
        "raw_counts": stripe_level(px.counts, px.valid),
        "level_1a_counts": stripe_level(px.values, px.valid),
    }
    return BandImage(to_counts(px.values), px.valid)


def _quality(work: SceneWork) -> dict[str, object]:
    return {"stripe_level": work.figures["stripe_level"]}


def _geometry_tree(work: SceneWork) -> dict[str, object]:
    return {**common_tree(work), "rpc": {b: r.product_tree() for b, r in rpc_1a(work).items()}}


MAKER = LevelMaker(
    name=Level.L1A,
    doc="the raw image calibrated, with RPCs",
    image=_image,
    quality=_quality,
    geometry_tree=_geometry_tree,
    prepare=rpc_1a,
    reads=Reads.CALIBRATED,
    raw_geometry=True,
)

#: The level's kind (:mod:`levels.kinds`, named in :mod:`levels.registry`).
KIND = scene_kind(MAKER, Export.RPC, ("scene",), rpc_section, stripes=True, counts_fill=None)
