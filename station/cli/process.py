"""``station process``: GEO and COR of a pass into level products, from a recorded L0
archive (``levels`` alone, plus the truth when the scenario is given) or from a scenario
(emulated, received and recorded first)."""

from __future__ import annotations

import argparse
import dataclasses
import logging
from pathlib import Path
from typing import TYPE_CHECKING, Any

from station.cli._options import add_json, add_out, add_runner, emit, exit_made, runner_of
from station.errors import StationError
from station.processing import Taken, frame_flow, is_frame, options_of, recorded_cut
from station.reports import PROCESS

if TYPE_CHECKING:
    from station.cli._options import Subparsers
    from station.processing import ProcessFlow

_log = logging.getLogger(__name__)

__all__ = ["PROCESS_REPORT", "register"]

#: The report ``station process`` writes into its output directory (what it made).
PROCESS_REPORT = PROCESS.file


def register(sub: Subparsers) -> None:
    _add_process(sub)
    _add_campaign(sub)


def _add_process(sub: Subparsers) -> None:
    p = sub.add_parser(
        "process",
        help="make level products of an L0 archive (or of a scenario's pass)",
        description="Run GEO and COR over a pass into one product per scene and level. "
        "SOURCE is an L0 archive (.h5), reprocessed as recorded: with "
        "--scenario (the scenario that made it) the checkpoints are measured "
        "against its truth and the products are those of its run, bit for bit. "
        "SOURCE may also be a scenario (.toml), emulated and received first. Several "
        "archives, one per HRV of one pass, are processed together: with "
        '[processing] adjustment = "twin", level 2 adjusts both HRVs at once. Two passes '
        "over one ground with --levels 2,DEM,3 make the pair's DEM and level 3 over it "
        "(tie points, the block's level 2, the DEM; --scenario BLOCK.toml for the truth). "
        "A SPOT 1–4 level-1A DIMAP scene (SPOT World Heritage's zip, read in place; its "
        "directory; or its METADATA.DIM) is processed as an archive of one scene: "
        "docs/dimap.md. A SAR frame (.frame.h5, or ESA's ENVISAT format: SAR_IMP_1P, "
        "SAR_IMS_1P .E1/.E2) makes GEC and GTC (--dem for GTC).",
    )
    p.add_argument(
        "source",
        nargs="+",
        help="an L0 archive (.h5), both HRVs' archives of one pass, two passes' archives, "
        "a scenario (.toml), a DIMAP 1A scene (.zip, directory or METADATA.DIM), or a SAR "
        "frame (.frame.h5, or ESA's .E1/.E2)",
    )
    p.add_argument(
        "--scenario",
        action="append",
        help="the scenario that made the L0 archive: its "
        "[processing] options and its truth for the checkpoints; once for the archives of "
        "one pass, or once per archive (a block of several passes)",
    )
    p.add_argument(
        "--options",
        help="a TOML file whose [processing] table sets the options "
        "(a scenario file will do); overrides --scenario's",
    )
    p.add_argument(
        "--levels", help="comma-separated levels to make (e.g. 1A,2A); overrides the options'"
    )
    _add_level2_inputs(p)
    p.add_argument(
        "--dem",
        metavar="DEM.tif",
        help="the DEM of level 3 (overrides [processing] dem_path) or of a SAR frame's GTC "
        "(heights above the ellipsoid; a GeoTIFF)",
    )
    p.add_argument("--name", help="product name prefix (default: the archive's or scenario's)")
    p.add_argument(
        "--check",
        action="store_true",
        help="check everything the processing needs (archives, control points, DEM, --out, "
        "memory, disk) and stop: nothing is written",
    )
    add_out(p, "directory of the products (default: <name>_products)")
    add_runner(p)
    add_json(p)
    p.set_defaults(func=_process)


def _add_level2_inputs(p: argparse.ArgumentParser) -> None:
    """What level 2 is made from: its adjustment's scope, the control points (or the
    reference they are found on), and the steps taken from an earlier run."""
    p.add_argument(
        "--adjustment",
        choices=("pass", "scene", "twin", "block"),
        help="level 2's adjustment; overrides the options' (block: every archive its own "
        "pass, tied by the <name>.tie.csv beside each: docs/blocks.md)",
    )
    p.add_argument(
        "--gcps",
        action="append",
        help="control points of the pass for level 2 (docs/gcp.md; default: the "
        "<name>.gcp.csv beside the L0 archive); once per archive, in their order",
    )
    p.add_argument(
        "--ties",
        metavar="DIR",
        help="the directory of the passes' tie files (<name>.tie.csv, station tie): with "
        "--adjustment block, default beside each archive; for a pair, a run's ties/ "
        "taken instead of matching them again",
    )
    p.add_argument(
        "--adjustment-from",
        metavar="DIR",
        help="level 2's adjustment taken from the level 2 products in DIR (a run's or a "
        "reprocessing's; a pair's block/), not solved again: no control point is needed",
    )
    p.add_argument(
        "--reference", metavar="REF.tif", help="level 2's control points found on this "
        "reference ortho-image first (station gcps; --dem), kept with the products",
    )  # fmt: skip


def _add_campaign(sub: Subparsers) -> None:
    c = sub.add_parser(
        "campaign",
        help="reprocess many L0 archives as one campaign, with one report",
        description="Process every L0 archive given (files, directories searched for "
        "*.l0.h5, or .txt lists of paths) into OUT/<archive>/, as station process would, "
        "and write OUT/campaign.json: per archive its products or why it failed. An archive "
        "that fails is named and the others are still processed; the exit code is then 2 "
        "(3 if a bug made it fail).",
    )
    c.add_argument("source", nargs="+", help="L0 archives, directories of them, or .txt lists")
    c.add_argument(
        "--options",
        help="a TOML file whose [processing] table sets the options (a scenario file will do)",
    )
    c.add_argument("--levels", help="comma-separated levels to make; overrides the options'")
    c.add_argument("--out", required=True, help="directory of the campaign's products")
    add_runner(c, "scenes of every archive")
    add_json(c, "the campaign report as JSON instead of the summary")
    c.set_defaults(func=_campaign)


def _process(args: argparse.Namespace) -> int:
    from station.scenario import check_name

    sources = [Path(s) for s in args.source]
    if len(sources) == 1 and is_frame(sources[0]):
        flow = frame_flow(
            sources[0],
            scenario=args.scenario[0] if args.scenario else None,
            dem=args.dem,
            levels=args.levels,
        )
        return _done(args, flow, "frame")
    scenarios, block_options = _scenarios(args, sources)
    if len(scenarios) > 1 and len(scenarios) != len(sources):
        raise StationError(
            f"--scenario given {len(scenarios)} times for {len(sources)} source(s): once for "
            "one pass, or once per archive"
        )
    if args.name:
        check_name(args.name, "--name")
    return _done(args, _pass_flow(args, sources, scenarios, block_options), "pass")


def _pass_flow(
    args: argparse.Namespace, sources: list[Path], scenarios: list[Any], block_options: Any
) -> ProcessFlow:
    """The flow of a scenario's pass, of recorded archives, or of several passes to a
    pair's products (``station.processing``)."""
    from station.processing import ProcessScenario, archives_flow

    if any(s.suffix == ".toml" for s in sources):
        return ProcessScenario(_scenario_source(args, sources, scenarios))
    options, names, inputs = _archive_sources(args, sources, scenarios, block_options)
    return archives_flow(
        sources,
        names,
        options,
        inputs,
        scenarios=scenarios,
        gcps=args.gcps,
        taken=_taken(args),
        reference=getattr(args, "reference", None),
        workers=args.workers or 0,
    )


def _taken(args: argparse.Namespace) -> Taken:
    """The steps ``--ties`` and ``--adjustment-from`` take from directories."""
    ties, adjustment = args.ties, getattr(args, "adjustment_from", None)
    return Taken(Path(ties) if ties else None, Path(adjustment) if adjustment is not None else None)


def _done(args: argparse.Namespace, flow: ProcessFlow, what: str) -> int:
    """``--check``: what the flow needs, checked, nothing written; else the flow run
    (:func:`station.flow.run_flow`) and its report printed."""
    from station.flow import flow_dir, run_flow

    out = Path(args.out) if args.out else Path(f"{flow.names[0]}_products")
    if args.check:
        from station.cli.run import check_text

        flow.check(flow_dir(flow, out), full=True)
        emit(args, flow.found, lambda f: check_text(", ".join(flow.names), f, out))
        return 0
    with runner_of(args) as runner:
        report = run_flow(flow, out, quicklooks=False, runner=runner)
    if what == "frame":
        emit(args, report, _frame_text)
        return exit_made(len(report["products"]), "station process")
    body = {k: v for k, v in report.items() if k not in ("format", "format_version", "software")}
    body.pop("names", None)
    if "pairs" in body:
        emit(args, body, _block_text)
        made = sum(len(d["products"]) for d in body["archives"] + body["block"])
        return exit_made(made + len(body["pairs"]), "station process")
    emit(args, body, _text)
    data = body["archives"] if "archives" in body else [body]
    return exit_made(sum(len(d["products"]) for d in data), "station process")


def _scenario_source(args: argparse.Namespace, sources: list[Path], scenarios: list[Any]) -> Any:
    """A scenario given as the SOURCE (emulated and received first), its options and name
    as the command's arguments set them."""
    from station.loader import load_scenario

    if len(sources) > 1:
        raise StationError("give one scenario (.toml), or L0 archives (.h5), not both")
    if scenarios:
        raise StationError(
            "give --scenario only with an L0 archive; a .toml SOURCE is the scenario"
        )
    if args.gcps:
        raise StationError(
            "give --gcps only with an L0 archive; a scenario draws its own control points"
        )
    scn = load_scenario(sources[0])
    return dataclasses.replace(
        scn, processing=options_of(args, scn.processing), name=args.name or scn.name
    )


def _archive_sources(
    args: argparse.Namespace, sources: list[Path], scenarios: list[Any], block_options: Any
) -> tuple[Any, list[str], list[Path]]:
    """L0 archives as the SOURCE: the options (the scenario's or the block's, then the
    command's), the names of their products and the files they read."""
    from station.reprocess import l0_stem

    if args.name and len(sources) > 1:
        raise StationError("--name names one archive's products; several are named after theirs")
    if args.gcps and len(args.gcps) != len(sources):
        raise StationError(
            f"--gcps given {len(args.gcps)} time(s) for {len(sources)} L0 archive(s): "
            "once per archive, or not at all"
        )
    base = scenarios[0].processing if scenarios else recorded_cut(sources)
    options = options_of(args, block_options or base)
    names = [args.name] if args.name else [l0_stem(s) for s in sources]
    given = [*(args.gcps or []), *([options.dem_path] if options.dem_path else [])]
    return options, names, [*sources, *(Path(g) for g in given)]


def _frame_text(report: dict[str, Any]) -> str:
    from station.tables import product_table

    lines = [f"{len(report['products'])} product(s) of {report['frame']} into {report['out']}/"]
    return "\n".join(lines + product_table(report["products"], []))


def _scenarios(args: argparse.Namespace, sources: list[Path]) -> tuple[list[Any], Any]:
    """The ``--scenario`` files: a pass's scenario per archive (or one for the archives of
    one pass); or a block's (``[[passes]]``), whose passes are matched to the archives by
    name and whose ``[processing]`` is the options' base."""
    from station.loader import BlockScenario, load_any
    from station.reprocess import l0_stem
    from station.scenario import Scenario

    given = args.scenario or []
    loaded = [load_any(s) for s in given]  # each file read once
    blk = loaded[0] if len(loaded) == 1 else None
    if isinstance(blk, BlockScenario):
        scns, processing = list(blk.passes), blk.processing
        by_name = {s.name: s for s in scns}
        stems = [l0_stem(s) for s in sources]
        missing = [n for n in stems if n not in by_name]
        if missing:
            raise StationError(
                f"--scenario {given[0]}: its passes are {', '.join(by_name)}; no pass "
                f"{missing[0]!r} made the archive {sources[stems.index(missing[0])]}"
            )
        return [by_name[n] for n in stems], processing
    for path, scn in zip(given, loaded, strict=True):
        if not isinstance(scn, Scenario):
            what = "a block's" if isinstance(scn, BlockScenario) else "a SAR frame's"
            raise StationError(f"--scenario {path}: {what} scenario, not a pass's")
    return loaded, None


def _block_text(report: dict[str, Any]) -> str:
    from station.tables import product_table

    lines = [_text({"archives": report["archives"]})]
    if report["block"]:
        lines.append("the block's adjustment:")
        lines.append(_text({"archives": report["block"]}))
    if report["pairs"]:
        lines.append("the pair's products:")
        lines += product_table(report["pairs"], [])
    return "\n".join(lines)


def _campaign(args: argparse.Namespace) -> int:
    import sys

    from station.campaign import campaign_archives, run_campaign

    archives = campaign_archives(args.source)
    options = options_of(args, None)
    with runner_of(args) as runner:  # a scheduler that does not answer fails first
        bar = None
        if not args.quiet and not args.json and sys.stderr.isatty():  # not into a log
            from tqdm import tqdm

            bar = tqdm(total=0, unit="scene", file=sys.stderr)

        def progress(done: int, total: int, what: str) -> None:
            if bar is not None:
                bar.total = total
                bar.set_description(what, refresh=False)
                bar.update(done - bar.n)

        try:
            report = run_campaign(archives, args.out, options, progress, runner)
        finally:
            if bar is not None:
                bar.close()
    emit(args, report, _campaign_text)
    failed = [a for a in report["archives"] if a["status"] != "ok"]
    if not failed:
        return exit_made(report["summary"]["products"], "the campaign")
    print(
        f"station: error: {len(failed)} of {len(archives)} archive(s) failed: "
        + "; ".join(f"{a['name']}: {a['reason']}" for a in failed),
        file=sys.stderr,
    )
    return 3 if any(a["kind"] == "internal error" for a in failed) else 2


def _campaign_text(report: dict[str, Any]) -> str:
    s = report["summary"]
    lines = [
        f"campaign of {s['archives']} archive(s): {s['ok']} made {s['products']} product(s), "
        f"{s['failed']} failed; {s['time_s']:.1f} s"
    ]
    for a in report["archives"]:
        what = (
            f"{a['scenes']} scene(s), {len(a['products'])} product(s)"
            if a["status"] == "ok"
            else f"FAILED ({a['kind']}): {a['reason']}"
        )
        lines.append(f"  {a['name']:<28} {a['time_s']:6.1f} s  {what}")
    return "\n".join(lines)


def _text(data: dict[str, Any]) -> str:
    if "archives" in data:
        return "\n".join(_text(d) for d in data["archives"])
    from station.tables import product_table

    t = data["timings_s"]
    lines = [
        f"{len(data['products'])} product(s) from {data['l0']} into {data['out']}/; "
        f"GEO {t['geo']:.3f} s, all {t['total']:.1f} s"
    ]
    rows = [
        {
            **{k: r[k] for k in ("scene", "level", "n_rows", "n_cols", "valid") if k in r},
            "file": Path(r["path"]).name,
            "quality": {k: v for k, v in r.items() if k not in _ROW_KEYS},
        }
        for r in data["products"]
    ]
    lines += product_table(rows, [("scene", "scene")])
    for k in data["skipped"]:
        lines.append(f"{k['index']:5d}  skipped: {k['reason']}")
    return "\n".join(lines)


#: What a product's row of ``process.json`` holds beside its quality figures.
_ROW_KEYS = ("scene", "level", "path", "n_rows", "n_cols", "valid", "timings_s")
