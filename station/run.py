"""End-to-end scenario runs: ``station run``.

One call takes a scenario through the whole ground segment and says how good each product
is: the spacecraft emulator images the pass, the sender and the channel carry it, the
receiving station decodes and records the L0 archive, the processing centre runs GEO once
and COR per scene and level, and every product is measured against the truth. The run
directory then holds the L0 archive, the products, a quicklook PNG per product and
``report.json``::

    <out>/<name>.l0.h5
    <out>/<name>.gcp.csv
    <out>/<name>.dem.tif          (with [dem]: the DEM the station is handed for level 3)
    <out>/<name>_s<scene>_<level>.nc    (2A, 2, 3; 1A and 1B: .h5, with .h5.aux.xml)
    <out>/quicklooks/<name>_s<scene>_<level>.png
    <out>/report.json

A pass imaged by both HRVs goes through one channel, L0 archive and GEO/COR chain per HRV,
and its files carry the HRV (``<name>_hrv2.l0.h5``, ``<name>_hrv2_s<scene>_<level>.h5``).
``report.json`` (format ``spot-station-run`` v2, ``docs/compare.md``) holds the scenario and
its hash, per HRV the decoding statistics of its downlink and what was made and skipped, per
product its size and headline quality figures, and the timings of every stage. Everything
in it except ``timings_s`` and the sizes in MB is a function of the scenario alone: reruns
with the same scenario and seed give identical products and the same report
(``comparable_report``).
"""

from __future__ import annotations

import dataclasses
import json
import logging
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypedDict

from levels.files import json_default
from levels.products import read_product
from levels.tasks import Runner
from levels.threads import in_threads
from levels.work import Made, Measure, Pass, Request, Result, Step
from station.catalog import CATALOG_FILE
from station.flow import FlowRun, ScenarioRun, make_flow, run_flow
from station.loader import BlockScenario
from station.outdir import replaceable_dir
from station.reports import BLOCK_RUN, PASS_RUN, scenario_entry
from station.scenario import Scenario
from station.tables import product_table
from station.truth.measure import StationTruth

if TYPE_CHECKING:
    from levels.adjust import Adjustment
    from levels.process import PassProducts
    from levels.readers.gcp import ControlPointSet
    from levels.reference import ReferenceInput
    from station.preflight import Checked
    from station.spacecraft.emulator import Acquisition

__all__ = [
    "check_run",
    "comparable_report",
    "prepare_run_dir",
    "run_scenario",
    "summary_table",
]

_log = logging.getLogger(__name__)

#: Report keys that vary from one run to the next (wall times, sizes on disk).
_VARYING = ("timings_s", "size_mb", "receive_speed_x_real_time")


def run_scenario(
    scn: Scenario,
    out_dir: str | Path,
    *,
    quicklooks: bool = True,
    progress: bool = False,
    runner: Runner | None = None,
    warm_up: bool = False,
) -> dict[str, Any]:
    """Run ``scn`` end to end into ``out_dir``; returns the report (also in report.json).

    ``progress`` shows progress bars on stderr (stages, then scenes). The scenes are tasks
    of ``runner`` (:mod:`levels.tasks`; in this process by default). ``warm_up``: if the
    processing kernels are not compiled yet, compile them in a background process while
    the pass is emulated and received (:mod:`levels.warmup`; what ``station run`` does).

    The run is built in a staging directory beside ``out_dir`` and replaces it whole only
    when complete (:func:`station.flow.run_flow`): a failure leaves the previous run as it
    was.
    """
    flow = PassRun(scn, warm_up)
    return run_flow(flow, out_dir, quicklooks=quicklooks, progress=progress, runner=runner)


class PassRun(ScenarioRun):
    """The flow of ``station run`` of a pass (:class:`station.flow.Flow`): the pass
    emulated and received, GEO and COR, the products' rows, the report."""

    report = PASS_RUN

    def __init__(self, scn: Scenario, warm_up: bool = False) -> None:
        super().__init__(scn)
        self.scn, self.warm_up = scn, warm_up
        self._received: list[_Received] = []
        self._acqs: list[Any] = []
        self._truth: StationTruth | None = None
        self._bar: Any = None

    def check(self, out: Path) -> None:
        check_run(self.scn, out)

    def catalog(self) -> tuple[str, str]:
        name = self.scn.name
        return name, f"the products of a run of scenario {name} (spot-station)"

    def measure(self) -> Measure:
        assert self._truth is not None  # acquired first
        return self._truth

    def acquire(self, stage: Path, state: FlowRun) -> Request:
        """The pass emulated, its DEM exported, each HRV's channel and L0 archive."""
        from tqdm import tqdm

        scn = self.scn
        self._bar = tqdm(
            total=1 + 3 * len(scn.instruments) + state.quicklooks,
            desc="emulate",
            unit="stage",
            disable=not state.progress,
            leave=False,
        )
        acqs, received, tags, options = _emulate_and_receive(
            scn, stage, self.warm_up, state.timings, self._bar
        )
        self._acqs, self._received = list(acqs), received
        self._truth = StationTruth({t: r.truth for t, r in zip(tags, received, strict=True)})
        self._bar.set_description("GEO and COR")
        scenes = tqdm(desc="scenes", unit="scene", disable=not state.progress, leave=False)

        def on_scene(_done: Any, total: int) -> None:
            scenes.total = total
            scenes.update()

        state.on_scene = on_scene
        archives = tuple(r.archive for r in received)
        gcps = tuple(r.gcps for r in received)
        found_on = tuple(r.reference for r in received)
        one = Pass(archives, tuple(tags), gcps, references=found_on)
        return Request(options, stage, (one,), provenance=scn.provenance())

    def sections(self, stage: Path, result: Result, state: FlowRun) -> dict[str, object]:
        timings, scn = state.timings, self.scn
        self._bar.update(2)
        passes = [d for d in result.passes if d.step is Step.SCENES]
        cor = timings.setdefault("cor", {})
        for done in passes:
            timings["geo"] = timings.get("geo", 0.0) + done.products.timings_s["geo"]
            for s in done.products.scenes:
                for k, v in s.timings_s.items():
                    cor[k] = cor.get(k, 0.0) + v
        hrv_of = {d.name: a.hrv.number for d, a in zip(passes, self._acqs, strict=True)}
        hrvs = [
            _section(a, r, d.products, _found_record(r, d.products))
            for a, r, d in zip(self._acqs, self._received, passes, strict=True)
        ]
        rows = in_threads(
            lambda m: _product_row(hrv_of[m.key], m, state.drawn.get(m.path), stage),
            result.of(Step.SCENES),
        )
        self._bar.close()
        return {
            "header": {"scenario": scenario_entry(scn)},
            "hrvs": hrvs,
            **(
                {"dem": {"file": f"{scn.name}.dem.tif", **asdict(scn.dem)}}
                if scn.dem is not None
                else {}
            ),
            "products": rows,
            "catalog": CATALOG_FILE,
            "timings_s": _rounded(timings),
        }


def _emulate_and_receive(
    scn: Scenario, out: Path, warm_up: bool, timings: dict[str, object], stages: Any
) -> tuple[Any, list[_Received], list[str], Any]:
    """The pass emulated, its DEM exported, each HRV's channel and L0 archive, while the
    kernels compile in the background (``warm_up``): the acquisitions, what was received,
    each HRV's tag and the processing options; adds the wall times to ``timings``."""
    from levels.warmup import start_warm_up, stop_warm_up, wait_for_warm_up
    from station.reprocess import with_exported_dem
    from station.spacecraft.emulator import emulate_pass

    clock = time.perf_counter
    warming = start_warm_up() if warm_up else None
    n_hrv = len(scn.instruments)
    try:  # a failed or interrupted run ends the warm-up it started
        t = clock()
        _log.info("emulating %s: %d HRV(s)", scn.name, n_hrv)
        acqs = emulate_pass(scn)
        timings["emulate"] = clock() - t
        _log.info("emulated in %.1f s", timings["emulate"])
        stages.update()
        t = clock()
        options = with_exported_dem(scn, acqs, out)
        if scn.dem is not None:
            timings["dem_export"] = clock() - t
        if scn.reference is not None:  # the ortho-image control points are found on
            from station.spacecraft.reference import export_reference

            t = clock()
            export_reference(scn, acqs, out)
            timings["reference_export"] = clock() - t
        tags = [scn.name if n_hrv == 1 else f"{scn.name}_hrv{a.hrv.number}" for a in acqs]
        received = [
            _receive(a, out, tag, timings, stages) for a, tag in zip(acqs, tags, strict=True)
        ]
        t = clock()
        wait_for_warm_up(warming)  # its kernels are cached: the processing loads them
        if warming is not None:
            timings["warm_up_wait"] = clock() - t
    except BaseException:
        stop_warm_up(warming)
        raise
    return acqs, received, tags, options


def _product_row(hrv: int, m: Made, quicklook: Path | None, out: Path) -> dict[str, object]:
    """What a run's report says of one product (and its quicklook, when drawn)."""
    p = read_product(m.path, images=False)
    assert m.scene is not None  # a scene's level
    index, first_line, n_lines = m.scene
    row: dict[str, object] = {
        "hrv": hrv,
        "scene": index,
        "level": m.kind,
        "first_line": first_line,
        "n_lines": n_lines,
        "file": m.path.name,
        "n_rows": p.attrs["n_rows"],
        "n_cols": p.attrs["n_cols"],
        "bands": list(p.bands),
        "valid_fraction": {b: round(float(im.valid.mean()), 6) for b, im in p.bands.items()},
        "size_mb": round(m.path.stat().st_size / 1e6, 3),
        "quality": dict(m.quality),
    }
    if quicklook is not None:
        row["quicklook"] = str(quicklook.relative_to(out))
    return row


def prepare_run_dir(out_dir: str | Path, name: str, inputs: list[Path] | None = None) -> Path:
    """The run directory, checked before any work: absent, empty or an earlier run of this
    scenario (its ``report.json`` names it), since the run replaces it whole
    (:mod:`station.outdir`); another scenario's run or other files there are refused."""
    return replaceable_dir(
        out_dir,
        PASS_RUN.file,
        PASS_RUN.owner_in,
        name,
        lambda n: f"a run of scenario {n!r}",
        inputs or [],
    )


def check_run(scn: Scenario, out: Path) -> Checked:
    """Everything the run of ``scn`` into ``out`` needs, checked before any work
    (:mod:`station.preflight`): the files the scenario names, a DEM for the levels that
    need one, a writable place for ``out``, and the memory and disk the run will take.
    Returns what was checked; :class:`StationError` (or the library's error) on the
    first failure."""
    from station.preflight import Checked, check_needs, check_scenario, run_needs

    files = check_scenario(scn)
    needs = run_needs(scn)
    return Checked(files=files, pixels=needs.pixels, **check_needs(needs, out))


@dataclass(frozen=True, eq=False)
class _Received:
    """One HRV's chain from the emulator to the processing centre's door: its L0 archive,
    the decoder's report, the truth behind it and its control points as measured."""

    l0: Path
    archive: Any
    decode: dict[str, object]
    truth: Any
    gcps: Any
    gcps_path: Path
    #: With ``[gcps] source = "reference"``: the reference and DEM they are found on,
    #: and the reference's file.
    reference: ReferenceInput | None = None
    reference_file: Path | None = None


def _receive(
    acq: Acquisition, out: Path, tag: str, timings: dict[str, Any], stages: Any
) -> _Received:
    """One HRV's channel, its L0 archive and its control-point file; adds the wall times
    to ``timings``."""
    from levels.readers.l0 import read_l0
    from station.chain.gcps import measured_control_points
    from station.chain.report import downlink_report
    from station.chain.session import downlink, record

    clock = time.perf_counter
    stages.set_description(f"downlink HRV{acq.hrv.number}")
    _log.info("HRV%d: downlink through the channel, then the receiver", acq.hrv.number)
    result = downlink(acq)
    for k, v in result.timings_s.items():
        timings[k] = timings.get(k, 0.0) + v
    t = clock()
    l0 = record(acq, result, out / f"{tag}.l0.h5")
    timings["record"] = timings.get("record", 0.0) + clock() - t
    decode = downlink_report(acq, result)
    _log.info("HRV%d: L0 archive %s recorded", acq.hrv.number, l0.name)
    stages.update()
    archive = read_l0(l0, lazy=True)  # each scene task reads its own rows
    gcps_path = out / f"{tag}.gcp.csv"
    truth, drawn = measured_control_points(acq, archive, gcps_path)
    scn, reference, path = acq.scenario, None, None
    gcps: ControlPointSet | None = drawn
    if scn.gcps.source == "reference":  # found on the run's reference when planned
        from levels.readers.dem import read_dem
        from levels.reference import ReferenceInput, read_reference
        from station.refgcps import reference_sigma_m
        from station.spacecraft.reference import reference_path

        path = reference_path(scn, out)
        ref = read_reference(path, reference_sigma_m(path, None))
        dem = read_dem(out / f"{scn.name}.dem.tif", scn.processing.dem_vertical)
        reference, gcps = ReferenceInput(ref, dem), None  # the drawn points not used
    return _Received(l0, archive, decode, truth, gcps, gcps_path, reference, path)


def _found_record(rec: _Received, products: PassProducts) -> dict[str, Any] | None:
    """The control points found on the run's reference, written beside the archive as the
    run's record (``<tag>.gcp.csv``) and scored against the truth; None when none were."""
    from station.refgcps import record_found

    if products.found is None or rec.reference is None or rec.reference_file is None:
        return None
    sigma = rec.reference.reference.sigma_m
    return record_found(rec.l0, rec.reference_file, rec.gcps_path, products.found, sigma, rec.truth)


def _section(
    acq: Acquisition, rec: _Received, products: PassProducts, found: dict[str, Any] | None
) -> dict[str, Any]:
    """One HRV's section of the run report."""
    scn, decode, archive, l0 = acq.scenario, rec.decode, rec.archive, rec.l0
    gcps_path = rec.gcps_path
    section = {
        "hrv": decode["hrv"],
        "mode": decode["mode"],
        "mirror_step": acq.hrv.mirror_step,
        "lines": decode["lines"],
        "detectors": decode["detectors"],
        "decode": {
            k: v
            for k, v in decode.items()
            if k not in ("scenario", "hrv", "mode", "lines", "detectors", "timings_s")
        },
        "l0": {
            "file": l0.name,
            "size_mb": round(l0.stat().st_size / 1e6, 3),
            "rows": archive.n_lines,
        },
        "gcps": {
            "file": gcps_path.name,
            "points": int(acq.gcps.line.size) if found is None else found["points"],
            **({"found": _found(found)} if found is not None else {}),
        },
        **({"adjustment": _adjustment(products.adjustment, acq)} if products.adjustment else {}),
        "processing": {
            "levels": list(scn.processing.levels),
            "scenes": len(products.scenes),
            "tail_lines": products.tail_lines,
            "skipped": [
                {
                    "scene": k.index,
                    "first_line": k.first_line,
                    "n_lines": k.n_lines,
                    "reason": k.reason,
                }
                for k in products.skipped
            ],
        },
    }
    return section


def _found(summary: dict[str, Any]) -> dict[str, Any]:
    """Control points found on a reference, in the report: the reference, its stated σ,
    each loop's mean shift and the points against the truth (``station.refgcps``)."""
    return {
        "reference": Path(summary["reference"]).name,
        "reference_sigma_m": summary["reference_sigma_m"],
        "loops_mean_shift_px": [loop["mean_shift_px"] for loop in summary["loops"]],
        "truth": summary.get("truth", {}),
    }


def _found_line(gcps: dict[str, Any]) -> str:
    f, t = gcps["found"], gcps["found"].get("truth", {})
    line = (
        f"control points: {gcps['points']} found on {f['reference']} "
        f"(σ {f['reference_sigma_m']:.1f} m stated; loops' mean shift "
        + " → ".join(f"{s:.2f}" for s in f["loops_mean_shift_px"])
        + " px)"
    )
    if t:
        line += f"; against the truth {t['rms_m']:.2f} m RMS"
    if "rms_of_matching_m" in t:
        line += f", {t['rms_of_matching_m']:.2f} m without the reference's own bias"
    return line


def _adjustment(adjustment: Adjustment, acq: Acquisition) -> dict[str, object]:
    """Level 2's adjustment in the report: its summary, and the blunders the emulator
    planted (``[gcps] blunder_fraction``) beside those it rejected."""
    import numpy as np

    rejected = np.array(adjustment.point_status) == "rejected"
    if acq.scenario.gcps.source == "reference":  # found on the reference: none planted
        return {**adjustment.summary(), "source": "reference"}
    planted = acq.gcps.blunder
    return {
        **adjustment.summary(),
        "blunders": {
            "planted": int(planted.sum()),
            "rejected": int(np.sum(planted & rejected)),
            "false_rejections": int(np.sum(~planted & rejected)),
        },
    }


def _rounded(x: Any) -> Any:
    if isinstance(x, dict):
        return {k: _rounded(v) for k, v in x.items()}
    return round(float(x), 4)


def comparable_report(report: dict[str, object]) -> dict[str, object]:
    """The report without what varies between identical runs (wall times, file sizes)."""

    def strip(x: Any) -> Any:
        if isinstance(x, dict):
            return {k: strip(v) for k, v in x.items() if k not in _VARYING}
        if isinstance(x, list):
            return [strip(v) for v in x]
        return x

    return strip(json.loads(json.dumps(report, default=json_default)))


def _downlink_line(dec: dict[str, Any]) -> str:
    """One HRV's decoding in a line: frames, errors, lines, and the check against the truth."""
    link, cadus, tc = dec["link"], dec["cadus"], dec["truth_check"]
    failed = [
        k for k in ("masks_match_lost_frames", "accounts_balance", "sent_as_counted") if not tc[k]
    ]
    tails_lost = [n for n, c in dec["channels"].items() if not c["tail_known"]]
    if failed == ["sent_as_counted"] and tails_lost:
        # the receiver cannot count frames sent after the last one it heard: it says so
        verdict = f"passed (frames sent after the pass's end unknown on {', '.join(tails_lost)})"
    else:
        verdict = "passed" if not failed else "FAILED: " + ", ".join(failed)
    return (
        f"  downlink: {link['cadus_sent']} CADUs, {link['bit_errors']} bit errors, "
        f"{cadus['corrected']} corrected, {cadus['uncorrectable']} uncorrectable; lines "
        + ", ".join(
            f"{b['name']} {b['lines_complete']}/{b['lines_partial']}/{b['lines_missing']}"
            for b in dec["bands"]
        )
        + f" (complete/partial/missing); truth check {verdict}"
    )


class ProductEntry(TypedDict):
    """What a run's report says of a product beside its quality."""

    level: str
    file: str
    n_rows: int
    n_cols: int
    valid: float


def product_entry(path: Path, where: str = "") -> ProductEntry:
    """What a run's report says of a product beside its quality: its kind, its file (under
    ``where`` in the run directory), its size in pixels and its first band's valid share."""
    p = read_product(path, images=False)
    first = next(iter(p.bands.values()))
    return ProductEntry(
        level=p.level,
        file=f"{where}{path.name}",
        n_rows=int(p.attrs["n_rows"]),
        n_cols=int(p.attrs["n_cols"]),
        valid=round(float(first.valid.mean()), 6),
    )


def table_row(r: dict[str, Any]) -> dict[str, Any]:
    """A product of a run's report as a row of :func:`station.tables.product_table`."""
    band = r["bands"][0] if r.get("bands") else None
    return {"valid": r.get("valid_fraction", {}).get(band), **r}


def summary_table(report: dict[str, Any], out_dir: str | Path | None = None) -> str:
    """The short human summary printed at the end of a run."""
    name, several = report["scenario"]["name"], len(report["hrvs"]) > 1
    lines = []
    for h in report["hrvs"]:
        lines.append(
            f"{name}: HRV{h['hrv']} {h['mode']}, mirror step {h['mirror_step']}, "
            f"{h['lines']} lines × {h['detectors']} detectors → "
            f"{h['processing']['scenes']} scene(s)"
        )
        lines.append(_downlink_line(h["decode"]))
        if "found" in h["gcps"]:
            lines.append(_found_line(h["gcps"]))
    lead = [("hrv", "HRV"), ("scene", "scene")] if several else [("scene", "scene")]
    lines += product_table([table_row(r) for r in report["products"]], lead)
    for h in report["hrvs"]:
        for k in h["processing"]["skipped"]:
            hrv = f"{h['hrv']:5d} " if several else ""
            lines.append(f"{hrv}{k['scene']:5d}  skipped: {k['reason']}")
    t = report["timings_s"]
    cor = sum(t.get("cor", {}).values())
    parts = [
        f"emulate {t['emulate']:.1f}",
        f"downlink {t.get('transmit', 0) + t.get('channel', 0) + t.get('receive', 0):.1f}",
        f"record {t['record']:.1f}",
        *(
            [f"waiting for the kernels' compilation {t['warm_up_wait']:.1f}"]
            if "warm_up_wait" in t
            else []
        ),
        f"GEO {t['geo']:.2f}",
        f"COR {cor:.1f}",
    ]
    if "quicklooks" in t:
        parts.append(f"quicklooks {t['quicklooks']:.1f}")
    lines.append("timings (s): " + ", ".join(parts) + f"; total {t['total']:.1f}")
    if out_dir is not None:
        n_ql = sum("quicklook" in r for r in report["products"])
        l0 = ", ".join(h["l0"]["file"] for h in report["hrvs"])
        lines.append(
            f"in {out_dir}/: report.json, catalog.json, {l0}, "
            f"{len(report['products'])} products, {n_ql} quicklooks"
        )
    return "\n".join(lines)


def run_block(
    blk: BlockScenario,
    out_dir: str | Path,
    *,
    quicklooks: bool = True,
    progress: bool = False,
    runner: Runner | None = None,
) -> dict[str, Any]:
    """Run a block (``[[passes]]``, :func:`station.loader.load_block`) end to end into ``out_dir``:
    each pass as ``station run`` runs one (``<out>/<pass>/``); the tie points between every
    two passes whose 2A scenes overlap (:mod:`levels.tiepoints`, ``<out>/ties/``); then, with
    level 2 asked and ``adjustment = "block"``, every pass's level 2 on one adjustment
    (``<out>/block/``, checkpoints against each pass's truth), the pair's DEM and level 3
    over it. Published whole, as a run."""
    flow = BlockRun(blk)
    return run_flow(flow, out_dir, quicklooks=quicklooks, progress=progress, runner=runner)


class BlockRun(ScenarioRun):
    """The flow of ``station run`` of a block (:class:`station.flow.Flow`): each pass's
    flow in its own directory, then the block's request (:mod:`levels.work`) on them."""

    report = BLOCK_RUN

    def __init__(self, blk: BlockScenario) -> None:
        super().__init__(blk)
        self.blk = blk
        self._reports: list[dict[str, Any]] = []
        self._truth: StationTruth | None = None

    def check(self, out: Path) -> None:
        for s in self.blk.passes:
            check_run(s, out)

    def catalog(self) -> tuple[str, str]:
        name = self.blk.name
        return name, f"the products of a block run of {name} (spot-station)"

    def measure(self) -> Measure:
        assert self._truth is not None  # acquired first
        return self._truth

    def acquire(self, stage: Path, state: FlowRun) -> Request:
        """Each pass run as a pass's flow in ``<stage>/<pass>/``, the first pass's control
        points shared; the block's request on their archives."""
        from station.reprocess import block_request

        name, scns, processing = self.blk.name, list(self.blk.passes), self.blk.processing
        for k, s in enumerate(scns, start=1):
            _log.info("block %s: pass %d of %d, %s", name, k, len(scns), s.name)
            (stage / s.name).mkdir()
            mine = FlowRun(state.quicklooks, state.progress, state.runner)
            self._reports.append(make_flow(PassRun(s), stage / s.name, mine))
        if scns[0].gcps.shared:
            _share_control_points(stage, scns)
        opts = processing
        if processing.adjustment != "block":  # each pass's own adjustment: the ties alone
            opts = dataclasses.replace(opts, levels=("2A",), stereo=False)
        _log.info("block %s: tie points, level 2 and the pair's products", name)
        request, self._truth = block_request(
            [stage / s.name / f"{s.name}.l0.h5" for s in scns],
            stage,
            options=opts,
            scenarios=scns,
            names=[s.name for s in scns],
            gcps=[stage / s.name / f"{s.name}.gcp.csv" for s in scns],
            made_in=[stage / s.name for s in scns],
        )
        return request

    def sections(self, stage: Path, result: Result, state: FlowRun) -> dict[str, Any]:
        scns = list(self.blk.passes)
        block, stereo = {}, {}
        if result.of(Step.LEVEL2):
            block = {
                "products": [
                    {
                        "pass": s.name,
                        "scene": sc.index,
                        **product_entry(stage / "block" / p.name, "block/"),
                        "quality": sc.quality[level],
                    }
                    for s in scns
                    for sc in result.pass_products(s.name, Step.LEVEL2, Step.OVER_PAIR).scenes
                    for level, p in sc.paths.items()
                ],
            }
        if self.blk.processing.stereo:
            stereo = {
                "dems": [
                    {
                        **product_entry(p.path, "stereo/"),
                        "geotiff": p.export.name if p.export else None,
                        "quality": p.quality,
                        "timings_s": {k: round(v, 4) for k, v in p.timings_s.items()},
                    }
                    for p in result.of(Step.PAIR)
                ]
            }
        header = {
            "name": self.blk.name,
            "file": Path(self.blk.source).name,
            "passes": [s.name for s in scns],
        }
        return {
            "header": {"scenario": header},
            "passes": self._reports,
            "ties": result.ties,
            "block": block,
            **({"stereo": stereo} if stereo else {}),
            "timings_s": {"total": round(state.timings["total"], 3)},
        }


def _share_control_points(stage: Path, scns: list[Scenario]) -> None:
    """``[gcps] shared``: the first pass's control points measured in every other pass's
    image where it sees them (their true ground, by that pass's true model, with its
    pointing error), added to its ``<pass>.gcp.csv`` under the first pass's ids and map
    positions: the same ground points in every image, as a photogrammetrist's."""
    import numpy as np

    from levels.readers.gcp import ControlPointSet, read_gcps, write_gcps
    from levels.readers.l0 import read_l0
    from station.truth.optical import truth_for

    first = scns[0]
    l0 = read_l0(stage / first.name / f"{first.name}.l0.h5", lazy=True)
    acq = truth_for(first, l0).acq
    g = acq.gcps
    mine = read_gcps(stage / first.name / f"{first.name}.gcp.csv")
    for k, s in enumerate(scns[1:], start=1):
        path = stage / s.name / f"{s.name}.gcp.csv"
        archive = read_l0(stage / s.name / f"{s.name}.l0.h5", lazy=True)
        truth = truth_for(s, archive)
        seen = truth.model(0).ground_to_image(g.true_lat_rad, g.true_lon_rad, g.true_h_m)
        line = seen.line - truth.row_offset
        rng = np.random.default_rng([s.seed, k, 37])
        sigma = s.gcps.pointing_error_px
        line = line + sigma * rng.standard_normal(line.size)
        col = seen.column + sigma * rng.standard_normal(line.size)
        inside = (
            seen.converged
            & (line >= 0)
            & (line <= archive.n_lines - 1)
            & (col >= 0)
            & (col <= archive.n_columns - 1)
        )
        i = np.flatnonzero(inside)
        shared = ControlPointSet(
            tuple(f"{first.name}_{mine.id[j]}" for j in i),
            mine.lon_rad[i],
            mine.lat_rad[i],
            mine.h_m[i],
            line[i],
            col[i],
            mine.sigma_ground_m[i],
            mine.sigma_h_m[i],
            np.full(i.size, max(sigma, 0.01)),
            np.full(i.size, archive.hrv, dtype=np.int64),
        )
        own = read_gcps(path)
        write_gcps(
            path, own + shared, f"control points of {s.name}, {i.size} shared with {first.name}"
        )
