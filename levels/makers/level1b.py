"""Level 1B: 1A resampled along the lines and columns of a tangent plane through INPE's
polynomials f, g, h (paper ``004_…`` eqs. 1–3, :mod:`levels.geo.level1b`), with RPCs.

Its quality: the polynomials against the rigorous model (the first band's; the others'
fits are the same polynomials a few tenths of a pixel apart, and their checkpoints measure
each band) and, with a checkpoint source, the checkpoint errors per band.
"""

from __future__ import annotations

from levels.choices import Level
from levels.cor.resample import resample_1b
from levels.geo.level1b import Level1BGeometry
from levels.kinds import Export
from levels.makers.base import BandPixels, LevelMaker, SceneWork
from levels.makers.scene import plane_section, rpc_section, scene_kind
from levels.makers.steps import common_tree, geometry_1b, radiometry, rpc_1b
from levels.products import BandImage

__all__ = ["KIND", "MAKER"]


def _prepare(work: SceneWork) -> None:
    geometry_1b(work)
    rpc_1b(work)


def _image(work: SceneWork, band: str, px: BandPixels) -> BandImage:
    g = geometry_1b(work)[band]
    opts = work.options
    return BandImage(*resample_1b(px.values, None, g, opts.interpolation_1b, lines=opts.lines_1b))


def _quality(work: SceneWork) -> dict[str, object]:
    scene, g1b, bands = work.scene, geometry_1b(work), work.bands
    q: dict[str, object] = {
        "radiometry": radiometry(work),
        "polynomials_vs_model": g1b[bands[0]].approximation_error(scene.model),
    }
    cp, per_side = work.ctx.checkpoints, work.options.checkpoints_per_side
    if cp is not None:
        q["checkpoints"] = {b: cp.level_1b(scene, g1b[b], k, per_side) for k, b in enumerate(bands)}
    return q


def _geometry_tree(work: SceneWork) -> dict[str, object]:
    return {
        **common_tree(work),
        "level_1b": Level1BGeometry.product_tree(geometry_1b(work)),
        "rpc": {b: r.product_tree() for b, r in rpc_1b(work).items()},
    }


MAKER = LevelMaker(
    name=Level.L1B,
    doc="1A on INPE's tangent plane through the polynomials f, g, h, with RPCs",
    image=_image,
    quality=_quality,
    geometry_tree=_geometry_tree,
    prepare=_prepare,
)

#: The level's kind (:mod:`levels.kinds`, named in :mod:`levels.registry`).
KIND = scene_kind(MAKER, Export.RPC, ("scene", "level_1b"), rpc_section, plane_section)
