"""The processing centre's driver: a request → a plan of products → scene tasks.

A :class:`ProcessingRequest` says what to process: the L0 archives of one pass (one per
HRV, :func:`levels.readers.l0.read_l0`), the :class:`~levels.options.ProcessingOptions`,
where the products go and how they are named, and what the levels need from outside
(control points, a checkpoint source, a DEM). :func:`plan` turns it into one
:class:`PassPlan` per archive: GEO's set-up of the pass and its scenes, what the levels
asked need of the whole pass (level 2's adjustment, level 3's DEM), and the levels to make
in order (:func:`plan_levels`: those asked and those they require). :func:`run_plans`
makes every scene as a task of a runner (:mod:`levels.tasks`); :func:`process` is both.

The levels themselves are declared in :mod:`levels.makers` and named in
:mod:`levels.registry`; the driver knows none of them. For each scene
(:func:`make_scene`), the raw counts of each band are read from the archive once,
calibrated once and deconvolved once for every level: INPE's "all operations executed by
COR require the raw image to be read only once" (paper ``004_…`` §2.2).

Every product carries its quality: the approximation errors of its geometry against the
rigorous model (always), and, when a :class:`~levels.quality.CheckpointSource` is given
(the emulator's truth, or surveyed points), the checkpoint errors against it.

XS bands share one output grid, computed on the first band; each band goes through its own
1B polynomials and 2A grids onto it, so that the bands are registered. This module needs
nothing of the emulator: ``station process L0.h5`` is a thin command over it.
"""

from __future__ import annotations

import json
import logging
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from levels import __version__
from levels.adjust import Adjustment, Strip, adjust, adjust_block, adjust_strips
from levels.choices import AdjustmentScope
from levels.cor.radiometry import calibrate, counts_in_place, deconvolution_taps, deconvolve
from levels.cor.resample import with_nan
from levels.errors import DemError, GcpError, GeometryError, LevelsError, OptionsError
from levels.export import write_rpc_sidecar
from levels.geo.coverage import check_coverage
from levels.geo.scenes import SceneGeometry
from levels.makers.base import BandPixels, LevelMaker, Need, PassContext, Reads, SceneWork
from levels.makers.scene import level_maker
from levels.options import ProcessingOptions
from levels.passes import (
    PassSetup,
    SkippedScene,
    geo_pass,
    nominal_pixel_size_m,
    passes_of,
    platform_records,
)
from levels.products import Product, product_name, write_product
from levels.quality import CheckpointSource, scalar_figures
from levels.readers.dem import Dem, read_dem
from levels.readers.gcp import ControlPointSet
from levels.readers.l0 import L0Archive
from levels.tasks import InProcess, Runner, TaskFailure, raise_first
from levels.threads import one_blas_thread

if TYPE_CHECKING:
    from levels.reference import ReferenceInput, ReferencePoints

_log = logging.getLogger(__name__)

__all__ = [
    "PassPlan",
    "PassProducts",
    "PassSetup",
    "ProcessingRequest",
    "SceneProducts",
    "ScenesFailed",
    "SkippedScene",
    "all_made",
    "geo_pass",
    "make_scene",
    "nominal_pixel_size_m",
    "pair_kinds_of",
    "pass_dem",
    "passes_of",
    "plan",
    "plan_levels",
    "platform_records",
    "process",
    "run_plans",
]


@dataclass(frozen=True)
class SceneProducts:
    """What was made of one scene: product paths and headline quality per level."""

    index: int
    first_line: int
    n_lines: int
    paths: dict[str, Path]
    quality: dict[str, dict[str, object]]
    timings_s: dict[str, float]


@dataclass(frozen=True)
class PassProducts:
    """All scenes of a pass, the rows left after the last whole scene, GEO's time."""

    scenes: list[SceneProducts]
    tail_lines: int
    timings_s: dict[str, float] = field(default_factory=dict)
    skipped: list[SkippedScene] = field(default_factory=list)
    adjustment: Adjustment | None = None
    #: The control points found on a reference for level 2 (``ProcessingRequest.references``).
    found: ReferencePoints | None = None


def plan_levels(levels: Sequence[str], given: Sequence[str] = ()) -> tuple[LevelMaker, ...]:
    """The makers of the ``levels`` asked and of the levels they require
    (:attr:`LevelMaker.requires`), each after those it requires, otherwise in the order of
    :func:`levels.registry.level_names`; none of the levels ``given`` (made already)."""
    from levels.kinds import Unit
    from levels.registry import kind, level_names

    order = {name: k for k, name in enumerate(level_names())}
    wanted: dict[str, LevelMaker] = {}
    # a pair's kinds are made by the block's driver (levels.block), of the scenes' levels
    todo = [lv for lv in levels if lv not in order or kind(lv).unit is Unit.SCENE]
    while todo:
        name = todo.pop()
        if name not in wanted and name not in given:
            try:
                wanted[name] = level_maker(name)
            except KeyError as exc:
                raise OptionsError(str(exc).strip("'\"")) from None
            todo.extend(wanted[name].requires)
    out: list[LevelMaker] = []
    pending = sorted(wanted.values(), key=lambda m: order.get(m.name, len(order)))
    while pending:
        ready = next(
            (m for m in pending if all(r in {*given, *(o.name for o in out)} for r in m.requires)),
            None,
        )
        if ready is None:
            raise OptionsError(f"levels {[m.name for m in pending]} require each other")
        out.append(ready)
        pending.remove(ready)
    return tuple(out)


def _recorded(options: ProcessingOptions, out: Path, root: Path) -> ProcessingOptions:
    """The options as a product records them: a DEM inside the published directory ``root``
    as a path relative to the products' directory ``out`` (a staging directory's name is
    renamed away when published), one outside it as given."""
    import os

    if not options.dem_path:
        return options
    dem = Path(options.dem_path).absolute()
    if not dem.is_relative_to(Path(root).absolute()):
        return options
    return replace(options, dem_path=os.path.relpath(dem, Path(out).absolute()))


def pair_kinds_of(options: ProcessingOptions) -> list[Any]:
    """The kinds of a pair the options ask for (:attr:`levels.kinds.Unit.PAIR`: made of two
    passes by :func:`levels.block.process_block`, not by a pass's scene tasks)."""
    from levels.kinds import Unit
    from levels.registry import kind, kind_names

    known = set(kind_names())
    return [kind(lv) for lv in options.levels if lv in known and kind(lv).unit is Unit.PAIR]


def _needs(makers: Sequence[LevelMaker]) -> frozenset[Need]:
    return frozenset().union(*(m.needs for m in makers))


def pass_dem(options: ProcessingOptions, makers: Sequence[LevelMaker] | None = None) -> Dem | None:
    """The DEM of the levels asked that need one (``options.dem_path``, heights above
    ``options.dem_vertical``), or None when none does; :class:`DemError` when one does and
    no DEM is named. ``makers``: the levels planned, when they are (:func:`plan_levels`)."""
    planned = plan_levels(options.levels) if makers is None else makers
    needing = [m.name for m in planned if Need.DEM in m.needs]
    if not needing:
        return None
    if not options.dem_path:
        raise DemError(
            f"level {needing[0]} needs a DEM: set [processing] dem_path to a DEM file "
            "(GeoTIFF, SRTM .hgt, DTED) and dem_vertical to its datum, or give the scenario a "
            "[dem] section"
        )
    return read_dem(options.dem_path, options.dem_vertical)


@dataclass(frozen=True, eq=False)
class ProcessingRequest:
    """What to process: the archives of one pass and everything the levels asked need.

    Attributes
    ----------
    archives
        The pass, one archive per HRV, as :func:`levels.readers.l0.read_l0` reads them
        (``lazy=True`` keeps one scene's counts in memory at a time).
    options
        What to make and how.
    out_dir
        Where the products go.
    names
        One per archive: its products are named ``<name>_s<scene>_<level>.h5``.
    checkpoints
        Where checkpoints truly are, per archive, for the ``checkpoints`` quality figures
        (the emulator's truth, or surveyed points); empty: none.
    gcps
        Control points per archive (``docs/gcp.md``; those of the archive's HRV are used,
        both HRVs' with ``adjustment = "twin"``): level 2 needs them. Empty: none.
    provenance
        Added to each product's ``provenance`` group, over the archive's own.
    dem
        The DEM of level 3 when already read; by default :func:`pass_dem` reads the
        options'.
    root
        The directory the products are published in (a run's, a reprocessing's; by default
        ``out_dir``): a file inside it (the DEM) is recorded in the products' provenance
        relative to their own directory, so that a run records the same bytes wherever it
        is staged and published.
    adjustments
        Level 2's adjustment per archive when made already, taken as it is (a block's level 3
        over the pair's own DEM: :func:`levels.block.process_block` says why).
    references
        Per archive, a reference ortho-image and a DEM to find its control points on when
        it has none (:class:`levels.reference.ReferenceInput`): found on GEO's set-up of
        the pass before level 2's adjustment, GEO made once.
    given
        Levels of the options made already by an earlier step (the block's level 2 before
        level 3 over the pair's DEM): the levels made here are on their model (level 3 on
        level 2's), and they are neither made nor written again.
    scenes
        The scenes to make (their cut indices), the others not (None: every one): a pass
        still arriving makes each scene once its lines are in (``station serve --levels``).
    """

    archives: tuple[L0Archive, ...]
    options: ProcessingOptions
    out_dir: Path
    names: tuple[str, ...]
    checkpoints: tuple[CheckpointSource | None, ...] = ()
    gcps: tuple[ControlPointSet | None, ...] = ()
    provenance: Mapping[str, Any] = field(default_factory=dict)
    dem: Dem | None = None
    root: Path | None = None
    adjustments: tuple[Adjustment | None, ...] = ()
    given: tuple[str, ...] = ()
    references: tuple[ReferenceInput | None, ...] = ()
    scenes: frozenset[int] | None = None

    def __post_init__(self) -> None:
        n = len(self.archives)
        normal = {
            "out_dir": Path(self.out_dir),
            "archives": tuple(self.archives),
            "names": tuple(self.names),
            "checkpoints": tuple(self.checkpoints) or (None,) * n,  # none given: none each
            "gcps": tuple(self.gcps) or (None,) * n,
            "references": tuple(self.references) or (None,) * n,
        }
        for what, value in normal.items():
            object.__setattr__(self, what, value)
        object.__setattr__(self, "adjustments", tuple(self.adjustments))
        for what in ("names", "checkpoints", "gcps", *(("adjustments",) * bool(self.adjustments))):
            if len(getattr(self, what)) != n:
                raise ValueError(f"{n} archives but {len(getattr(self, what))} {what}")
        hrvs = [a.hrv for a in self.archives]
        block = self.options.adjustment == AdjustmentScope.BLOCK
        if len(set(hrvs)) != n and not block:  # a block's archives are passes of their own
            raise GeometryError(f"one archive per HRV of a pass: got HRVs {hrvs}")
        if len(set(self.names)) != n:
            raise GeometryError(f"two archives named alike: {list(self.names)}")

    @classmethod
    def of(
        cls,
        archive: L0Archive,
        options: ProcessingOptions,
        out_dir: str | Path,
        name: str = "pass",
        gcps: ControlPointSet | None = None,
    ) -> ProcessingRequest:
        """The request for one archive, without checkpoints (the common case of scripts)."""
        return cls((archive,), options, Path(out_dir), (name,), gcps=(gcps,))


@dataclass(frozen=True, eq=False)
class PassPlan:
    """One HRV's pass ready for its scene tasks (:func:`plan`): what every scene shares,
    the scenes to make, those skipped, GEO's time."""

    ctx: PassContext
    scenes: list[SceneGeometry]
    skipped: list[SkippedScene]
    tail_lines: int
    timings_s: dict[str, float]
    found: ReferencePoints | None = None

    def task_name(self, scene: SceneGeometry) -> str:
        """How a scene's task is named in reports: ``<name>-s<scene index>``."""
        return f"{self.ctx.name}-s{scene.cut.index:03d}"


class ScenesFailed(LevelsError):
    """Scenes of a pass that could not be made, each named, after the others were made
    (``failures``: :class:`levels.tasks.TaskFailure`; ``made``: what was made)."""

    def __init__(self, failures: list[TaskFailure], made: list[PassProducts]) -> None:
        super().__init__("; ".join(f.line() for f in failures))
        self.failures = failures
        self.made = made


def process(
    request: ProcessingRequest,
    runner: Runner | None = None,
    on_scene: Callable[[SceneProducts, int], None] | None = None,
) -> list[PassProducts]:
    """:func:`plan` and :func:`run_plans`: the products of every archive of the request,
    or the failures raised once every scene was tried (:func:`all_made`).
    ``on_scene(done, n_scenes)`` after each scene (progress reporting)."""
    return all_made(run_plans(plan(request), runner, on_scene))


def plan(request: ProcessingRequest) -> list[PassPlan]:
    """Everything before the scene tasks, one plan per archive: the levels to make, GEO's
    set-up of each archive, what the levels need of the pass (the DEM, read once; level
    2's adjustment, made on both HRVs together with ``adjustment = "twin"``: the platform's
    gyro records of either channel, :func:`platform_records`, and one adjustment,
    :func:`levels.adjust.adjust_strips`, so that control points in one HRV serve the
    other), the output directory."""
    opt, archives = request.options, request.archives
    pairs = [k.name for k in pair_kinds_of(opt)]
    if pairs:
        raise OptionsError(
            f"{pairs[0]} is made of a pair of passes (levels.block): give the archives of two "
            "passes over one ground, with level 2"
        )
    makers = plan_levels(opt.levels, request.given)
    needs = _needs(makers)
    if request.adjustments:  # made already: taken as they are
        needs |= {Need.ADJUSTMENT}
    elif Need.ADJUSTMENT in needs and any(
        g is None and r is None for g, r in zip(request.gcps, request.references, strict=True)
    ):
        raise GcpError(
            "level 2 needs control points: give the pass's control-point file "
            "(docs/gcp.md), or leave '2' out of the levels"
        )
    dem = request.dem
    if dem is None and Need.DEM in needs:
        dem = pass_dem(opt, makers)  # read once for every HRV
    twin = Need.ADJUSTMENT in needs and opt.adjustment == AdjustmentScope.TWIN
    block = Need.ADJUSTMENT in needs and opt.adjustment == AdjustmentScope.BLOCK
    setups: list[PassSetup | None] = [None] * len(archives)
    adjustments: list[Adjustment | None] = [None] * len(archives)
    made = list(request.adjustments)
    if block:
        groups = passes_of(archives)
        platform = {  # a twin pass: its HRVs on the platform's records, as below
            k: platform_records([archives[i] for i in group]) if len(group) > 1 else None
            for group in groups
            for k in group
        }
        setups = [geo_pass(a, opt, platform[k]) for k, a in enumerate(archives)]
    elif twin and len(archives) > 1:
        records = platform_records(archives)
        setups = [geo_pass(a, opt, records) for a in archives]
    request, found = _found_points(request, setups, Need.ADJUSTMENT in needs and not made)
    placed = [s for s in setups if s is not None]
    if made:
        adjustments = made
    elif block:
        adjustments = _block_adjustment(request, placed, passes_of(archives), dem)
    elif twin and len(archives) > 1:
        adjustments = _twin_adjustment(request, placed)
    return [
        _plan_archive(request, k, makers, setups[k], adjustments[k], dem, found[k])
        for k in range(len(archives))
    ]


def _found_points(
    request: ProcessingRequest, setups: list[PassSetup | None], needed: bool
) -> tuple[ProcessingRequest, list[ReferencePoints | None]]:
    """The control points of the archives that have none found on their reference
    (:func:`levels.reference.find_on_reference`), on their GEO set-up (made here when not
    yet, and kept in ``setups`` for the scenes): the request with them."""
    from levels.reference import find_on_reference

    found: list[ReferencePoints | None] = [None] * len(request.archives)
    if not needed:
        return request, found
    for k, (given, points) in enumerate(zip(request.references, request.gcps, strict=True)):
        if given is None or points is not None:
            continue
        archive = request.archives[k]
        setup = setups[k] or geo_pass(archive, request.options)
        setups[k] = setup
        t0 = time.perf_counter()
        points_found = find_on_reference(archive, setup.pg, setup.scenes, given, request.options)
        found[k] = points_found
        _log.info(
            "%s: %d control points found on the reference in %.1f s",
            request.names[k],
            len(points_found.points),
            time.perf_counter() - t0,
        )
    gcps = tuple(f.points if f is not None else g for f, g in zip(found, request.gcps, strict=True))
    return replace(request, gcps=gcps), found


def _twin_adjustment(
    request: ProcessingRequest, setups: list[PassSetup]
) -> list[Adjustment | None]:
    """Level 2's adjustment of both HRVs of a twin pass together (:func:`plan`)."""
    placed = [k for k, s in enumerate(setups) if s.scenes]
    strips = []
    for k in placed:
        archive, points = request.archives[k], request.gcps[k]
        assert points is not None  # plan() checked
        strips.append(
            Strip(
                setups[k].pg,
                setups[k].scenes,
                points.of_hrv(archive.hrv),
                next(iter(archive.bands)),
            )
        )
    if strips and not any(len(s.gcps) for s in strips):
        raise GcpError("level 2 of a twin pass: no control point in either HRV's file")
    out: list[Adjustment | None] = [None] * len(setups)
    if strips:
        for k, adj in zip(placed, adjust_strips(strips, request.options), strict=True):
            out[k] = adj
    return out


def _block_adjustment(
    request: ProcessingRequest,
    setups: list[PassSetup],
    groups: list[list[int]],
    dem: Dem | None,
) -> list[Adjustment | None]:
    """Level 2 of every pass of the request together (``groups``: the archives of each, a
    twin pass's HRVs on one platform as ``adjustment = "twin"`` takes them), tied by the tie
    points (kind ``tie``) of their control-point sets (:func:`levels.adjust.adjust_block`);
    the DEM of ``dem_path``, when given, observes the tie points' heights."""
    opt = request.options
    if dem is None and opt.dem_path:
        dem = read_dem(opt.dem_path, opt.dem_vertical)
    passes, ties, where = [], [], []
    for group in groups:
        placed = [k for k in group if setups[k].scenes]
        if not placed:
            continue
        strips, sets = [], []
        for k in placed:
            archive, points = request.archives[k], request.gcps[k]
            assert points is not None  # plan() checked
            mine = points.of_hrv(archive.hrv)
            band = next(iter(archive.bands))
            strips.append(Strip(setups[k].pg, setups[k].scenes, mine, band))
            sets.append(mine.ties())
        passes.append(strips)
        ties.append(sets)
        where.append(placed)
    if len(passes) < 2 or not any(len(t) for sets in ties for t in sets):
        raise GcpError(
            "level 2 of a block: give two passes or more and their tie points (kind tie, "
            "docs/gcp.md: station tie writes them)"
        )
    out: list[Adjustment | None] = [None] * len(setups)
    result = adjust_block(passes, ties, opt, dem=dem, dem_sigma_m=opt.tie_height_sigma_m)
    for placed, adjs in zip(where, result, strict=True):
        for k, adj in zip(placed, adjs, strict=True):
            out[k] = adj
    return out


def _plan_archive(
    request: ProcessingRequest,
    k: int,
    makers: tuple[LevelMaker, ...],
    setup: PassSetup | None,
    adjustment: Adjustment | None,
    dem: Dem | None,
    found: ReferencePoints | None = None,
) -> PassPlan:
    """The plan of the request's archive ``k`` (:func:`plan`)."""
    archive, options, name = request.archives[k], request.options, request.names[k]
    out = request.out_dir
    out.mkdir(parents=True, exist_ok=True)
    clock = time.perf_counter
    t0 = clock()
    setup = setup or geo_pass(archive, options)
    pg, scenes, skipped = setup.pg, setup.scenes, setup.skipped
    if request.scenes is not None:  # those asked for alone
        scenes = [s for s in scenes if s.cut.index in request.scenes]
        skipped = [s for s in skipped if s.index in request.scenes]
    band_names = list(archive.bands)
    res = options.pixel_size_m or nominal_pixel_size_m(pg.look_angles[band_names[0]])
    taps = (
        deconvolution_taps(options.psf_fwhm_px, options.noise_to_signal)
        if options.deconvolution
        else np.ones(1)
    )
    prov = {
        "software": f"spot-station {__version__}",
        "inputs": Path(archive.path).name,
        "processing": json.dumps(asdict(_recorded(options, out, request.root or out))),
        "route": "L0 archive",  # a DIMAP scene's archive says its own
        **archive.provenance,
        **request.provenance,
    }
    if dem is not None:
        check_coverage(dem, scenes)
    t_geo = setup.time_s + clock() - t0  # the adjustment is timed apart
    if Need.ADJUSTMENT in _needs(makers) and scenes and adjustment is None:
        points = request.gcps[k]
        assert points is not None  # plan() checked
        mine = points.of_hrv(archive.hrv)
        if not len(mine):
            raise GcpError(
                f"level 2 of HRV{archive.hrv}: no control point of this HRV in the file "
                "(in a twin pass, adjustment = 'twin' lets the other HRV's points serve)"
            )
        adjustment = adjust(pg, scenes, mine, options, band_names[0])
    ctx = PassContext(
        archive,
        pg,
        options,
        res,
        taps,
        out,
        name,
        request.checkpoints[k],
        prov,
        adjustment,
        dem,
        makers,
        frozenset(request.given),
    )
    timings = {"geo": t_geo, "total": setup.time_s + clock() - t0}
    if adjustment is not None:
        timings["adjust"] = adjustment.timings_s["adjust"]
    tail = pg.tail_lines(setup.scene_lines, options.overlap_lines)
    _log.info(
        "GEO of %s: %d scene(s) to make (%s), %d skipped; %.2f s",
        name,
        len(scenes),
        ", ".join(m.name for m in makers),
        len(skipped),
        t_geo,
    )
    return PassPlan(ctx, list(scenes), list(skipped), tail, timings, found)


def run_plans(
    plans: Sequence[PassPlan],
    runner: Runner | None = None,
    on_scene: Callable[[SceneProducts, int], None] | None = None,
) -> list[PassProducts | ScenesFailed]:
    """Make every scene of the ``plans`` as tasks of ``runner`` (:mod:`levels.tasks`; in
    this process by default): per plan its products, or :class:`ScenesFailed` naming its
    failed scenes (the other scenes' products are made). ``on_scene(products, n_scenes)``
    after each scene, in the order they end."""
    runner = runner or InProcess()
    clock = time.perf_counter
    t0 = clock()
    handles: dict[Any, tuple[int, SceneGeometry]] = {}
    for k, p in enumerate(plans):
        shared = runner.share(p.ctx) if p.scenes else None
        for scene in p.scenes:
            handles[runner.submit(p.task_name(scene), make_scene, shared, scene)] = (k, scene)
    made: list[dict[int, SceneProducts]] = [{} for _ in plans]
    failed: list[list[TaskFailure]] = [[] for _ in plans]
    ended = [0.0] * len(plans)
    n_scenes = sum(len(p.scenes) for p in plans)
    for handle, result in runner.completed(handles):
        k, scene = handles[handle]
        ended[k] = clock() - t0
        if isinstance(result, TaskFailure):
            _log.warning("%s", result.line())
            failed[k].append(result)
            continue
        made[k][scene.cut.index] = result
        _log.info("%s: %d product(s)", plans[k].task_name(scene), len(result.paths))
        _log.debug(
            "%s timings: %s",
            plans[k].task_name(scene),
            ", ".join(f"{s} {t:.3f} s" for s, t in result.timings_s.items()),
        )
        if on_scene is not None:
            on_scene(result, n_scenes)
    out: list[PassProducts | ScenesFailed] = []
    for k, p in enumerate(plans):
        timings = {**p.timings_s, "total": p.timings_s["total"] + ended[k]}
        products = PassProducts(
            [made[k][i] for i in sorted(made[k])],
            p.tail_lines,
            timings,
            p.skipped,
            p.ctx.adjustment,
            p.found,
        )
        out.append(ScenesFailed(failed[k], [products]) if failed[k] else products)
    return out


def all_made(results: list[PassProducts | ScenesFailed]) -> list[PassProducts]:
    """What :func:`run_plans` made, all of it: the products of every plan, or the
    failures raised once all tasks ended: a bug raised as itself (its task named in a
    note), bad input as :class:`ScenesFailed`."""
    failures = [f for r in results if isinstance(r, ScenesFailed) for f in r.failures]
    if not failures:
        return [r for r in results if isinstance(r, PassProducts)]
    bug = next((f for f in failures if not f.bad_input), None)
    if bug is not None:
        raise_first(failures, first=bug)
    raise ScenesFailed(failures, [r.made[0] if isinstance(r, ScenesFailed) else r for r in results])


@one_blas_thread
def make_scene(ctx: PassContext, scene: SceneGeometry) -> SceneProducts:
    """One scene's task: every level of the plan made (:mod:`levels.makers.base`: geometry,
    images band by band, quality), those asked written; their paths and figures returned."""
    work = SceneWork(ctx, scene)
    for maker in ctx.makers:
        if maker.prepare is not None:
            with work.timed("geometry"):
                maker.prepare(work)
    for band in ctx.archive.bands:
        _band_images(work, band)
    written = [_maker_of(ctx, name) for name in ctx.options.levels if name not in ctx.given]
    quality = {}
    for maker in written:
        with work.timed("quality"):
            quality[maker.name] = maker.quality(work)
    with work.timed("write"):
        paths = {m.name: _write(work, m, quality[m.name]) for m in written}
    cut = scene.cut
    figures = {lv: scalar_figures(q) for lv, q in quality.items()}
    return SceneProducts(cut.index, cut.first_line, cut.n_lines, paths, figures, work.timings_s)


def _maker_of(ctx: PassContext, name: str) -> LevelMaker:
    """The maker of level ``name`` in the pass's plan."""
    return next(m for m in ctx.makers if m.name == name)


def _band_images(work: SceneWork, band_name: str) -> None:
    """One band's images for every level of the plan: the raw counts read, calibrated and
    deconvolved once for all of them (module docstring)."""
    ctx, scene = work.ctx, work.scene
    band = ctx.archive.bands[band_name]
    rows = slice(scene.cut.first_line, scene.cut.first_line + scene.cut.n_lines)
    with work.timed("calibration"):
        counts, valid = band.counts[rows], band.pixel_valid_rows(rows)
        cal = calibrate(counts, valid, band.gain, band.offset_counts)
    resampled = [m for m in ctx.makers if m.reads is Reads.DECONVOLVED]
    for m in ctx.makers:
        if m.reads is Reads.CALIBRATED:
            with work.timed(m.name):
                work.images[m.name][band_name] = m.image(
                    work, band_name, BandPixels(counts, valid, cal)
                )
    if not resampled:
        return
    with work.timed("deconvolution"):
        cal = counts_in_place(cal)  # the 1A as written: a DIMAP 1A's levels are the same
        dec, dvalid = deconvolve(cal, valid, ctx.taps) if ctx.taps.size > 1 else (cal, valid)
    nan_dec = with_nan(dec, dvalid)  # what every resampling reads
    del cal, dec  # (a full P scene: 144 MB each) not read again
    pixels = BandPixels(counts, dvalid, nan_dec)
    for m in resampled:
        with work.timed(m.name):
            work.images[m.name][band_name] = m.image(work, band_name, pixels)


def _write(work: SceneWork, maker: LevelMaker, quality: dict[str, object]) -> Path:
    """The product of one level of the scene, written whole (:mod:`levels.products`)."""
    ctx, level = work.ctx, maker.name
    images = work.images[level]
    first = next(iter(images.values())).image
    attrs = {
        "level": level,
        "scene_index": work.scene.cut.index,
        "name": ctx.name,
        "hrv": ctx.archive.hrv,
        "mode": ctx.archive.mode,
        "mirror_step": ctx.archive.mirror_step,
        "n_rows": first.shape[0],
        "n_cols": first.shape[1],
        "pixel_size_m": 0.0 if maker.raw_geometry else ctx.pixel_size_m,
    }
    product = Product(
        attrs,
        images,
        maker.geometry_tree(work),
        quality,
        {**ctx.provenance, "level": level},
        maker.map_grid(work),
    )
    path = write_product(
        ctx.out / product_name(ctx.name, work.scene.cut.index, level, product.map_grid is not None),
        product,
        ctx.options.deflate_level,
    )
    write_rpc_sidecar(product, path)  # GDAL finds the RPCs on the product as written
    return path
