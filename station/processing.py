"""``station process`` as flows of the run skeleton (:mod:`station.flow`): recorded archives
(one pass's HRVs, or a block's tied beside them), a scenario's pass (emulated and recorded
first), several passes over one ground (a pair's products) and a SAR frame, each into one
output directory with ``process.json`` (:data:`station.reports.PROCESS`) and its catalogue.

Each flow's report says, per archive, its products (scene, level, path, size, valid share,
headline figures, timings) and the scenes it skipped; a block's adds the block's level 2
and 3, the ties and the pair's products; a frame's, its products.
"""

from __future__ import annotations

import argparse
import dataclasses
import logging
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

from levels.options import ProcessingOptions
from levels.process import PassProducts
from levels.work import Frame, Measure, Request, Result, Step
from station.flow import Flow, FlowRun
from station.preflight import Checked
from station.reports import PROCESS
from station.scenario import Scenario
from station.truth.measure import StationTruth

if TYPE_CHECKING:
    from levels.frame import FrameOptions
    from levels.geometry.dem import Dem
    from levels.readers.sar import SarFrame
    from levels.reference import ReferenceInput
    from station.sar_scenario import SarScenario

_log = logging.getLogger(__name__)

__all__ = [
    "ProcessArchives",
    "ProcessBlock",
    "ProcessFlow",
    "ProcessFrame",
    "ProcessScenario",
    "archive_data",
    "archives_flow",
    "check_archives",
    "command_options",
    "frame_flow",
    "is_frame",
    "options_of",
    "recorded_cut",
]


@dataclass(frozen=True)
class Taken:
    """Steps of a reprocessing taken from directories, not made again (``station process
    --ties DIR --adjustment-from DIR``): the tie points (``<name>.tie.csv``) and level 2's
    adjustment (the level 2 products that carry it: :func:`levels.work.taken_adjustment`)."""

    ties_dir: Path | None = None
    adjustment_dir: Path | None = None


class ProcessFlow(Flow, Protocol):
    """A ``station process`` flow: what it names its products, what its checks found, and
    its checks, the whole of them with ``full`` (``--check``)."""

    names: list[str]
    found: Checked

    def check(self, out: Path, full: bool = False) -> None: ...


class _Processing:
    """What every ``station process`` flow shares: its report, what its output is made of
    (the names of its products), the files it reads, its catalogue."""

    report = PROCESS

    def __init__(self, names: Sequence[str], inputs: Sequence[Path], description: str) -> None:
        self.names, self._inputs, self._description = list(names), list(inputs), description
        self.out = Path()
        self._truth: Measure | None = None

    @property
    def owner(self) -> object:
        return self.names

    def what(self, owner: object) -> str:
        return f"products of {owner}"

    def inputs(self) -> list[Path]:
        return self._inputs

    def catalog(self) -> tuple[str, str]:
        return self.out.name, self._description

    def measure(self) -> Measure:
        assert self._truth is not None  # acquired first
        return self._truth


class _Recorded(_Processing):
    """What the flows of recorded archives share: the archives, their names, options and
    files read, the scenarios that made them, their control points (or the reference they
    are found on), the steps taken from directories, the workers; the checks before work
    (:func:`check_archives`)."""

    def __init__(
        self,
        sources: Sequence[Path],
        names: Sequence[str],
        options: ProcessingOptions,
        inputs: Sequence[Path],
        *,
        scenarios: Sequence[Scenario] = (),
        gcps: Sequence[str | Path] | None = None,
        taken: Taken = Taken(),
        reference: str | Path | None = None,
        workers: int = 0,
    ) -> None:
        super().__init__(names, inputs, f"the products of a reprocessing of {', '.join(names)}")
        self.sources, self.options, self.scenarios = list(sources), options, list(scenarios)
        self.gcps, self.taken, self.workers = gcps, taken, workers
        self.reference = reference  # a lone pass's control points found on it
        self.found = Checked()

    def check(self, out: Path, full: bool = False) -> None:
        """The archives readable and their scenes' memory and disk (``full``: their
        control points and DEM too, :func:`check_archives`)."""
        self.out = out
        self.found = check_archives(
            self.sources, self.options, out, self.gcps, full, self.workers, self.taken
        )


class ProcessArchives(_Recorded):
    """Recorded archives processed together (``station.reprocess.pass_request``), with
    their control points found on a reference first when one is given (kept with the
    products as ``<name>.reference.gcp.csv``)."""

    def acquire(self, stage: Path, state: FlowRun) -> Request:
        from station.reprocess import pass_request

        per = self.scenarios
        request, self._truth = pass_request(
            self.sources,
            stage,
            options=self.options,
            scenario=per if len(per) > 1 else (per[0] if per else None),
            names=self.names,
            gcps=self.gcps,
            ties_dir=self.taken.ties_dir,
            adjustment_dir=self.taken.adjustment_dir,
            references=(self._reference(),) if self.reference is not None else (),
        )
        return request

    def _reference(self) -> ReferenceInput:
        """The reference ortho-image and the DEM the pass's control points are found on
        (as ``station gcps`` finds them), when the plan makes its GEO."""
        from levels.readers.dem import read_dem
        from levels.reference import ReferenceInput, read_reference
        from station.errors import StationError
        from station.refgcps import reference_sigma_m

        if len(self.sources) != 1 or self.gcps:
            raise StationError(
                "--reference finds one archive's control points: give one, no --gcps"
            )
        if not self.options.dem_path:
            raise StationError("--reference needs the DEM under the pass: give --dem")
        assert self.reference is not None
        ref = read_reference(self.reference, reference_sigma_m(self.reference, None))
        return ReferenceInput(ref, read_dem(self.options.dem_path, self.options.dem_vertical))

    def sections(self, stage: Path, result: Result, state: FlowRun) -> dict[str, object]:
        done = [result.pass_products(n, Step.SCENES) for n in self.names]
        if self.reference is not None and done[0].found is not None:  # kept with them
            from station.refgcps import record_found

            out = stage / f"{self.names[0]}.reference.gcp.csv"
            ref = self.reference
            record_found(self.sources[0], ref, out, done[0].found, _sigma(ref))
        data = [
            archive_data(l0, self.out, products)
            for l0, products in zip(self.sources, done, strict=True)
        ]
        body = data[0] if len(data) == 1 else {"archives": data}
        return {"header": {"names": self.names}, **body}


def _sigma(reference: str | Path) -> float:
    from station.refgcps import reference_sigma_m

    return reference_sigma_m(reference, None)


class ProcessScenario(_Processing):
    """A scenario's pass emulated, downlinked and recorded, then processed
    (``station.reprocess.scenario_request``)."""

    def __init__(self, scn: Scenario) -> None:
        super().__init__([scn.name], scn.inputs(), f"the products of a reprocessing of {scn.name}")
        self.scn = scn
        self.found = Checked()
        self._l0 = Path()

    def check(self, out: Path, full: bool = False) -> None:
        from station.run import check_run

        self.out = out
        self.found = check_run(self.scn, out)

    def acquire(self, stage: Path, state: FlowRun) -> Request:
        from station.reprocess import scenario_request

        request, self._truth, self._l0 = scenario_request(self.scn, stage)
        return request

    def sections(self, stage: Path, result: Result, state: FlowRun) -> dict[str, object]:
        products = result.pass_products(self.scn.name, Step.SCENES)
        return {
            "header": {"names": self.names},
            **archive_data(self.out / self._l0.name, self.out, products),
        }


class ProcessBlock(_Recorded):
    """Several passes to a pair's products (``station.reprocess.block_request``): every
    pass's scene levels in ``<out>/<name>/``, the tie points, the block's level 2 and 3 and
    the pair's DEM in ``ties/``, ``block/`` and ``stereo/``."""

    def acquire(self, stage: Path, state: FlowRun) -> Request:
        from station.reprocess import block_request

        request, self._truth = block_request(
            self.sources,
            stage,
            options=self.options,
            scenarios=self.scenarios or None,
            names=self.names,
            gcps=self.gcps,
            ties_dir=self.taken.ties_dir,
            adjustment_dir=self.taken.adjustment_dir,
        )
        return request

    def sections(self, stage: Path, result: Result, state: FlowRun) -> dict[str, object]:
        from station.run import product_entry

        pairs = zip(self.sources, self.names, strict=True)
        data = [
            archive_data(l0, self.out / n, result.pass_products(n, Step.SCENES)) for l0, n in pairs
        ]
        level2 = [
            archive_data(
                l0, self.out / "block", result.pass_products(n, Step.LEVEL2, Step.OVER_PAIR)
            )
            for l0, n in zip(self.sources, self.names, strict=True)
            if result.of(Step.LEVEL2)
        ]
        made = [
            {**product_entry(p.path, "stereo/"), "quality": p.quality} for p in result.of(Step.PAIR)
        ]
        return {
            "header": {"names": self.names},
            "archives": data,
            "block": level2,
            "ties": result.ties,
            "pairs": made,
        }


class ProcessFrame(_Processing):
    """A SAR frame file to its geocoded products (:class:`levels.frame.FrameOptions`:
    the SAR scenario's when given, with its truth; else the levels asked and the DEM's
    heights)."""

    def __init__(
        self,
        source: Path,
        frame: SarFrame,
        options: FrameOptions,
        *,
        dem: Dem | None = None,
        dem_file: Path | None = None,
        scenario: SarScenario | None = None,
    ) -> None:
        inputs = [source, *([dem_file] if dem_file else [])]
        super().__init__([frame.name], inputs, f"the products of the SAR frame {frame.name}")
        self.source, self.frame, self.options = source, frame, options
        self.dem, self.dem_file, self.scenario = dem, dem_file, scenario
        self.found = Checked()
        self._grid: Any = None

    def check(self, out: Path, full: bool = False) -> None:
        """The frame's grid laid and its memory checked before it is allocated."""
        from levels.sar import frame_grid
        from station.preflight import check_needs, frame_needs

        self.out = out
        o, ann = self.options, self.frame.image().annotation
        self._grid = frame_grid(ann, o.pixel_size_m, o.reference_height_m, o.margin_m)
        cells = self._grid.n_rows * self._grid.n_cols
        needs = frame_needs(cells, ann.shape[0] * ann.shape[1], len(o.levels))
        self.found = Checked(frame=str(self.source), **check_needs(needs, out))

    def acquire(self, stage: Path, state: FlowRun) -> Request:
        from station.run_sar import frame_quality, scenario_provenance

        scn = self.scenario
        measure = frame_quality(scn, self.frame) if scn is not None else None
        self._truth = StationTruth({}, frame=measure)
        return Request(
            ProcessingOptions(),
            stage,
            frames=(Frame(self.frame, self._grid),),  # laid once: its memory was checked
            frame_options=self.options,
            dem=self.dem,
            dem_source=self.dem_file.name if self.dem_file else "",
            provenance=scenario_provenance(scn) if scn is not None else {},
        )

    def sections(self, stage: Path, result: Result, state: FlowRun) -> dict[str, object]:
        from levels.products import read_product

        rows = []
        for m in result.of(Step.FRAME):
            attrs = read_product(m.path, images=False).attrs
            rows.append(
                {
                    "level": m.kind,
                    "file": m.path.name,
                    "n_rows": int(attrs["n_rows"]),
                    "n_cols": int(attrs["n_cols"]),
                    "valid": round(float(m.quality["valid_fraction"]), 6),
                    "quality": m.quality,
                }
            )
        return {
            "header": {"names": self.names},
            "frame": str(self.source),
            "out": str(self.out),
            "products": rows,
        }


def check_archives(
    sources: Sequence[Path],
    options: ProcessingOptions,
    out: Path,
    gcps: Sequence[str | Path] | None = None,
    full: bool = False,
    workers: int = 0,
    taken: Taken = Taken(),
) -> Checked:
    """What reprocessing ``sources`` into ``out`` needs, before any work: the archives
    readable (their headers) and the memory and disk their scenes take
    (``station.preflight``); ``full`` (``--check``): also their control points when level 2
    is asked and the DEM when a level needs one (a reprocessing reads those itself before
    its first scene: read here too, they would be read twice), unless level 2's adjustment
    is ``taken`` from a directory."""
    from levels.makers.base import Need
    from levels.process import nominal_pixel_size_m, pass_dem, plan_levels
    from levels.readers.formats import open_archive
    from levels.readers.gcp import read_gcps
    from station.preflight import check_needs, scene_needs
    from station.reprocess import gcps_beside, run_dem

    archives = [open_archive(s) for s in sources]
    makers = plan_levels(options.levels)
    if full and taken.adjustment_dir is None and any(Need.ADJUSTMENT in m.needs for m in makers):
        where = gcps or [gcps_beside(s) for s in sources]
        for w, a in zip(where, archives, strict=True):
            read_gcps(w, a.n_lines, a.n_columns)
    if full:
        if not options.dem_path and any(Need.DEM in m.needs for m in makers):
            dem_path = str(run_dem(sources[0], archives[0]))
            options = dataclasses.replace(options, dem_path=dem_path)
        pass_dem(options, makers)
    a = archives[0]
    lines = min(options.scene_lines or a.n_columns, a.n_lines)
    n_scenes = sum(-(-x.n_lines // lines) for x in archives)
    native_m = nominal_pixel_size_m(next(iter(a.bands.values())).look)
    needs = scene_needs(
        lines,
        a.n_columns,
        len(a.bands),
        len(makers),
        n_scenes,
        workers,
        native_m,
        options.pixel_size_m,
    )
    return Checked(archives=[str(s) for s in sources], **check_needs(needs, out))


def archive_data(l0: Path, out: Path, products: PassProducts) -> dict[str, object]:
    """What ``process.json`` says of one archive's products (its size and valid share, as
    a run says them; its figures; its timings) and the scenes it skipped."""
    from station.run import product_entry

    rows = []
    for s in products.scenes:
        for lv in s.paths:
            entry = product_entry(s.paths[lv])
            rows.append(
                {
                    "scene": s.index,
                    "level": lv,
                    "path": str(out / s.paths[lv].name),
                    **{k: entry[k] for k in ("n_rows", "n_cols", "valid")},
                    **s.quality[lv],
                    "timings_s": s.timings_s,
                }
            )
    return {
        "l0": str(l0),
        "out": str(out),
        "tail_lines": products.tail_lines,
        "timings_s": products.timings_s,
        "products": rows,
        "skipped": [dataclasses.asdict(k) for k in products.skipped],
    }


def command_options(
    base: ProcessingOptions | None = None,
    *,
    options_file: str | Path | None = None,
    levels: str | None = None,
    adjustment: str | None = None,
    dem: str | Path | None = None,
) -> ProcessingOptions:
    """The options a command's arguments ask for, over ``base`` (the library's defaults):
    ``options_file``'s ``[processing]`` table (a scenario file will do; its DEM relative to
    it), ``levels`` (comma-separated, each known, none twice), level 2's ``adjustment``,
    level 3's ``dem``."""
    from levels.choices import AdjustmentScope
    from levels.registry import level_names
    from station.errors import ScenarioError
    from station.scenario import read_toml

    opts = base or ProcessingOptions()
    if options_file:
        table, _ = read_toml(options_file, "options")
        opts = ProcessingOptions.from_table(table.get("processing", {}), error=ScenarioError)
        if opts.dem_path and not Path(opts.dem_path).is_absolute():  # relative to the file
            opts = dataclasses.replace(
                opts, dem_path=str(Path(options_file).parent / opts.dem_path)
            )
    if levels:
        wanted = [lv.strip() for lv in levels.split(",") if lv.strip()]
        known = level_names()
        bad = [lv for lv in wanted if lv not in known] or ([] if wanted else [levels])
        if bad or len(set(wanted)) != len(wanted):
            raise ScenarioError(
                f"--levels {levels}: expected a comma-separated list, "
                f"without repeats, of {', '.join(known)}"
            )
        opts = dataclasses.replace(opts, levels=tuple(wanted))
    if adjustment:
        opts = dataclasses.replace(opts, adjustment=AdjustmentScope(adjustment))
    if dem:  # a pass's level 3 (a SAR frame's GTC reads it apart)
        opts = dataclasses.replace(opts, dem_path=str(dem))
    return opts


def options_of(args: argparse.Namespace, base: ProcessingOptions | None) -> ProcessingOptions:
    """:func:`command_options` of a command's ``--options``, ``--levels``, ``--adjustment``
    and ``--dem`` (those it has)."""
    return command_options(
        base,
        options_file=args.options,
        levels=args.levels,
        adjustment=getattr(args, "adjustment", None),
        dem=getattr(args, "dem", None),
    )


def recorded_cut(sources: Sequence[Path]) -> ProcessingOptions:
    """The processing options by default: the scenes cut as the station that recorded the
    archives cut them (``L0Archive.scene_cut``), so that a reprocessing makes the run's
    scenes; the library's default for archives that do not say, or say differently."""
    from levels.readers.formats import open_archive

    cuts = [open_archive(s).scene_cut for s in sources]
    if not cuts or not cuts[0] or any(c != cuts[0] for c in cuts):
        return ProcessingOptions()
    cut = cuts[0]
    return ProcessingOptions(
        scene_lines=cut.get("scene_lines", 0), overlap_lines=cut.get("overlap_lines", 0)
    )


def is_frame(path: Path) -> bool:
    """Whether ``path`` is a SAR frame (``levels.readers.formats``)."""
    from levels.readers.formats import is_frame_file

    return is_frame_file(path)


def archives_flow(
    sources: Sequence[Path],
    names: Sequence[str],
    options: ProcessingOptions,
    inputs: Sequence[Path],
    *,
    scenarios: Sequence[Scenario] = (),
    gcps: Sequence[str | Path] | None = None,
    taken: Taken = Taken(),
    reference: str | Path | None = None,
    workers: int = 0,
) -> ProcessFlow:
    """Recorded archives' flow: several passes asking for a pair's kinds are a block
    (:class:`ProcessBlock`), any other set of archives is processed together
    (:class:`ProcessArchives`)."""
    from levels.process import pair_kinds_of

    block = len(sources) > 1 and bool(pair_kinds_of(options))
    if block and reference is not None:
        from station.errors import StationError

        raise StationError(
            "--reference finds one pass's control points: a pair's passes give theirs"
        )
    flow = ProcessBlock if block else ProcessArchives
    return flow(
        sources,
        names,
        options,
        inputs,
        scenarios=scenarios,
        gcps=gcps,
        taken=taken,
        reference=reference,
        workers=workers,
    )


def frame_flow(
    source: Path,
    *,
    scenario: str | Path | None = None,
    dem: str | Path | None = None,
    levels: str | None = None,
) -> ProcessFrame:
    """A SAR frame file's flow: its levels, pixel and reference height from ``scenario``
    (the SAR scenario that made it: its products measured against the truth, and the
    run's), else ``levels`` (comma-separated) and the DEM's heights."""
    import numpy as np

    from levels.frame import FrameOptions, margin_of_dem
    from levels.readers.dem import read_dem
    from levels.readers.formats import open_frame
    from station.loader import load_sar
    from station.run_sar import frame_options

    frame = open_frame(source)
    scn = load_sar(scenario) if scenario else None
    grid_dem = read_dem(dem, "ellipsoid") if dem else None
    asked = tuple(lv.strip() for lv in levels.split(",")) if levels else None
    if scn is not None:
        options = frame_options(scn)
        options = dataclasses.replace(options, levels=asked or options.levels)
    else:
        ref = float(np.nanmedian(grid_dem.height_m)) if grid_dem is not None else 0.0
        options = FrameOptions(
            levels=asked or _frame_kinds(grid_dem is not None),
            reference_height_m=ref,
            margin_m=margin_of_dem(grid_dem, ref) if grid_dem is not None else 0.0,
        )
    dem_file = Path(dem) if dem else None
    return ProcessFrame(source, frame, options, dem=grid_dem, dem_file=dem_file, scenario=scn)


def _frame_kinds(with_dem: bool) -> tuple[str, ...]:
    """A SAR frame's kinds, those that need a DEM only ``with_dem``: the others said, not
    skipped in silence."""
    from levels.kinds import Unit
    from levels.registry import kind, kind_names

    kinds = [(n, "dem" in kind(n).needs) for n in kind_names(Unit.FRAME)]
    skipped = [n for n, needs_dem in kinds if needs_dem and not with_dem]
    if skipped:
        _log.warning(
            "%s not made: %s a DEM (give --dem DEM.tif)",
            ", ".join(skipped),
            "it needs" if len(skipped) == 1 else "they need",
        )
    return tuple(n for n, needs_dem in kinds if with_dem or not needs_dem)
