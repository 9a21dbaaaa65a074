"""The processing centre on recorded archives: ``levels`` makes the products, the truth
(when the scenario that made an archive is given) measures them.

:func:`reprocess_l0` and :func:`reprocess_pass` process archives already recorded (one
pass, its HRVs), :func:`reprocess_block` the archives of several passes (a block, a
stereo pair), with the truth when the scenario that made them is given: the products are
then those of the run, bit for bit. :func:`process_scenario` emulates, downlinks and
records a scenario's pass first (``station process --scenario`` alone).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from levels.errors import L0Error
from levels.makers.base import Need
from levels.options import ProcessingOptions
from levels.process import (
    PassPlan,
    PassProducts,
    ProcessingRequest,
    plan,
    plan_levels,
)
from levels.readers.formats import open_archive
from levels.readers.gcp import read_gcps
from levels.readers.l0 import L0Archive, read_l0
from levels.tasks import Runner
from levels.work import Pass, Request, Result
from station.chain.gcps import measured_control_points
from station.scenario import Scenario
from station.spacecraft.emulator import Acquisition, emulate
from station.truth.measure import StationTruth
from station.truth.optical import truth_for

if TYPE_CHECKING:
    from levels.reference import ReferenceInput

__all__ = [
    "PACK_POINTS",
    "block_request",
    "gcps_beside",
    "l0_stem",
    "pass_request",
    "plan_reprocess",
    "process_scenario",
    "reprocess_block",
    "reprocess_l0",
    "reprocess_pass",
    "run_dem",
    "scenario_request",
    "with_exported_dem",
]


def reprocess_l0(
    l0_path: str | Path,
    out_dir: str | Path,
    *,
    options: ProcessingOptions | None = None,
    scenario: Scenario | None = None,
    name: str | None = None,
    gcps: str | Path | None = None,
    runner: Runner | None = None,
) -> PassProducts:
    """Process a recorded L0 archive again into ``out_dir``, its scenes as tasks of
    ``runner`` (:mod:`levels.tasks`).

    ``options`` default to the scenario's ``[processing]``, else to the defaults; with the
    ``scenario``, the checkpoints are measured against its truth. Products are named after
    the archive (``<name>.l0.h5`` → ``<name>_s000_2A.nc``) unless ``name`` is given.
    Level 2 reads the control points from ``gcps``, by default the ``<name>.gcp.csv`` a run
    wrote beside the archive.
    """
    return reprocess_pass(
        [l0_path],
        out_dir,
        options=options,
        scenario=scenario,
        names=[name] if name else None,
        gcps=[gcps] if gcps else None,
        runner=runner,
    )[0]


def reprocess_pass(
    l0_paths: Sequence[str | Path],
    out_dir: str | Path,
    *,
    options: ProcessingOptions | None = None,
    scenario: Scenario | list[Scenario] | None = None,
    names: list[str] | None = None,
    gcps: list[str | Path] | None = None,
    runner: Runner | None = None,
    ties_dir: str | Path | None = None,
) -> list[PassProducts]:
    """:func:`reprocess_l0` of the archives of one pass, one per HRV, together
    (:func:`levels.process.plan`: with ``adjustment = "twin"``, level 2 adjusts
    both HRVs at once). ``names`` and ``gcps``, when given, one per archive; the scenes
    are tasks of ``runner`` (:mod:`levels.tasks`, in this process by default)."""
    from levels.work import Step, run
    from levels.work import plan as plan_work

    request, truth = pass_request(
        l0_paths,
        out_dir,
        options=options,
        scenario=scenario,
        names=names,
        gcps=gcps,
        ties_dir=ties_dir,
    )
    result = run(plan_work(request), runner, truth)
    return [result.pass_products(n, Step.SCENES) for n in request.passes[0].names]


def plan_reprocess(
    l0_paths: Sequence[str | Path],
    out_dir: str | Path,
    *,
    options: ProcessingOptions | None = None,
    scenario: Scenario | list[Scenario] | None = None,
    names: list[str] | None = None,
    gcps: list[str | Path] | None = None,
    ties_dir: str | Path | None = None,
) -> list[PassPlan]:
    """Everything of :func:`reprocess_pass` before its scene tasks (the scene driver's
    plans, :func:`levels.process.plan`: what a campaign batches)."""
    request, truth = pass_request(
        l0_paths,
        out_dir,
        options=options,
        scenario=scenario,
        names=names,
        gcps=gcps,
        ties_dir=ties_dir,
    )
    (one,) = request.passes
    return plan(
        ProcessingRequest(
            one.archives,
            request.options,
            request.out_dir,
            one.names,
            checkpoints=tuple(truth.checkpoints(n) for n in one.names),
            gcps=one.gcps,
        )
    )


def pass_request(
    l0_paths: Sequence[str | Path],
    out_dir: str | Path,
    *,
    options: ProcessingOptions | None = None,
    scenario: Scenario | list[Scenario] | None = None,
    names: Sequence[str] | None = None,
    gcps: Sequence[str | Path] | None = None,
    ties_dir: str | Path | None = None,
    references: Sequence[ReferenceInput | None] = (),
    adjustment_dir: str | Path | None = None,
) -> tuple[Request, StationTruth]:
    """Recorded archives processed together (one per HRV of a pass; a block's, each tied
    by its ``<name>.tie.csv`` from ``ties_dir``, else beside it) as one request of
    :mod:`levels.work`, and their truth (the scenario that made them, one for the archives
    of one pass or one per archive; none: no truth). The archives are read lazily (a
    scene's counts are read by its task); the options default to the scenario's, the DEM
    to the run's beside the first archive, the control points to those beside each, or to
    those found on ``references`` (per archive, :class:`levels.reference.ReferenceInput`);
    none read when level 2's adjustment is taken from ``adjustment_dir`` (a directory of its
    level 2 products: :func:`levels.work.taken_adjustment`)."""
    paths = [Path(p) for p in l0_paths]
    for what, given in (("names", names), ("control-point files", gcps)):
        if given is not None and len(given) != len(paths):
            raise L0Error(f"{len(paths)} L0 archives but {len(given)} {what}")
    archives = [open_archive(p) for p in paths]
    # one scenario for the archives of one pass, or one per archive (a block)
    per = scenario if isinstance(scenario, list) else [scenario] * len(archives)
    if len(per) != len(archives):
        raise L0Error(f"{len(archives)} L0 archives but {len(per)} scenarios")
    first = per[0] if per else None
    opts = options or (first.processing if first is not None else ProcessingOptions())
    names = tuple(names or [l0_stem(p) for p in paths])
    truths = {
        n: truth_for(s, a) if s is not None else None
        for n, s, a in zip(names, per, archives, strict=True)
    }
    needs = {n for m in plan_levels(opts.levels) for n in m.needs}
    if Need.DEM in needs and not opts.dem_path:
        opts = dataclasses.replace(opts, dem_path=str(run_dem(paths[0], archives[0])))
    points = None
    if Need.ADJUSTMENT in needs and not any(references) and adjustment_dir is None:
        where = [Path(g) for g in gcps] if gcps else [gcps_beside(p) for p in paths]
        points = [
            read_gcps(w, a.n_lines, a.n_columns) for w, a in zip(where, archives, strict=True)
        ]
        if opts.adjustment == "block":  # each pass's tie points, in ties_dir or beside it
            for k, (p, a) in enumerate(zip(paths, archives, strict=True)):
                name = f"{l0_stem(p)}.tie.csv"
                tie = Path(ties_dir) / name if ties_dir else p.with_name(name)
                if tie.is_file():
                    points[k] = points[k] + read_gcps(tie, a.n_lines, a.n_columns)
    one = Pass(tuple(archives), names, tuple(points or ()), references=tuple(references))
    taken = Path(adjustment_dir) if adjustment_dir is not None else None
    return Request(opts, Path(out_dir), (one,), adjustment_dir=taken), StationTruth(truths)


def with_exported_dem(scn: Scenario, acqs: Sequence[Acquisition], out: Path) -> ProcessingOptions:
    """The scenario's processing options, after its ``[dem]`` (if any) is exported as
    ``<name>.dem.tif`` into ``out``: the DEM level 3 then uses unless ``dem_path`` names
    another."""
    options = scn.processing
    if scn.dem is not None:
        from station.spacecraft.dem import export_dem

        dem = export_dem(acqs, scn.dem, scn.seed, out / f"{scn.name}.dem.tif")
        if not options.dem_path:
            options = dataclasses.replace(options, dem_path=str(dem))
    return options


def run_dem(l0_path: Path, archive: L0Archive) -> Path:
    """The DEM a run exported beside its L0 archive (``<scenario>.dem.tif``), for level 3
    when no ``dem_path`` is given; :class:`DemError` naming both when there is none."""
    from levels.errors import DemError

    names = [str(archive.provenance.get("scenario", "")), l0_stem(l0_path)]
    for name in filter(None, names):
        candidate = l0_path.with_name(f"{name}.dem.tif")
        if candidate.is_file():
            return candidate
    raise DemError(
        f"level 3 needs a DEM: no [processing] dem_path given and no {names[-1]}.dem.tif "
        f"beside {l0_path}; set dem_path in --options (or --scenario)"
    )


def gcps_beside(path: str | Path) -> Path:
    """Where a source's control points are when none are given: ``<name>.gcp.csv`` beside
    it (a run's); for a DIMAP pack without one, its zip or its directory, the
    ``control_points.csv`` it holds (``station export --dimap`` puts them there), read in
    place."""
    import zipfile

    p = Path(path)
    beside = p.with_name(f"{l0_stem(p)}.gcp.csv")
    if beside.is_file():
        return beside
    if p.is_dir() and (p / PACK_POINTS).is_file():  # a pack's directory
        return p / PACK_POINTS
    if p.is_file() and zipfile.is_zipfile(p):
        with zipfile.ZipFile(p) as z:
            if PACK_POINTS in z.namelist():
                return p / PACK_POINTS
    return beside


#: The control points a DIMAP pack holds at its top (:mod:`station.benchmark_pack`).
PACK_POINTS = "control_points.csv"


def l0_stem(path: str | Path) -> str:
    """The name an archive gives its products: ``<name>.l0.h5`` → ``<name>``; a DIMAP
    scene's zip ``<name>.zip``, its directory ``<name>/`` or ``<name>/METADATA.DIM`` →
    ``<name>``."""
    from station.scenario import NAME_PATTERN

    p = Path(path)
    if p.suffix.upper() == ".DIM":
        p = p.resolve().parent
    stem = p.name.removesuffix(".h5").removesuffix(".l0").removesuffix(".zip")
    if not NAME_PATTERN.fullmatch(stem):  # ".", "" or a name no file should carry
        raise L0Error(f"{p}: cannot name products after this file ({stem!r}); give --name")
    return stem


def process_scenario(
    scn: Scenario,
    out_dir: str | Path,
    l0_path: str | Path | None = None,
    runner: Runner | None = None,
) -> tuple[PassProducts, Path]:
    """Emulate, downlink, record and process a scenario; products measured against truth,
    the scenes as tasks of ``runner`` (:mod:`levels.tasks`)."""
    from levels.work import Step, run
    from levels.work import plan as plan_work

    request, truth, l0 = scenario_request(scn, out_dir, l0_path)
    result = run(plan_work(request), runner, truth)
    return result.pass_products(scn.name, Step.SCENES), l0


def scenario_request(
    scn: Scenario, out_dir: str | Path, l0_path: str | Path | None = None
) -> tuple[Request, StationTruth, Path]:
    """A scenario's pass emulated, downlinked and recorded (its L0 archive ``l0_path``, by
    default ``<out>/<name>.l0.h5``, and its control points beside it) as one request of
    :mod:`levels.work`, its truth and its archive's path."""
    from station.chain.session import downlink, record

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    acq = emulate(scn)
    result = downlink(acq)
    l0 = record(acq, result, l0_path or out / f"{scn.name}.l0.h5")
    archive = read_l0(l0, lazy=True)
    truth, gcps = measured_control_points(
        acq, archive, Path(l0).with_name(f"{l0_stem(l0)}.gcp.csv")
    )
    request = Request(
        with_exported_dem(scn, [acq], out),
        out,
        (Pass((archive,), (scn.name,), (gcps,)),),
        provenance=scn.provenance(),
    )
    return request, StationTruth({scn.name: truth}), l0


def reprocess_block(
    l0_paths: Sequence[str | Path],
    out_dir: str | Path,
    *,
    options: ProcessingOptions,
    scenarios: Sequence[Scenario | None] | None = None,
    names: Sequence[str] | None = None,
    gcps: Sequence[str | Path] | None = None,
    runner: Runner | None = None,
) -> Result:
    """Several recorded passes over one ground, to the kinds of a pair (a stereo DEM), as
    one request of :mod:`levels.work` (:func:`block_request`), made."""
    from levels.work import plan, run

    request, truth = block_request(
        l0_paths, out_dir, options=options, scenarios=scenarios, names=names, gcps=gcps
    )
    return run(plan(request), runner, truth)


def block_request(
    l0_paths: Sequence[str | Path],
    out_dir: str | Path,
    *,
    options: ProcessingOptions,
    scenarios: Sequence[Scenario | None] | None = None,
    names: Sequence[str] | None = None,
    gcps: Sequence[str | Path] | None = None,
    made_in: Sequence[Path] | None = None,
    ties_dir: str | Path | None = None,
    adjustment_dir: str | Path | None = None,
) -> tuple[Request, StationTruth]:
    """Several recorded passes over one ground as one request of :mod:`levels.work`, and
    their truth: each pass's scene levels into ``<out>/<name>/`` (2A for the tie points, 1A
    for a pair: its scenario's own ``[processing]`` when given, as its run made them; or
    taken from ``made_in``, a run's passes), then the tie points, the block's level 2, the
    pair's products and level 3 over the pair's DEM into ``<out>/ties``, ``block`` and
    ``stereo``. With the scenarios (one per archive), every product is measured against
    their truth and is the run's, bit for bit. The tie points may be taken from
    ``ties_dir`` and level 2's adjustment from ``adjustment_dir`` (a run's ``ties/`` and
    ``block/``): then no control point is read."""
    paths = [Path(p) for p in l0_paths]
    out = Path(out_dir)
    names = list(names or [l0_stem(p) for p in paths])
    archives = [open_archive(p) for p in paths]
    per: list[Scenario | None] = list(scenarios) if scenarios else [None] * len(paths)
    if len(per) != len(paths):
        raise L0Error(f"{len(paths)} L0 archives but {len(per)} scenarios")
    truths = {
        n: truth_for(s, a) if s is not None else None
        for n, s, a in zip(names, per, archives, strict=True)
    }
    where = [Path(g) for g in gcps] if gcps else [gcps_beside(p) for p in paths]
    if not options.dem_path and per[0] is not None and per[0].dem is not None:
        options = dataclasses.replace(options, dem_path=str(run_dem(paths[0], archives[0])))
    passes = tuple(
        Pass(
            (a,),
            (n,),
            (read_gcps(w, a.n_lines, a.n_columns),) if adjustment_dir is None else (),
            options=s.processing if s is not None else None,
            made_in=made_in[k] if made_in else None,
        )
        for k, (a, n, w, s) in enumerate(zip(archives, names, where, per, strict=True))
    )
    request = Request(
        options,
        out,
        passes,
        ties_dir=Path(ties_dir) if ties_dir is not None else None,
        adjustment_dir=Path(adjustment_dir) if adjustment_dir is not None else None,
    )
    return request, StationTruth(truths, names)
