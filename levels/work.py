"""One unit of work: a request → one plan of nodes → one result.

A :class:`Request` names what to process: passes (each the L0 archives of one pass, one per
HRV, with their control points), SAR frames, the options, a DEM (read already, or the
options' ``dem_path``), where the products go and their provenance. :func:`plan` turns it
into a :class:`Plan`, a graph of :class:`Node` s (a step, a key, the kinds it makes, the
nodes it requires) laid from each kind's declaration across the units of work
(:class:`levels.kinds.Unit`):

- ``reference:<pass>``: a lone pass's control points found on a reference ortho-image
  (:mod:`levels.reference`), on GEO's set-up of the pass that its scenes are then made on;
- ``scenes:<pass>``: a pass's scene levels, made by the scene driver's tasks
  (:mod:`levels.process`); a lone pass's level 2 and 3 among them, on its own adjustment;
- ``ties:block``: the tie points between every two passes' overlapping 2A scenes;
- ``adjustment:block``: one adjustment of every pass together (Westin's block, the control
  points of any pass carried across by the tie points: :mod:`levels.adjust`);
- ``level2:<pass>``: each pass's level 2 on that adjustment (and its level 3 over the
  request's DEM when no pair is planned);
- ``<kind>:<a>+<b>``: a pair's products (:attr:`levels.kinds.Unit.PAIR`: the stereo DEM);
- ``over_pair:<pass>``: level 3 over the pair's DEM, on the block's level 2 as adjusted
  (under the tie points again, that DEM would count the pair's measurements twice);
- ``frame:<name>``: a SAR frame's kinds (:attr:`levels.kinds.Unit.FRAME`: GEC, GTC).

Every node is made once, and every refusal (an unknown kind, no control points, no DEM, a
kind of pair with one pass) is raised by :func:`plan`, before any work. :func:`run` makes the
nodes in order through their kinds' makers and returns one :class:`Result`: every product
(:class:`Made`), each archive's facts (:class:`PassDone`: its adjustment, the scenes it
skipped) and the tie points found. What the products are held to is one :class:`Measure`
for every unit (the station's truth; :data:`NO_TRUTH` by default). A step may be taken from
a directory instead of made, as ASP's entry points are: a pass's scene levels
(:attr:`Pass.made_in`), the tie points (:attr:`Request.ties_dir`).
"""

from __future__ import annotations

import dataclasses
import itertools
import logging
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from enum import StrEnum
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

from levels.choices import AdjustmentScope, Level
from levels.errors import DemError, GcpError, OptionsError
from levels.kinds import ProductKind, Unit
from levels.makers.base import Need
from levels.makers.pairs import PairMade, PairMaker, PairScene
from levels.options import ProcessingOptions
from levels.process import (
    PassProducts,
    ProcessingRequest,
    SceneProducts,
    all_made,
    pair_kinds_of,
    plan_levels,
    run_plans,
)
from levels.process import plan as plan_scenes
from levels.products import product_name
from levels.quality import CheckpointSource
from levels.readers.dem import Dem, read_dem
from levels.readers.gcp import ControlPointSet, read_gcps
from levels.readers.l0 import L0Archive
from levels.registry import kind, kind_names
from levels.step_files import TiePair, TiesFound, taken_adjustment, tie_points
from levels.tasks import Runner

if TYPE_CHECKING:
    import numpy as np
    from numpy.typing import NDArray

    from levels.adjust.model import Adjustment
    from levels.frame import FrameOptions
    from levels.geo.maps import MapGrid
    from levels.readers.sar import SarFrame
    from levels.reference import ReferenceInput
    from levels.sar.geocoding import Geocoded
    from levels.stereo import StereoDem

_log = logging.getLogger(__name__)

__all__ = [
    "NO_TRUTH",
    "Frame",
    "Made",
    "Measure",
    "Node",
    "Pass",
    "PassDone",
    "Plan",
    "Request",
    "Result",
    "Step",
    "TiePair",
    "TiesFound",
    "pair_kinds",
    "pass_levels",
    "plan",
    "run",
    "taken_adjustment",
    "tie_points",
]

#: Where a block's products go, under the request's output directory.
TIES, LEVEL2, PAIRS = "ties", "block", "stereo"


class Step(StrEnum):
    """The steps of a plan (module docstring), in the order :func:`run` takes them."""

    REFERENCE = "reference"
    SCENES = "scenes"
    TIES = "ties"
    ADJUSTMENT = "adjustment"
    LEVEL2 = "level2"
    PAIR = "pair"
    OVER_PAIR = "over_pair"
    FRAME = "frame"


class Measure(Protocol):
    """What the products are held to, for every unit of work: the truth (the emulator's, or
    surveyed points) or nothing (:data:`NO_TRUTH`)."""

    def checkpoints(self, name: str) -> CheckpointSource | None:
        """Where the checkpoints of archive ``name`` truly are (its scenes' quality)."""
        ...

    def pair(self, made: StereoDem) -> dict[str, object]:
        """A pair product's quality from what its maker made (a :class:`levels.stereo.
        StereoDem`)."""
        ...

    def frame(
        self, level: str, geocoded: Geocoded, gamma0: NDArray[np.float32] | None
    ) -> dict[str, object]:
        """A SAR frame product's quality from its geocoding and its γ⁰."""
        ...


class _NoTruth:
    """Nothing to hold the products to: their quality is what the library knows itself."""

    def checkpoints(self, name: str) -> CheckpointSource | None:
        return None

    def pair(self, made: StereoDem) -> dict[str, object]:
        return {}

    def frame(
        self, level: str, geocoded: Geocoded, gamma0: NDArray[np.float32] | None
    ) -> dict[str, object]:
        return {}


#: The :class:`Measure` of a request without truth.
NO_TRUTH: Measure = _NoTruth()


@dataclass(frozen=True, eq=False)
class Pass:
    """One pass of a request: its archives (one per HRV, :func:`levels.readers.l0.read_l0`),
    the names of their products, their control points (level 2; empty: none), its own
    options for its scene levels (a block's pass run by its own scenario; None: the
    request's), ``made_in``: the directory where its scene levels are already (the step
    taken, not made), and ``references``: per archive without control points, the
    reference ortho-image and DEM to find them on (a node before the adjustment)."""

    archives: tuple[L0Archive, ...]
    names: tuple[str, ...]
    gcps: tuple[ControlPointSet | None, ...] = ()
    options: ProcessingOptions | None = None
    made_in: Path | None = None
    references: tuple[ReferenceInput | None, ...] = ()

    def __post_init__(self) -> None:
        n = len(self.archives)
        object.__setattr__(self, "gcps", tuple(self.gcps) or (None,) * n)
        object.__setattr__(self, "references", tuple(self.references) or (None,) * n)
        if len(self.names) != n or len(self.gcps) != n:
            raise ValueError(f"{n} archives, {len(self.names)} names, {len(self.gcps)} gcps")


@dataclass(frozen=True, eq=False)
class Frame:
    """A SAR frame of a request, and its grid when already laid (a caller that checked the
    grid's memory first: :func:`levels.sar.frame_grid`)."""

    frame: SarFrame
    grid: MapGrid | None = None


@dataclass(frozen=True, eq=False)
class Request:
    """What to process (module docstring).

    Attributes
    ----------
    options
        What to make (``levels``: scene levels, kinds of a pair, with ``stereo`` the pair's
        DEM) and how.
    out_dir
        Where the products go: a lone pass's and the frames' into it; a block's passes
        into ``<out>/<name>/`` (unless made already), ``ties/``, ``block/`` and ``stereo/``.
    passes
        The passes: one alone, or two or more over one ground (a block).
    frames, frame_options
        SAR frames and how they are geocoded.
    dem, dem_source
        The DEM of level 3 and GTC when already read, and the file it came from; None:
        the options' ``dem_path`` (level 3), none (GTC).
    provenance
        Added to every product's ``provenance``.
    root
        The directory the products are published in (by default ``out_dir``): a file in it
        is recorded relative to the products (:class:`levels.process.ProcessingRequest`).
    ties_dir
        A directory of tie points already matched (``<name>.tie.csv``); None: matched.
    adjustment_dir
        A directory of level 2 products made already (a run's ``block/``, or a lone pass's
        products): level 2's adjustment is taken from them (:func:`taken_adjustment`),
        not solved again, and no control point is needed; None: solved.
    scenes
        A lone pass's scenes to make (cut indices), the others not; None: every one.
    """

    options: ProcessingOptions
    out_dir: Path
    passes: tuple[Pass, ...] = ()
    frames: tuple[Frame, ...] = ()
    frame_options: FrameOptions | None = None
    dem: Dem | None = None
    dem_source: str = ""
    provenance: Mapping[str, Any] = field(default_factory=dict)
    root: Path | None = None
    ties_dir: Path | None = None
    adjustment_dir: Path | None = None
    scenes: frozenset[int] | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "out_dir", Path(self.out_dir))
        object.__setattr__(self, "passes", tuple(self.passes))
        object.__setattr__(self, "frames", tuple(self.frames))

    @property
    def block(self) -> bool:
        """Several passes over one ground: planned as one block."""
        return len(self.passes) > 1


@dataclass(frozen=True)
class Node:
    """A node of a plan: its step, its key (a pass's, a pair's, a frame's name), the kinds
    of the products it makes and the ids of the nodes it requires; ``taken``: where it was
    made already (not made again)."""

    step: Step
    key: str
    kinds: tuple[str, ...] = ()
    requires: tuple[str, ...] = ()
    taken: Path | None = None

    @property
    def id(self) -> str:
        return f"{self.step}:{self.key}"


@dataclass(frozen=True, eq=False)
class Plan:
    """A request's nodes, each after those it requires (:func:`plan`)."""

    request: Request
    nodes: tuple[Node, ...]

    def of(self, step: Step) -> list[Node]:
        """The nodes of ``step``, in order."""
        return [n for n in self.nodes if n.step is step]

    def text(self) -> list[str]:
        """The plan in lines: each node, its kinds and what it requires."""
        return [
            f"{n.id}: {', '.join(n.kinds) or '-'}"
            + (f" ← {', '.join(n.requires)}" if n.requires else "")
            + (f" (taken from {n.taken})" if n.taken else "")
            for n in self.nodes
        ]


@dataclass(frozen=True)
class Made:
    """A product made: its kind, its node's step and key (a pass's archive, a pair's, a
    frame's name), its scene (index, first line, lines) for a scene's level, its path, its
    export (a GeoTIFF, or None), its quality (a scene level's headline figures flattened,
    :func:`levels.quality.scalar_figures`; a pair's or a frame's tree) and timings."""

    kind: str
    step: Step
    key: str
    path: Path
    quality: Mapping[str, Any]
    timings_s: Mapping[str, float] = field(default_factory=dict)
    scene: tuple[int, int, int] | None = None
    export: Path | None = None


@dataclass(frozen=True)
class PassDone:
    """What one archive's scene driver did in a step: its adjustment, the rows after its
    last scene, its scenes skipped and its timings (:class:`levels.process.PassProducts`)."""

    name: str
    step: Step
    products: PassProducts


@dataclass(frozen=True)
class Result:
    """Everything a plan made (module docstring)."""

    products: tuple[Made, ...]
    passes: tuple[PassDone, ...]
    ties: TiesFound = field(default_factory=lambda: TiesFound(pairs=[]))

    def of(self, *steps: Step) -> list[Made]:
        """The products of ``steps``, in the order they were made."""
        return [m for m in self.products if m.step in steps]

    def pass_products(self, name: str, *steps: Step) -> PassProducts:
        """Archive ``name``'s scenes as the scene driver returns them, their levels of
        ``steps`` together (a block's level 2 and its level 3 over the pair's DEM)."""
        done = [d.products for d in self.passes if d.name == name and d.step in steps]
        if not done:
            raise KeyError(f"no archive {name!r} made in steps {[str(s) for s in steps]}")
        scenes: dict[int, SceneProducts] = {}
        for p in done:
            for s in p.scenes:
                had = scenes.get(s.index)
                scenes[s.index] = s if had is None else _merged(had, s)
        first = done[0]
        last_adjusted = next((p.adjustment for p in reversed(done) if p.adjustment), None)
        return dataclasses.replace(
            done[-1],
            scenes=[scenes[i] for i in sorted(scenes)],
            skipped=first.skipped,
            adjustment=last_adjusted,
        )


def _merged(a: SceneProducts, b: SceneProducts) -> SceneProducts:
    """A scene's products of two steps as one (the later's timings)."""
    return dataclasses.replace(
        a, paths={**a.paths, **b.paths}, quality={**a.quality, **b.quality}, timings_s=b.timings_s
    )


def pair_kinds(options: ProcessingOptions) -> list[ProductKind]:
    """The kinds of a pair the options ask for (``levels``; ``stereo``: the stereo pair's
    DEM too)."""
    kinds = pair_kinds_of(options)
    dem = kind("DEM")
    return [*kinds, dem] if options.stereo and dem not in kinds else kinds


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


def plan(request: Request) -> Plan:
    """The request's nodes (module docstring); every refusal raised here, before any work."""
    opt = request.options
    known = kind_names()
    unknown = [lv for lv in opt.levels if lv not in known]
    if unknown:
        raise OptionsError(f"level {unknown[0]!r}: expected one of {', '.join(known)}")
    nodes = _frame_nodes(request) if request.frames else []
    if request.block:
        nodes += _block_nodes(request)
    elif request.passes:
        nodes += _pass_nodes(request)
    return Plan(request, tuple(nodes))


def _scene_levels(opt: ProcessingOptions) -> tuple[str, ...]:
    return tuple(lv for lv in opt.levels if kind(lv).unit is Unit.SCENE)


def _check_pass_needs(request: Request, levels: Sequence[str], pair_dem: bool) -> None:
    """Control points for level 2 and a DEM for level 3 (unless the pair makes one)."""
    needs = {n for m in plan_levels(levels) for n in m.needs}
    if Need.ADJUSTMENT in needs and request.adjustment_dir is not None:
        for p in request.passes:  # every archive's adjustment there, read before any work
            for name in p.names:
                taken_adjustment(request.adjustment_dir, name)
    elif Need.ADJUSTMENT in needs:
        missing = [
            n
            for p in request.passes
            for n, g, r in zip(p.names, p.gcps, p.references, strict=True)
            if g is None and r is None
        ]
        if missing:
            raise GcpError(
                f"level 2 of {missing[0]} needs control points: give the pass's control-point "
                "file (docs/gcp.md), or leave '2' out of the levels"
            )
    if Need.DEM in needs and request.dem is None and not request.options.dem_path and not pair_dem:
        raise DemError(
            "level 3 needs a DEM: set [processing] dem_path to a DEM file (GeoTIFF, SRTM "
            ".hgt, DTED) and dem_vertical to its datum, or give the scenario a [dem] section"
        )


def _pass_nodes(request: Request) -> list[Node]:
    """A lone pass: its scene levels, in one node."""
    opt = request.options
    pairs = [k.name for k in pair_kinds_of(opt)]
    if pairs:
        raise OptionsError(
            f"{pairs[0]} is made of a pair of passes: give the archives of two passes over "
            "one ground, with level 2"
        )
    (one,) = request.passes
    levels = _scene_levels(opt)
    plan_levels(levels)  # an unknown or circular level refused here
    _check_pass_needs(request, levels, False)
    key = "+".join(one.names)
    found = (
        [Node(Step.REFERENCE, key)]
        if Level.L2 in levels and any(r is not None for r in one.references)
        else []
    )
    if Level.L2 in levels and request.adjustment_dir is not None:
        found = [Node(Step.ADJUSTMENT, key, taken=request.adjustment_dir)]
    scenes = Node(Step.SCENES, key, levels, tuple(n.id for n in found), taken=one.made_in)
    return [*found, scenes]


def _block_nodes(request: Request) -> list[Node]:
    """Several passes over one ground (module docstring)."""
    opt, passes = request.options, request.passes
    kinds = pair_kinds(opt)
    if kinds and Level.L2 not in opt.levels:
        raise OptionsError(f"{kinds[0].name} is made from the passes' level 2: ask for level 2 too")
    if kinds and len(passes) != 2:
        raise OptionsError(f"a pair's products take a block of two passes, got {len(passes)}")
    with_l3 = Level.L3 in opt.levels
    l2_l3 = (Level.L2,) * (Level.L2 in opt.levels) + (Level.L3,) * with_l3
    _check_pass_needs(request, l2_l3, bool(kinds))  # a pair's DEM is level 3's
    for p in passes:
        if any(r is not None for r in p.references):
            raise OptionsError(
                f"{p.names[0]}: control points found on a reference are a lone pass's; a "
                "block's passes give theirs"
            )
        if len(p.archives) != 1:
            raise OptionsError(
                f"a block's pass is one archive: {', '.join(p.names)} are {len(p.archives)} "
                "(process a twin pass's HRVs as one pass, or each as a pass of its own)"
            )
    mine = tuple(pass_levels(opt))
    nodes = [Node(Step.SCENES, p.names[0], mine, taken=p.made_in) for p in passes]
    scenes = tuple(n.id for n in nodes)
    ties = Node(Step.TIES, "block", requires=scenes, taken=request.ties_dir)
    nodes.append(ties)
    if Level.L2 not in opt.levels:
        return nodes
    adjustment = Node(Step.ADJUSTMENT, "block", requires=(ties.id,), taken=request.adjustment_dir)
    # level 3 over the request's DEM on the block's level 2, or over the pair's afterwards
    here = (Level.L3,) * (with_l3 and not kinds)
    level2 = [Node(Step.LEVEL2, p.names[0], (Level.L2, *here), (adjustment.id,)) for p in passes]
    nodes += [adjustment, *level2]
    pair_nodes = [
        Node(
            Step.PAIR,
            f"{k.name}:{passes[0].names[0]}+{passes[1].names[0]}",
            (k.name,),
            (*scenes, *(n.id for n in level2)),
        )
        for k in kinds
    ]
    nodes += pair_nodes
    if with_l3 and kinds:
        after = (adjustment.id, *(n.id for n in pair_nodes))
        nodes += [Node(Step.OVER_PAIR, p.names[0], (Level.L3,), after) for p in passes]
    return nodes


def _frame_nodes(request: Request) -> list[Node]:
    """A SAR frame's kinds, in one node per frame; GTC refused without a DEM."""
    fo = request.frame_options
    if fo is None:
        raise OptionsError("SAR frames to process need their options (levels.frame.FrameOptions)")
    needing = [lv for lv in fo.levels if "dem" in kind(lv).needs]
    if needing and request.dem is None:
        raise DemError(f"{needing[0]} geocodes over terrain: give the DEM under the frame")
    return [Node(Step.FRAME, f.frame.name, tuple(fo.levels)) for f in request.frames]


def run(
    work: Plan,
    runner: Runner | None = None,
    measure: Measure = NO_TRUTH,
    on_scene: Callable[[SceneProducts, int], None] | None = None,
) -> Result:
    """Make every node of the plan ``work``, each once and in order (module docstring):
    the scenes as tasks of ``runner`` (:mod:`levels.tasks`; in this process by default),
    ``on_scene(done, n_scenes)`` after each of a lone pass's; the products held to
    ``measure``."""
    made = _Making(work.request, runner, measure, on_scene)
    scenes = [n for n in work.of(Step.SCENES) if n.taken is None]
    if scenes:
        made.scenes(scenes)
    if work.of(Step.TIES):
        made.ties(work.of(Step.TIES)[0])
    if work.of(Step.LEVEL2):
        made.level2(work.of(Step.LEVEL2))
    for node in work.of(Step.PAIR):
        made.pair(node)
    if work.of(Step.OVER_PAIR):
        made.over_pair(work.of(Step.OVER_PAIR))
    for node in work.of(Step.FRAME):
        made.frame(node)
    return Result(tuple(made.products), tuple(made.passes), made.ties_found)


class _Making:
    """The state of :func:`run`: what each step made, for the steps after it."""

    def __init__(
        self,
        request: Request,
        runner: Runner | None,
        measure: Measure,
        on_scene: Callable[[SceneProducts, int], None] | None,
    ) -> None:
        self.request, self.runner, self.measure, self.on_scene = request, runner, measure, on_scene
        self.products: list[Made] = []
        self.passes: list[PassDone] = []
        self.ties_found = TiesFound(pairs=[])
        self.ties_dir = request.ties_dir or request.out_dir / TIES
        self.made_pairs: list[PairMade] = []

    def scene_dir(self, p: Pass) -> Path:
        """Where pass ``p``'s scene levels are: made here, or taken."""
        if p.made_in is not None:
            return p.made_in
        return self.request.out_dir / p.names[0] if self.request.block else self.request.out_dir

    def taken(self, p: Pass) -> tuple[Adjustment, ...]:
        """Pass ``p``'s adjustments taken from the request's ``adjustment_dir`` (none:
        solved), one per archive."""
        where = self.request.adjustment_dir
        if where is None or Level.L2 not in self.request.options.levels:
            return ()
        return tuple(taken_adjustment(where, name) for name in p.names)

    def _keep(self, step: Step, names: Sequence[str], done: Sequence[PassProducts]) -> None:
        for name, products in zip(names, done, strict=True):
            self.passes.append(PassDone(name, step, products))
            for s in products.scenes:
                for lv, path in s.paths.items():
                    at = (s.index, s.first_line, s.n_lines)
                    self.products.append(Made(lv, step, name, path, s.quality[lv], s.timings_s, at))

    def scenes(self, nodes: Sequence[Node]) -> None:
        """Every pass's scene levels, the passes' scenes as tasks of one runner."""
        req = self.request
        todo = [p for p in req.passes if p.names[0] in {n.key.split("+")[0] for n in nodes}]
        requests = []
        for p in todo:
            base = p.options or req.options
            levels = tuple(pass_levels(req.options)) if req.block else _scene_levels(base)
            opts = dataclasses.replace(base, levels=levels)
            requests.append(
                ProcessingRequest(
                    p.archives,
                    opts,
                    self.scene_dir(p),
                    p.names,
                    checkpoints=tuple(self.measure.checkpoints(n) for n in p.names),
                    gcps=p.gcps if not req.block else (),
                    references=p.references if not req.block else (),
                    provenance=req.provenance,
                    dem=req.dem,
                    root=req.root if not req.block else None,
                    adjustments=self.taken(p) if not req.block else (),
                    scenes=req.scenes if not req.block else None,
                )
            )
        plans = [pp for r in requests for pp in plan_scenes(r)]
        done = all_made(run_plans(plans, self.runner, None if req.block else self.on_scene))
        names = [n for p in todo for n in p.names]
        self._keep(Step.SCENES, names, done)

    def ties(self, node: Node) -> None:
        if node.taken is not None:
            return
        _log.info("block: tie points between the passes' 2A scenes")
        dirs = {p.names[0]: self.scene_dir(p) for p in self.request.passes}
        self.ties_found = tie_points(dirs, self.ties_dir)

    def _block_request(self, levels: tuple[str, ...], **more: Any) -> ProcessingRequest:
        """The passes' level 2 (and 3) on the block's adjustment, into ``block/``."""
        req = self.request
        points: list[ControlPointSet | None] = []
        archives, names = [], []
        for p in req.passes:
            (archive,), (name,), (gcps,) = p.archives, p.names, p.gcps
            tie = self.ties_dir / f"{name}.tie.csv"
            own = read_gcps(tie, archive.n_lines, archive.n_columns) if tie.is_file() else None
            if gcps is None:  # the adjustment taken from a directory (plan() checked)
                points.append(None)
            else:
                points.append(gcps + own if own is not None else gcps)
            archives.append(archive)
            names.append(name)
        opts = dataclasses.replace(
            req.options,
            levels=levels,
            adjustment=AdjustmentScope.BLOCK,
            **more.pop("options", {}),
        )
        return ProcessingRequest(
            tuple(archives),
            opts,
            req.out_dir / LEVEL2,
            tuple(names),
            checkpoints=tuple(self.measure.checkpoints(n) for n in names),
            gcps=tuple(points),
            provenance=req.provenance,
            root=req.out_dir,
            **more,
        )

    def level2(self, nodes: Sequence[Node]) -> None:
        """The block's one adjustment and every pass's level 2 (and 3) on it."""
        _log.info("block: level 2 of every pass on one adjustment")
        taken = tuple(a for p in self.request.passes for a in self.taken(p))
        block = self._block_request(nodes[0].kinds, dem=self.request.dem, adjustments=taken)
        done = all_made(run_plans(plan_scenes(block), self.runner))
        self._keep(Step.LEVEL2, block.names, done)

    def pair(self, node: Node) -> None:
        """One kind of pair's products of the first two passes' overlapping scenes."""
        pair_kind = kind(node.kinds[0])
        maker: PairMaker = pair_kind.maker
        out = self.request.out_dir / PAIRS
        out.mkdir(parents=True, exist_ok=True)
        a, b = (self._pair_scenes(p, maker.needs) for p in self.request.passes[:2])
        for sa, sb in itertools.product(a, b):
            _log.info("%s of %s scene %d and %s scene %d", pair_kind.name, *_sides(sa, sb))
            done = maker.make(sa, sb, out, self.measure.pair)
            if done is None:
                continue
            self.made_pairs.append(done)
            name = f"{sa.name}_s{sa.scene:03d}+{sb.name}_s{sb.scene:03d}"
            self.products.append(
                Made(
                    pair_kind.name,
                    Step.PAIR,
                    name,
                    done.path,
                    done.quality,
                    done.timings_s,
                    export=done.export,
                )
            )

    def _pair_scenes(self, p: Pass, needs: Sequence[str]) -> list[PairScene]:
        """Pass ``p``'s scenes as sides of a pair: each scene of its level 2, with its
        products of the kinds the pair's maker ``needs`` (level 2's in ``block/``, the others
        where its scene levels are, named as the driver names them)."""
        (name,), (archive,) = p.names, p.archives
        own = read_gcps(self.ties_dir / f"{name}.tie.csv", archive.n_lines, archive.n_columns)
        level2 = self._level2_of(name)
        where = self.scene_dir(p)
        return [
            PairScene(
                name,
                sc.index,
                {
                    lv: sc.paths[lv]
                    if lv in sc.paths
                    else where / product_name(name, sc.index, lv, kind(lv).on_map)
                    for lv in needs
                },
                own,
            )
            for sc in level2.scenes
        ]

    def _level2_of(self, name: str) -> PassProducts:
        return next(d.products for d in self.passes if d.name == name and d.step is Step.LEVEL2)

    def over_pair(self, nodes: Sequence[Node]) -> None:
        """Level 3 of every pass over the pair's DEM, on the block's level 2 as adjusted
        (level 2 is given: neither made nor written again)."""
        dems = [p.export for p in self.made_pairs if p.export is not None]
        if not dems:
            _log.warning("block: no pair overlapped: no level 3 over the pair's DEM")
            return
        _log.info("block: level 3 over the pair's own DEM")
        names = [p.names[0] for p in self.request.passes]
        adjusted = [self._level2_of(n).adjustment for n in names]
        block = self._block_request(
            (Level.L2, Level.L3),
            options={"dem_path": str(dems[0]), "dem_vertical": "ellipsoid"},
            dem=read_dem(dems[0], "ellipsoid"),
            adjustments=tuple(adjusted),
            given=(Level.L2,),
        )
        done = all_made(run_plans(plan_scenes(block), self.runner))
        self._keep(Step.OVER_PAIR, block.names, done)

    def frame(self, node: Node) -> None:
        """A SAR frame's kinds (:func:`levels.frame.process_frame`)."""
        from levels.frame import process_frame

        req = self.request
        assert req.frame_options is not None  # plan() checked
        given = next(f for f in req.frames if f.frame.name == node.key)
        for m in process_frame(
            given.frame,
            req.frame_options,
            req.out_dir,
            dem=req.dem,
            dem_source=req.dem_source,
            measure=self.measure.frame,
            provenance=dict(req.provenance),
            grid=given.grid,
        ):
            self.products.append(
                Made(m.level, Step.FRAME, node.key, m.path, m.product.quality, m.timings_s)
            )


def _sides(a: PairScene, b: PairScene) -> tuple[str, int, str, int]:
    return a.name, a.scene, b.name, b.scene
