"""The processing centre's run over one pass: GEO once, COR once per scene and level.

:func:`process_l0` takes an L0 archive (:func:`levels.readers.l0.read_l0`) and
:class:`~levels.options.ProcessingOptions`, and writes one product per scene and level
(:mod:`levels.products`). For each scene, the raw counts are read from the archive once,
calibrated once (level 1A), deconvolved once, and resampled into 1B and 2A: INPE's "all
operations executed by COR require the raw image to be read only once" (paper ``004_…``
§2.2).

Every product carries its quality: the approximation errors of its geometry against the
rigorous model (always), the stripe level before and after calibration (1A), and, when a
:class:`~levels.quality.CheckpointSource` is given (the emulator's truth, or surveyed
points), the checkpoint errors against it.

XS bands share one output grid, computed on the first band; each band goes through its own
1B polynomials and 2A grids onto it, so that the bands are registered.

This module needs nothing of the emulator: a user with L0 archives runs it alone
(``station process L0.h5`` is a thin command over it).
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, TypeVar

import numpy as np
from numpy.typing import NDArray

from levels import __version__
from levels.adjust import Adjustment, Strip, adjust, adjust_strips
from levels.cor.radiometry import (
    calibrate,
    deconvolution_taps,
    deconvolve,
    fir_response,
    mtf,
    stripe_level,
    to_counts,
)
from levels.cor.resample import resample_1b, resample_2a, resample_3, with_nan
from levels.errors import DemError, GcpError, GeometryError, LevelsError
from levels.geo.level1b import Level1BGeometry, level1b_geometry
from levels.geo.level2a import INVERSE_METHODS, Level2AGeometry, level2a_geometry
from levels.geo.level3 import Level3Geometry, level3_geometry
from levels.geo.maps import ascending_node_lon_rad, map_crs
from levels.geo.rpc import RPC_HEIGHT_MARGIN_M, Rpc, rpc_of_1b, rpc_of_model
from levels.geo.scenes import PassGeometry, SceneGeometry, cut_scenes, pass_geometry
from levels.geometry.sensor import LookAngleTable
from levels.options import ProcessingOptions
from levels.products import BandImage, MapGrid, Product, product_name, write_product
from levels.quality import CheckpointSource, scalar_figures
from levels.readers.dem import Dem, read_dem
from levels.readers.gcp import ControlPointSet
from levels.readers.l0 import L0Archive
from levels.spot import ORBIT_ALTITUDE_M
from levels.tasks import InProcess, Runner, TaskFailure, raise_first
from levels.threads import one_blas_thread

__all__ = [
    "PassPlan",
    "PassProducts",
    "PassSetup",
    "SceneProducts",
    "ScenesFailed",
    "SkippedScene",
    "all_made",
    "geo_pass",
    "make_scene",
    "nominal_pixel_size_m",
    "pass_dem",
    "plan_l0",
    "plan_pass",
    "platform_records",
    "process_l0",
    "process_pass",
    "run_plans",
]


@dataclass(frozen=True)
class SceneProducts:
    """What was made of one scene: product paths and headline quality per level."""

    index: int
    first_line: int
    n_lines: int
    paths: dict[str, Path]
    quality: dict[str, dict[str, Any]]
    timings_s: dict[str, float]


@dataclass(frozen=True)
class SkippedScene:
    """A scene of the pass that could not be made, and why (lost in the downlink, or GEO
    could not place it: no attitude or ephemeris over it)."""

    index: int
    first_line: int
    n_lines: int
    reason: str


@dataclass(frozen=True)
class PassProducts:
    """All scenes of a pass, the rows left after the last whole scene, GEO's time."""

    scenes: list[SceneProducts]
    tail_lines: int
    timings_s: dict[str, float] = field(default_factory=dict)
    skipped: list[SkippedScene] = field(default_factory=list)
    adjustment: Adjustment | None = None


def nominal_pixel_size_m(look: LookAngleTable) -> float:
    """The nominal output pixel: the look table's angular pitch at 822 km, to 10 m (10 m
    for P, 20 m for XS, and proportionally more for a reduced detector count)."""
    pitch = float(np.median(np.abs(np.diff(look.psi_y_rad))))
    return max(10.0, 10.0 * round(pitch * ORBIT_ALTITUDE_M / 10.0))


_G = TypeVar("_G", Level1BGeometry, Level2AGeometry, Level3Geometry)


def _rpcs(
    scene: SceneGeometry,
    opt: ProcessingOptions,
    g1b: dict[str, Level1BGeometry] | None,
    g3: dict[str, Level3Geometry] | None,
) -> dict[str, dict[str, Rpc]]:
    """RPCs of the image-geometry levels made (1A, 1B), per band (:mod:`levels.geo.rpc`):
    over the heights of level 3's DEM under the scene when there is one, else the reference
    height ± ``RPC_HEIGHT_MARGIN_M``."""
    if g3 is not None:
        h = next(iter(g3.values())).heights_m
        heights = (float(h[0]), float(h[-1]))
    else:
        ref = opt.reference_height_m
        heights = (ref - RPC_HEIGHT_MARGIN_M, ref + RPC_HEIGHT_MARGIN_M)
    out: dict[str, dict[str, Rpc]] = {}
    if "1A" in opt.levels:
        out["1A"] = {b: rpc_of_model(m, heights) for b, m in scene.models.items()}
    if g1b is not None:
        out["1B"] = {b: rpc_of_1b(scene.models[b], g1b[b], heights) for b in scene.models}
    return out


def _per_band(scene: SceneGeometry, make: Callable[[str, _G | None], _G]) -> dict[str, _G]:
    """A geometry per band, every band on the first band's output grid."""
    first, *others = scene.models
    out = {first: make(first, None)}
    for b in others:
        out[b] = make(b, out[first])
    return out


@dataclass(frozen=True, eq=False)
class _PassContext:
    """What every scene of a pass shares: the archive, GEO's pass set-up, the options and
    what follows from them."""

    archive: L0Archive
    pg: PassGeometry
    options: ProcessingOptions
    pixel_size_m: float
    taps: NDArray[np.float64]
    out: Path
    name: str
    checkpoints: CheckpointSource | None
    provenance: dict[str, Any]
    adjustment: Adjustment | None
    dem: Dem | None


@dataclass(frozen=True, eq=False)
class PassSetup:
    """GEO of one HRV's pass: the pass set-up, the scenes it can place and those it skips."""

    archive: L0Archive
    pg: PassGeometry
    scenes: list[SceneGeometry]
    skipped: list[SkippedScene]
    scene_lines: int
    time_s: float


def platform_records(
    archives: Sequence[L0Archive],
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The platform's gyro records of a pass imaged by several HRVs: every record any HRV's
    channel brought (each carries the same platform data; a record lost on one channel may
    have come through the other). Times and rates, unsorted (GEO sorts and deduplicates)."""
    first = archives[0]
    for a in archives[1:]:
        if a.epoch != first.epoch:
            raise GeometryError(
                f"{a.path} and {first.path} count time from different epochs: not the same pass"
            )
    return (
        np.concatenate([a.aux_t_s for a in archives]),
        np.concatenate([a.gyro_rates_rad_per_s for a in archives]),
    )


@one_blas_thread
def geo_pass(
    archive: L0Archive,
    options: ProcessingOptions,
    records: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None,
) -> PassSetup:
    """GEO's set-up of a pass and its scenes (``records``: the platform's gyro records,
    by default the archive's own; :func:`platform_records` for a twin pass)."""
    t0 = time.perf_counter()
    band_names = list(archive.bands)
    gyro_t, gyro = records or (archive.aux_t_s, archive.gyro_rates_rad_per_s)
    pg = pass_geometry(
        archive.epoch,
        archive.line_t_s,
        archive.line_period_s,
        archive.ephemeris,
        gyro_t,
        gyro,
        {b: archive.bands[b].look for b in band_names},
    )
    n_det = archive.bands[band_names[0]].counts.shape[1]
    scene_lines = options.scene_lines or n_det
    cuts = cut_scenes(archive.n_lines, scene_lines, options.overlap_lines)
    # a row is seen when one of its segments arrived (every segment has detectors)
    rows_seen = np.logical_or.reduce([archive.bands[b].valid.any(axis=1) for b in band_names])
    scenes, skipped = [], []
    for c in cuts:
        if not rows_seen[c.first_line : c.first_line + c.n_lines].any():
            skipped.append(
                SkippedScene(
                    c.index, c.first_line, c.n_lines, "no valid line: lost in the downlink"
                )
            )
            continue
        try:
            scenes.append(pg.scene(c, options.reference_height_m))
        except GeometryError as exc:
            skipped.append(
                SkippedScene(c.index, c.first_line, c.n_lines, f"GEO could not place it: {exc}")
            )
    return PassSetup(archive, pg, scenes, skipped, scene_lines, time.perf_counter() - t0)


def pass_dem(options: ProcessingOptions) -> Dem | None:
    """The DEM of level 3 (``options.dem_path``, heights above ``options.dem_vertical``),
    or None when level 3 is not asked; :class:`DemError` when it is and no DEM is named."""
    if "3" not in options.levels:
        return None
    if not options.dem_path:
        raise DemError(
            "level 3 needs a DEM: set [processing] dem_path to a DEM file (GeoTIFF, SRTM "
            ".hgt, DTED) and dem_vertical to its datum, or give the scenario a [dem] section"
        )
    return read_dem(options.dem_path, options.dem_vertical)


def _need_gcps(options: ProcessingOptions, gcps: Any) -> None:
    if "2" in options.levels and gcps is None:
        raise GcpError(
            "level 2 needs control points: give the pass's control-point file "
            "(docs/gcp.md), or leave '2' out of the levels"
        )


def process_l0(
    archive: L0Archive,
    options: ProcessingOptions,
    out_dir: str | Path,
    *,
    name: str = "pass",
    checkpoints: CheckpointSource | None = None,
    provenance: dict[str, Any] | None = None,
    on_scene: Callable[[SceneProducts, int], None] | None = None,
    gcps: ControlPointSet | None = None,
    setup: PassSetup | None = None,
    adjustment: Adjustment | None = None,
    dem: Dem | None = None,
    runner: Runner | None = None,
) -> PassProducts:
    """GEO and COR over a pass (module docstring); products go to ``out_dir``.

    Parameters
    ----------
    archive
        The pass, as :func:`levels.readers.l0.read_l0` reads it (``lazy=True`` to keep one
        scene's counts in memory at a time).
    options
        What to make and how.
    name
        Products are named ``<name>_s<scene>_<level>.h5``.
    checkpoints
        Where checkpoints truly are, for the ``checkpoints`` quality figures (optional).
    provenance
        Added to each product's ``provenance`` group, over the archive's own.
    on_scene
        Called as ``on_scene(done, n_scenes)`` after each scene (progress reporting).
    gcps
        Control points of the pass (``docs/gcp.md``; those of the archive's HRV are used):
        level 2 needs them (:mod:`levels.adjust`).
    setup, adjustment
        GEO's set-up and level 2's adjustment when already made (:func:`process_pass`
        makes them for both HRVs of a twin pass together).
    dem
        Level 3's DEM when already read (by default :func:`pass_dem` reads the options').
        Level 3 is made on level 2's refined model when level 2 is made too, on the system
        model otherwise.
    runner
        Where the scenes are made (:mod:`levels.tasks`; by default one after another in
        this process). A scene that fails does not stop the others: once they are made,
        :class:`ScenesFailed` names every failed scene (the error itself when one is a
        bug).
    """
    plan = plan_l0(
        archive,
        options,
        out_dir,
        name=name,
        checkpoints=checkpoints,
        provenance=provenance,
        gcps=gcps,
        setup=setup,
        adjustment=adjustment,
        dem=dem,
    )
    return all_made(run_plans([plan], runner, on_scene))[0]


@dataclass(frozen=True, eq=False)
class PassPlan:
    """One HRV's pass ready for its scene tasks (:func:`plan_l0`): what every scene
    shares, the scenes to make, those skipped, GEO's time."""

    ctx: _PassContext
    scenes: list[SceneGeometry]
    skipped: list[SkippedScene]
    tail_lines: int
    timings_s: dict[str, float]

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


def plan_l0(
    archive: L0Archive,
    options: ProcessingOptions,
    out_dir: str | Path,
    *,
    name: str = "pass",
    checkpoints: CheckpointSource | None = None,
    provenance: dict[str, Any] | None = None,
    gcps: ControlPointSet | None = None,
    setup: PassSetup | None = None,
    adjustment: Adjustment | None = None,
    dem: Dem | None = None,
) -> PassPlan:
    """Everything of :func:`process_l0` before its scenes (same parameters): GEO's set-up,
    level 2's adjustment, the DEM, the output directory."""
    if adjustment is None:
        _need_gcps(options, gcps)
    if dem is None:
        dem = pass_dem(options)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    clock = time.perf_counter
    t0 = clock()
    setup = setup or geo_pass(archive, options)
    pg, scenes = setup.pg, setup.scenes
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
        "processing": json.dumps(asdict(options)),
        **archive.provenance,
        **(provenance or {}),
    }
    t_geo = setup.time_s + clock() - t0  # the adjustment is timed apart
    if "2" in options.levels and scenes and adjustment is None:
        assert gcps is not None
        mine = gcps.of_hrv(archive.hrv)
        if not len(mine):
            raise GcpError(
                f"level 2 of HRV{archive.hrv}: no control point of this HRV in the file "
                "(in a twin pass, adjustment = 'twin' lets the other HRV's points serve)"
            )
        adjustment = adjust(pg, scenes, mine, options, band_names[0])
    ctx = _PassContext(
        archive, pg, options, res, taps, out, name, checkpoints, prov, adjustment, dem
    )
    timings = {"geo": t_geo, "total": setup.time_s + clock() - t0}
    if adjustment is not None:
        timings["adjust"] = adjustment.timings_s["adjust"]
    tail = pg.tail_lines(setup.scene_lines, options.overlap_lines)
    return PassPlan(ctx, list(scenes), list(setup.skipped), tail, timings)


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
    for k, plan in enumerate(plans):
        shared = runner.share(plan.ctx) if plan.scenes else None
        for scene in plan.scenes:
            handles[runner.submit(plan.task_name(scene), make_scene, shared, scene)] = (k, scene)
    made: list[dict[int, SceneProducts]] = [{} for _ in plans]
    failed: list[list[TaskFailure]] = [[] for _ in plans]
    ended = [0.0] * len(plans)
    n_scenes = sum(len(p.scenes) for p in plans)
    for handle, result in runner.completed(handles):
        k, scene = handles[handle]
        ended[k] = clock() - t0
        if isinstance(result, TaskFailure):
            failed[k].append(result)
            continue
        made[k][scene.cut.index] = result
        if on_scene is not None:
            on_scene(result, n_scenes)
    out: list[PassProducts | ScenesFailed] = []
    for k, plan in enumerate(plans):
        timings = {**plan.timings_s, "total": plan.timings_s["total"] + ended[k]}
        products = PassProducts(
            [made[k][i] for i in sorted(made[k])],
            plan.tail_lines,
            timings,
            plan.skipped,
            plan.ctx.adjustment,
        )
        out.append(ScenesFailed(failed[k], [products]) if failed[k] else products)
    return out


def all_made(results: list[PassProducts | ScenesFailed]) -> list[PassProducts]:
    """What :func:`run_plans` made, all of it: the products of every plan, or the
    failures raised once all tasks ended: a bug raised as itself (its task named in a
    note), bad input as :class:`ScenesFailed`."""
    failures = [f for r in results if isinstance(r, ScenesFailed) for f in r.failures]
    if not failures:
        return results  # type: ignore[return-value]
    bug = next((f for f in failures if not f.bad_input), None)
    if bug is not None:
        raise_first(failures, first=bug)
    raise ScenesFailed(failures, [r.made[0] if isinstance(r, ScenesFailed) else r for r in results])


def process_pass(
    archives: Sequence[L0Archive],
    options: ProcessingOptions,
    out_dir: str | Path,
    *,
    names: Sequence[str],
    checkpoints: Sequence[CheckpointSource | None] | None = None,
    provenance: dict[str, Any] | None = None,
    on_scene: Callable[[SceneProducts, int], None] | None = None,
    gcps: Sequence[ControlPointSet | None] | None = None,
    runner: Runner | None = None,
) -> list[PassProducts]:
    """Every HRV of one pass (one L0 archive each, ``names`` theirs): :func:`process_l0`
    for each, their scenes as tasks of one ``runner``, except that with ``adjustment =
    "twin"`` and level 2 both HRVs' GEO use the platform's gyro records of either channel
    (:func:`platform_records`) and are refined by one adjustment
    (:func:`levels.adjust.adjust_strips`), so that control points in one HRV serve the
    other. ``gcps[k]`` are the points of ``archives[k]``'s HRV."""
    plans = plan_pass(
        archives,
        options,
        out_dir,
        names=names,
        checkpoints=checkpoints,
        provenance=provenance,
        gcps=gcps,
    )
    return all_made(run_plans(plans, runner, on_scene))


def plan_pass(
    archives: Sequence[L0Archive],
    options: ProcessingOptions,
    out_dir: str | Path,
    *,
    names: Sequence[str],
    checkpoints: Sequence[CheckpointSource | None] | None = None,
    provenance: dict[str, Any] | None = None,
    gcps: Sequence[ControlPointSet | None] | None = None,
) -> list[PassPlan]:
    """Everything of :func:`process_pass` before its scenes: one plan per archive."""
    n = len(archives)
    if len(names) != n:
        raise ValueError(f"{n} archives but {len(names)} names")
    marks = list(checkpoints) if checkpoints is not None else [None] * n
    points = list(gcps) if gcps is not None else [None] * n
    hrvs = [a.hrv for a in archives]
    if len(set(hrvs)) != n:
        raise GeometryError(f"one archive per HRV of a pass: got HRVs {hrvs}")
    dem = pass_dem(options)  # read once for both HRVs
    setups: list[PassSetup | None] = [None] * n
    adjustments: list[Adjustment | None] = [None] * n
    if options.adjustment == "twin" and "2" in options.levels and n > 1:
        for p in points:
            _need_gcps(options, p)
        records = platform_records(archives)
        setups = [geo_pass(a, options, records) for a in archives]
        placed = [k for k, s in enumerate(setups) if s.scenes]
        strips = [
            Strip(
                setups[k].pg,
                setups[k].scenes,
                points[k].of_hrv(archives[k].hrv),  # type: ignore[union-attr]
                next(iter(archives[k].bands)),
            )
            for k in placed
        ]
        if strips and not any(len(s.gcps) for s in strips):
            raise GcpError("level 2 of a twin pass: no control point in either HRV's file")
        if strips:
            for k, adj in zip(placed, adjust_strips(strips, options), strict=True):
                adjustments[k] = adj
    return [
        plan_l0(
            a,
            options,
            out_dir,
            name=names[k],
            checkpoints=marks[k],
            provenance=provenance,
            gcps=points[k],
            setup=setups[k],
            adjustment=adjustments[k],
            dem=dem,
        )
        for k, a in enumerate(archives)
    ]


@one_blas_thread
def make_scene(ctx: _PassContext, scene: SceneGeometry) -> SceneProducts:
    """One scene's task: its products written, their paths and figures returned."""
    clock = time.perf_counter
    opt, res = ctx.options, ctx.pixel_size_m
    timings: dict[str, float] = {}
    t = clock()
    rows = slice(scene.cut.first_line, scene.cut.first_line + scene.cut.n_lines)
    g1b = None
    maps: dict[str, dict[str, Level2AGeometry]] = {}  # map levels' grids: 2A, 2
    refined = None
    if "1B" in opt.levels:
        g1b = _per_band(scene, lambda b, like: level1b_geometry(scene, res, band=b, like=like))

    node = ascending_node_lon_rad(ctx.pg.ephemeris) if opt.crs == "som" else None
    crs = map_crs(opt.crs, scene.centre_lat_rad, scene.centre_lon_rad, node)

    grids = {"grid_rows": opt.grid_rows, "grid_columns": opt.grid_columns}

    def map_geometry(sg: SceneGeometry) -> dict[str, Level2AGeometry]:
        return _per_band(
            sg,
            lambda b, like: level2a_geometry(
                sg, res, crs, opt.inverse_2a, band=b, like=like, **grids
            ),
        )

    # level 2's "before" checkpoints are the 2A geometry's: made for them when 2A is not
    if "2A" in opt.levels or ("2" in opt.levels and ctx.checkpoints is not None):
        maps["2A"] = map_geometry(scene)
    if "2" in opt.levels:
        assert ctx.adjustment is not None
        refined = ctx.adjustment.refine(ctx.pg, scene)
        maps["2"] = map_geometry(refined)
    g2a = maps.get("2A")
    timings["geometry"] = clock() - t
    g3 = None
    scene3 = refined if refined is not None else scene  # level 2's model when it is made
    if "3" in opt.levels:
        t = clock()
        dem = ctx.dem
        assert dem is not None
        g3 = _per_band(
            scene3,
            lambda b, like: level3_geometry(
                scene3, dem, res, crs, opt.inverse_2a, band=b, like=like, **grids
            ),
        )
        timings["3_geometry"] = clock() - t
    t = clock()
    rpcs = _rpcs(scene, opt, g1b, g3)
    if rpcs:
        timings["rpc"] = clock() - t
    images: dict[str, dict[str, BandImage]] = {lv: {} for lv in opt.levels}
    stripes: dict[str, dict[str, float]] = {}
    hidden: dict[str, float] = {}
    for bname, band in ctx.archive.bands.items():
        t = clock()
        counts, valid = band.counts[rows], band.pixel_valid_rows(rows)
        cal = calibrate(counts, valid, band.gain, band.offset_counts)
        stripes[bname] = {
            "raw_counts": stripe_level(counts, valid),
            "level_1a_counts": stripe_level(cal, valid),
        }
        if "1A" in opt.levels:
            images["1A"][bname] = BandImage(to_counts(cal), valid)
        timings["1A"] = timings.get("1A", 0.0) + clock() - t
        if g1b is None and not maps and g3 is None:
            continue
        t = clock()
        dec, dvalid = deconvolve(cal, valid, ctx.taps) if ctx.taps.size > 1 else (cal, valid)
        timings["deconvolution"] = timings.get("deconvolution", 0.0) + clock() - t
        nan_dec = with_nan(dec, dvalid)  # what every resampling reads
        del cal, dec  # (a full P scene: 144 MB each) not read again
        if g1b is not None:
            t = clock()
            images["1B"][bname] = BandImage(
                *resample_1b(nan_dec, None, g1b[bname], opt.interpolation_1b)
            )
            timings["1B"] = timings.get("1B", 0.0) + clock() - t
        for level, grids in maps.items():
            if level in opt.levels:  # 2A's grids may be there for level 2's checkpoints only
                t = clock()
                images[level][bname] = BandImage(
                    *resample_2a(nan_dec, None, grids[bname], opt.resampling_2a)
                )
                timings[level] = timings.get(level, 0.0) + clock() - t
        if g3 is not None:
            t = clock()
            image, ok, hid = resample_3(nan_dec, None, g3[bname], opt.resampling_2a)
            images["3"][bname] = BandImage(image, ok)
            # of the pixels the scene covers, the share hidden by the relief
            hidden[bname] = float(hid.sum() / max(1, int(ok.sum() + hid.sum())))
            timings["3"] = timings.get("3", 0.0) + clock() - t
    t = clock()
    quality = _quality(scene, opt, g1b, g2a, stripes, ctx.taps, ctx.checkpoints)
    if refined is not None:
        assert ctx.adjustment is not None
        quality["2"] = _quality_2(
            scene,
            refined,
            maps["2"],
            quality["radiometry"],
            quality.get("2A", {}).get("checkpoints"),
            ctx.adjustment,
            opt,
            ctx.checkpoints,
        )
    if g3 is not None:
        quality["3"] = _quality_3(
            scene3, g3, hidden, quality["radiometry"], refined is not None, opt, ctx.checkpoints
        )
    quality = {lv: quality[lv] for lv in opt.levels}
    timings["quality"] = clock() - t
    t = clock()
    common = ctx.pg.product_tree(scene)
    paths = {}
    for level in opt.levels:
        geometry = dict(common)
        if level == "1B":
            geometry["level_1b"] = Level1BGeometry.product_tree(g1b)  # type: ignore[arg-type]
        if level in rpcs:
            geometry["rpc"] = {b: rpc.product_tree() for b, rpc in rpcs[level].items()}
        if level == "2A":
            geometry["level_2a"] = Level2AGeometry.product_tree(g2a)  # type: ignore[arg-type]
        if level == "2":
            assert refined is not None and ctx.adjustment is not None
            geometry = ctx.pg.product_tree(refined)
            geometry["level_2a"] = Level2AGeometry.product_tree(maps["2"])
            geometry["adjustment"] = ctx.adjustment.product_tree(scene.cut.index)
        if level == "3":
            assert g3 is not None
            geometry = ctx.pg.product_tree(scene3)
            geometry["level_3"] = Level3Geometry.product_tree(g3)
            if refined is not None:  # made on level 2's model
                assert ctx.adjustment is not None
                geometry["adjustment"] = ctx.adjustment.product_tree(scene.cut.index)
        first = next(iter(images[level].values())).image
        attrs = {
            "level": level,
            "scene_index": scene.cut.index,
            "name": ctx.name,
            "hrv": ctx.archive.hrv,
            "mode": ctx.archive.mode,
            "mirror_step": ctx.archive.mirror_step,
            "n_rows": first.shape[0],
            "n_cols": first.shape[1],
            "pixel_size_m": res if level != "1A" else 0.0,
        }
        grid = None
        if level in maps or level == "3":
            g = next(iter((g3 if level == "3" else maps[level]).values()))  # type: ignore[union-attr]
            grid = MapGrid(g.crs_wkt, g.geotransform)
        product = Product(
            attrs, images[level], geometry, quality[level], {**ctx.provenance, "level": level}, grid
        )
        paths[level] = write_product(
            ctx.out / product_name(ctx.name, scene.cut.index, level), product, opt.deflate_level
        )
    timings["write"] = clock() - t
    return SceneProducts(
        scene.cut.index,
        scene.cut.first_line,
        scene.cut.n_lines,
        paths,
        {lv: scalar_figures(q) for lv, q in quality.items()},
        timings,
    )


def _radiometry(opt: ProcessingOptions, taps: NDArray[np.float64]) -> dict[str, Any]:
    """The deconvolution of levels 1B, 2A and 2, and the MTF at Nyquist before and after."""
    nyquist = np.array([0.5])
    before = float(mtf(nyquist, opt.psf_fwhm_px)[0])
    return {
        "deconvolution_taps": taps,
        "mtf_at_nyquist_before": before,
        "mtf_at_nyquist_after": before * abs(float(fir_response(taps, nyquist)[0])),
    }


def _quality(
    scene: SceneGeometry,
    opt: ProcessingOptions,
    g1b: dict[str, Level1BGeometry] | None,
    g2a: dict[str, Level2AGeometry] | None,
    stripes: dict[str, dict[str, float]],
    taps: NDArray[np.float64],
    checkpoints: CheckpointSource | None,
) -> dict[str, dict[str, Any]]:
    radiometry = _radiometry(opt, taps)
    # the levels' trees, and the radiometry they share (for level 2's)
    q: dict[str, dict[str, Any]] = {"1A": {"stripe_level": stripes}, "radiometry": radiometry}
    per_side = opt.checkpoints_per_side
    bands = list(scene.models)
    if g1b is not None:
        # the first band's figures: the others' fits are the same polynomials a few tenths
        # of a pixel apart, and their checkpoints below measure each band
        q["1B"] = {
            "radiometry": radiometry,
            "polynomials_vs_model": g1b[bands[0]].approximation_error(scene.model),
        }
        if checkpoints is not None:
            q["1B"]["checkpoints"] = {
                b: checkpoints.level_1b(scene, g1b[b], k, per_side) for k, b in enumerate(bands)
            }
    if g2a is not None:  # made for level 2's "before" checkpoints alone when 2A is not asked
        g = g2a[bands[0]]
        approx = {
            m: g.approximation_error(scene.model, scene.reference_height_m, m)
            for m in (INVERSE_METHODS if "2A" in opt.levels else ())
        }
        q["2A"] = {"radiometry": radiometry, "inverse_vs_model": approx, "inverse_method": g.method}
        if checkpoints is not None:
            q["2A"]["checkpoints"] = {
                b: checkpoints.level_2a(scene, g2a[b], k, per_side) for k, b in enumerate(bands)
            }
    return q


def _quality_3(
    scene: SceneGeometry,
    g3: dict[str, Level3Geometry],
    hidden: dict[str, float],
    radiometry: dict[str, Any],
    refined: bool,
    opt: ProcessingOptions,
    checkpoints: CheckpointSource | None,
) -> dict[str, Any]:
    """Level 3's quality: the anchor grid's error against the rigorous model (every band's),
    the DEM used, the pixels hidden by the relief or over voids, and with a checkpoint
    source the errors on the terrain beside those 2A had at the same points."""
    bands = list(scene.models)
    g = g3[bands[0]]
    lo, hi = g.terrain_range_m
    q: dict[str, Any] = {
        "radiometry": radiometry,
        "model": "level 2 (adjusted on control points)" if refined else "system",
        "anchor_error_px": {b: dict(g3[b].anchor_error_px) for b in bands},
        "anchor_step_px": int(g.grid.inverse_step[0]),
        "anchor_heights_m": g.heights_m,
        "dem": {
            "source": Path(g.dem.source).name,
            "vertical": g.dem.vertical,
            "spacing_m": g.dem_spacing_m,
            "void_fraction": g.dem.void_fraction,
            "height_min_m": lo if np.isfinite(lo) else None,
            "height_max_m": hi if np.isfinite(hi) else None,
        },
        "hidden_fraction": hidden,
    }
    if checkpoints is not None:
        q["checkpoints"] = {
            b: checkpoints.level_3(scene, g3[b], k, opt.checkpoints_per_side)
            for k, b in enumerate(bands)
        }
    return q


def _quality_2(
    scene: SceneGeometry,
    refined: SceneGeometry,
    g2: dict[str, Level2AGeometry],
    radiometry: dict[str, Any],
    before: dict[str, Any] | None,
    adjustment: Adjustment,
    opt: ProcessingOptions,
    checkpoints: CheckpointSource | None,
) -> dict[str, Any]:
    """Level 2's quality: its inverse against the refined model, the control points of the
    scene after the adjustment, the predicted accuracy and, with a checkpoint source, the
    checkpoint errors after (the refined model) and ``before`` (the 2A model's)."""
    bands = list(scene.models)
    g = g2[bands[0]]
    k = adjustment.of_scene(scene.cut.index)
    mine = adjustment.point_scene == scene.cut.index
    status = np.array(adjustment.point_status)
    used = mine & (status == "used")
    after = np.hypot(*adjustment.residual_after_px[used].T)
    sigma = adjustment.predicted_sigma_m[k]
    q: dict[str, Any] = {
        "inverse_vs_model": {
            g.method: g.approximation_error(refined.model, refined.reference_height_m, g.method)
        },
        "inverse_method": g.method,
        "radiometry": radiometry,
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
    per_side = opt.checkpoints_per_side
    if checkpoints is not None:
        q["checkpoints"] = {
            b: checkpoints.level_2a(refined, g2[b], i, per_side) for i, b in enumerate(bands)
        }
        if before is not None:
            q["checkpoints_2a"] = before
    return q
