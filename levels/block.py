"""Several passes over one ground, planned as one: tie points, the block's level 2, the
products of pairs (a stereo pair's DEM), level 3 over the pair's own DEM.

A :class:`BlockRequest` holds the passes' L0 archives, each pass's control points, the
directories where each pass's scene levels already are (its 1A and 2A, made by
:func:`levels.process.process` per pass), the options and where the block's products go.
:func:`process_block` makes, in order and each once:

1. **tie points** between every two passes' overlapping 2A scenes
   (:func:`levels.tiepoints.match_views`), each pass's merged into ``ties/<pass>.tie.csv``
   (unless the request names a directory of them);
2. with level 2 asked, every pass's **level 2 on one adjustment** (Westin's block: the
   control points of any pass, carried across by the tie points; :mod:`levels.adjust`),
   into ``block/``;
3. the **kinds of a pair** asked (:attr:`levels.kinds.Unit.PAIR`: the DEM), between every
   overlapping pair of the first two passes' scenes, each made by its kind's
   :class:`PairMaker` from the scenes' products and tie points, into ``stereo/`` (the
   product, and a GeoTIFF for a DEM);
4. with level 3 asked and a pair's DEM made, **level 3** of every pass over that DEM, on
   the block's level 2 model, into ``block/``; with level 3 asked and no pair kind, level 3
   over the options' DEM with level 2.

The emulator is not needed: the checkpoints (per archive) and a pair's ``measure`` (what a
pair product is held to; the station's truth, or nothing) are given by the caller.
"""

from __future__ import annotations

import dataclasses
import functools
import itertools
import logging
import operator
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from levels.choices import AdjustmentScope, Level
from levels.errors import GeometryError, OptionsError
from levels.kinds import ProductKind, Unit
from levels.options import ProcessingOptions
from levels.process import (
    PassProducts,
    ProcessingRequest,
    all_made,
    pair_kinds_of,
    plan,
    run_plans,
)
from levels.products import product_name
from levels.quality import CheckpointSource
from levels.readers.gcp import ControlPointSet, read_gcps, write_gcps
from levels.readers.l0 import L0Archive
from levels.registry import kind, kind_names
from levels.tasks import Runner

_log = logging.getLogger(__name__)

__all__ = [
    "BlockProducts",
    "BlockRequest",
    "PairMade",
    "PairMaker",
    "PairScene",
    "pair_kinds",
    "pass_levels",
    "process_block",
    "tie_points",
]

#: Where a block's products go, under its output directory.
TIES, LEVEL2, PAIRS = "ties", "block", "stereo"


@dataclass(frozen=True)
class PairScene:
    """One side of a pair: a scene of a pass and its products by kind (``"2"``, ``"1A"``…)
    and the pass's tie points."""

    name: str
    scene: int
    products: dict[str, Path]
    ties: ControlPointSet


@dataclass(frozen=True)
class PairMade:
    """A pair product made: its path, its export (a GeoTIFF, or None), its quality and the
    wall times of its stages."""

    path: Path
    export: Path | None
    quality: dict[str, Any]
    timings_s: dict[str, float]


#: ``measure(intermediate) -> quality``: what a pair product is held to (the station's
#: truth), from what its maker made on the way (a :class:`levels.stereo.StereoDem`).
Measure = Callable[[Any], dict[str, Any]]


@dataclass(frozen=True)
class PairMaker:
    """What makes a kind of pair (:attr:`levels.kinds.Unit.PAIR`).

    ``make(a, b, out, measure)`` makes the product of scenes ``a`` and ``b`` into ``out``
    (the product and its export), or returns None when the two do not overlap; ``needs``
    the kinds each scene's products must include."""

    make: Callable[[PairScene, PairScene, Path, Measure | None], PairMade | None]
    needs: tuple[str, ...] = (Level.L1A, Level.L2)


@dataclass(frozen=True, eq=False)
class BlockRequest:
    """A block of passes to process (module docstring).

    Attributes
    ----------
    archives, names
        One L0 archive per pass (read lazily), and the name of its products.
    gcps
        Each pass's control points (level 2), without tie points.
    scene_dirs
        Where each pass's scene levels are (its 2A for the tie points, its 1A for a pair).
    options
        What to make (``levels``: 2, 3 and the kinds of a pair; ``stereo``: the pair's DEM
        too) and how; the adjustment is the block's.
    out_dir
        Where ``ties/``, ``block/`` and ``stereo/`` go.
    checkpoints
        Where checkpoints truly are, per archive (the emulator's truth); empty: none.
    ties_dir
        A directory of tie points already matched (``<name>.tie.csv``); None: matched here.
    provenance
        Added to each level 2 and 3 product's ``provenance``.
    """

    archives: tuple[L0Archive, ...]
    names: tuple[str, ...]
    gcps: tuple[ControlPointSet, ...]
    scene_dirs: tuple[Path, ...]
    options: ProcessingOptions
    out_dir: Path
    checkpoints: tuple[CheckpointSource | None, ...] = ()
    ties_dir: Path | None = None
    provenance: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        n = len(self.archives)
        if n < 2:
            raise OptionsError(f"a block takes two passes or more, got {n}")
        for what in ("names", "gcps", "scene_dirs"):
            if len(getattr(self, what)) != n:
                raise ValueError(f"{n} archives but {len(getattr(self, what))} {what}")


@dataclass(frozen=True)
class BlockProducts:
    """What a block made: its tie points (per pair of scenes), every pass's level 2 and 3
    (:class:`levels.process.PassProducts`, in the archives' order) and its pair products."""

    ties: dict[str, Any]
    passes: list[PassProducts]
    pairs: list[PairMade]


def pair_kinds(options: ProcessingOptions) -> list[ProductKind]:
    """The kinds of a pair the options ask for (``levels``: :func:`levels.process.
    pair_kinds_of`; ``stereo``: the stereo pair's DEM, :mod:`levels.makers.dem`)."""
    from levels.makers.dem import KIND as DEM

    kinds = pair_kinds_of(options)
    return [*kinds, DEM] if options.stereo and DEM not in kinds else kinds


def pass_levels(options: ProcessingOptions) -> list[str]:
    """What each pass of a block makes on its own, before the block: the scene levels asked
    that need nothing of the block (not level 2's adjustment, not level 3's DEM), the 2A its
    tie points are matched on, and the scene levels the pair's kinds read (a DEM: the 1A's
    raw pixels), in processing order."""
    scene = kind_names(Unit.SCENE)
    wanted = {lv for lv in options.levels if lv in scene and not kind(lv).maker.needs}
    wanted |= {Level.L2A} | {
        lv for k in pair_kinds(options) for lv in k.maker.needs if not kind(lv).maker.needs
    }
    return [lv for lv in scene if lv in wanted]


def tie_points(scene_dirs: dict[str, Path], out: Path) -> dict[str, Any]:
    """Tie points between every two passes' overlapping 2A scenes (the ``*_2A.nc`` of each
    pass's directory in ``scene_dirs``), each pass's merged into ``out/<pass>.tie.csv``;
    what was found, per pair of scenes."""
    from levels.products import read_product
    from levels.tiepoints import MapView, match_views

    views = {
        name: [MapView.of_product(read_product(p)) for p in sorted(d.glob(f"{name}_s*_2A.nc"))]
        for name, d in scene_dirs.items()
    }
    per: dict[str, list[ControlPointSet]] = {n: [] for n in scene_dirs}
    pairs = []
    for a, b in itertools.combinations(list(scene_dirs), 2):
        for va, vb in itertools.product(views[a], views[b]):
            try:
                tp = match_views(va, vb)
            except GeometryError:  # these two scenes do not overlap
                continue
            if not len(tp):
                continue
            per[a].append(tp.control_points("a"))
            per[b].append(tp.control_points("b"))
            pair = {"a": a, "b": b, "scene_a": va.scene, "scene_b": vb.scene}
            pairs.append({**pair, "points": len(tp), "counts": tp.counts})
    out.mkdir(parents=True, exist_ok=True)
    for n, sets in per.items():
        if sets:
            comment = f"tie points of {n} (docs/gcp.md)"
            write_gcps(out / f"{n}.tie.csv", functools.reduce(operator.add, sets), comment)
    return {"pairs": pairs}


def _level2_options(request: BlockRequest, levels: tuple[str, ...], **more: Any) -> Any:
    """The options of the block's level 2 (and 3): the request's, its levels ``levels``,
    its adjustment the block's."""
    return dataclasses.replace(
        request.options, levels=levels, adjustment=AdjustmentScope.BLOCK, **more
    )


def _adjusted(
    request: BlockRequest,
    ties: Path,
    options: ProcessingOptions,
    runner: Runner | None,
    made: Sequence[PassProducts] = (),
) -> list[PassProducts]:
    """Every pass's level 2 (and 3) on the block's adjustment, into ``block/``: the one
    ``made`` already when given (its adjustments taken as they are)."""
    points = []
    for name, gcps, archive in zip(request.names, request.gcps, request.archives, strict=True):
        tie = ties / f"{name}.tie.csv"
        own = read_gcps(tie, archive.n_lines, archive.n_columns) if tie.is_file() else None
        points.append(gcps + own if own is not None else gcps)
    block = ProcessingRequest(
        request.archives,
        options,
        request.out_dir / LEVEL2,
        request.names,
        checkpoints=request.checkpoints,
        gcps=tuple(points),
        provenance=request.provenance,
        root=request.out_dir,
        adjustments=tuple(p.adjustment for p in made),
    )
    return all_made(run_plans(plan(block), runner))


def _pair_scenes(
    request: BlockRequest, k: int, ties: Path, needs: Sequence[str], level2: PassProducts
) -> list[PairScene]:
    """Pass ``k``'s scenes as sides of a pair: each scene the block's level 2 made
    (``level2``), with its products of the kinds the pair's maker ``needs`` (level 2's in
    ``block/``, the others in the pass's own directory, named as the driver names them)."""
    name, archive = request.names[k], request.archives[k]
    own = read_gcps(ties / f"{name}.tie.csv", archive.n_lines, archive.n_columns)
    return [
        PairScene(
            name,
            sc.index,
            {
                lv: sc.paths[lv]
                if lv in sc.paths
                else request.scene_dirs[k] / product_name(name, sc.index, lv, kind(lv).on_map)
                for lv in needs
            },
            own,
        )
        for sc in level2.scenes
    ]


def _pairs(
    request: BlockRequest,
    kinds: list[ProductKind],
    ties: Path,
    level2: list[PassProducts],
    measure: Measure | None,
) -> list[PairMade]:
    """Every pair kind's products of the first two passes' overlapping scenes."""
    if len(request.archives) != 2:
        raise OptionsError(
            f"a pair's products take a block of two passes, got {len(request.archives)}"
        )
    made = []
    out = request.out_dir / PAIRS
    out.mkdir(parents=True, exist_ok=True)
    for pair_kind in kinds:
        maker: PairMaker = pair_kind.maker
        a, b = (_pair_scenes(request, k, ties, maker.needs, level2[k]) for k in (0, 1))
        for sa, sb in itertools.product(a, b):
            _log.info("%s of %s scene %d and %s scene %d", pair_kind.name, *_sides(sa, sb))
            done = maker.make(sa, sb, out, measure)
            if done is not None:
                made.append(done)
    return made


def _sides(a: PairScene, b: PairScene) -> tuple[str, int, str, int]:
    return a.name, a.scene, b.name, b.scene


def process_block(
    request: BlockRequest, runner: Runner | None = None, measure: Measure | None = None
) -> BlockProducts:
    """Make what the block asks, in order and each once (module docstring)."""
    opts = request.options
    if request.ties_dir is None:
        _log.info("block: tie points between the passes' 2A scenes")
        ties_found = tie_points(
            dict(zip(request.names, request.scene_dirs, strict=True)), request.out_dir / TIES
        )
        ties = request.out_dir / TIES
    else:
        ties_found, ties = {"pairs": []}, Path(request.ties_dir)
    kinds = pair_kinds(opts)
    passes: list[PassProducts] = []
    pairs: list[PairMade] = []
    if Level.L2 in opts.levels:
        _log.info("block: level 2 of every pass on one adjustment")
        later = Level.L3 in opts.levels and not kinds  # level 3 over the options' DEM
        levels = (Level.L2, Level.L3) if later else (Level.L2,)
        passes = _adjusted(request, ties, _level2_options(request, levels), runner)
        if kinds:
            pairs = _pairs(request, kinds, ties, passes, measure)
            dems = [p.export for p in pairs if p.export is not None]
            if Level.L3 in opts.levels and dems:
                # on the block's level 2 as adjusted: the pair's DEM comes of the same
                # images and tie points; under the tie points again it would count them
                # twice (the across-base accuracy claimed 1.5× what it is)
                _log.info("block: level 3 over the pair's own DEM")
                over = _level2_options(
                    request, (Level.L2, Level.L3), dem_path=str(dems[0]), dem_vertical="ellipsoid"
                )
                passes = _adjusted(request, ties, over, runner, made=passes)
    elif kinds:
        raise OptionsError(f"{kinds[0].name} is made from the passes' level 2: ask for level 2 too")
    return BlockProducts(ties_found, passes, pairs)
