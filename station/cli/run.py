"""``station run`` (and ``station`` alone): a scenario end to end into a run directory."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING

from station.cli._options import add_json, add_out, add_runner, exit_made, runner_of
from station.errors import StationError

if TYPE_CHECKING:
    from station.cli._options import Subparsers
    from station.loader import BlockScenario
    from station.sar_scenario import SarScenario
    from station.scenario import Scenario

__all__ = ["DEFAULT_SCENARIO", "register"]

#: The scenario ``station`` and ``station run`` run when given none.
DEFAULT_SCENARIO = Path(__file__).resolve().parents[2] / "scenarios" / "quickstart.toml"


def register(sub: Subparsers) -> None:
    p = sub.add_parser(
        "run",
        help="run a scenario end to end (the default scenario without one)",
        description="Run a scenario end to end: emulate the pass, send it through the "
        "channel, receive and record the L0 archive, run GEO and COR into level "
        "products, measure each against the truth, draw quicklooks and write "
        "report.json into the run directory.",
    )
    p.add_argument(
        "scenario", nargs="?", help="path to a scenario .toml (default: scenarios/quickstart.toml)"
    )
    add_out(p, "run directory (default: runs/<scenario name>)")
    add_json(p, "the report instead of a table")
    p.add_argument("--no-quicklooks", action="store_true", help="skip the quicklook PNGs")
    p.add_argument(
        "--check",
        action="store_true",
        help="check everything the run needs (scenario, the files it names, --out, memory, "
        "disk) and stop: nothing is written",
    )
    add_runner(p)
    p.set_defaults(func=_run)


def _run(args: argparse.Namespace) -> int:
    import json

    from station.loader import BlockScenario, load_any
    from station.run import run_scenario, summary_table
    from station.sar_scenario import SarScenario

    path = Path(args.scenario) if args.scenario else DEFAULT_SCENARIO
    if not args.scenario and not path.is_file():
        raise StationError(
            f"the default scenario {path} is not there (an install without "
            "the repository's scenarios/); give a scenario file"
        )
    scn = load_any(path)  # the file read once: a pass, a block or a SAR frame
    if isinstance(scn, BlockScenario):
        return _run_block(scn, path, args)
    if isinstance(scn, SarScenario):
        return _run_sar(scn, path, args)
    out = Path(args.out) if args.out else Path("runs") / scn.name
    if args.check:
        return _check(scn, out, args)
    if not args.json and not args.quiet:
        print(f"running {path} into {out}/ ...", file=sys.stderr)
    with runner_of(args) as runner:
        report = run_scenario(
            scn,
            out,
            quicklooks=not args.no_quicklooks,
            progress=not args.quiet and sys.stderr.isatty(),
            runner=runner,
            warm_up=True,
        )
    print(json.dumps(report, indent=2) if args.json else summary_table(report, out))
    return exit_made(len(report["products"]), "the run")


def _run_block(blk: BlockScenario, path: Path, args: argparse.Namespace) -> int:
    """A block scenario (``[[passes]]``): every pass, their tie points, the block."""
    import json

    from station.run import run_block, summary_table
    from station.tables import product_table

    name, scns = blk.name, blk.passes
    out = Path(args.out) if args.out else Path("runs") / name
    if args.check:
        for scn in scns:
            _check(scn, out / scn.name, args)
        return 0
    if not args.json and not args.quiet:
        print(f"running the block {path} ({len(scns)} passes) into {out}/ ...", file=sys.stderr)
    with runner_of(args) as runner:
        report = run_block(
            blk,
            out,
            quicklooks=not args.no_quicklooks,
            progress=not args.quiet and sys.stderr.isatty(),
            runner=runner,
        )
    if args.json:
        print(json.dumps(report, indent=2))
    else:
        for r in report["passes"]:
            print(summary_table(r, out / r["scenario"]["name"]))
        pairs = report["ties"]["pairs"]
        print(
            f"tie points: {sum(p['points'] for p in pairs)} between {len(pairs)} pair(s) of "
            f"scenes, in {out}/ties/"
        )
        block = report["block"].get("products", [])
        if block:
            print(f"the block's adjustment, in {out}/block/:")
            print("\n".join(product_table(block, [("pass", "pass"), ("scene", "scene")])))
        dems = report.get("stereo", {}).get("dems", [])
        if dems:
            print(f"the pair's DEM against the true terrain, in {out}/stereo/:")
            print("\n".join(product_table(dems, [])))
    made = len(report["block"].get("products", [])) + sum(
        len(r["products"]) for r in report["passes"]
    )
    return exit_made(made, "the block")


def _run_sar(scn: SarScenario, path: Path, args: argparse.Namespace) -> int:
    """A SAR frame's scenario (``[sar]``): the frame, its GEC and GTC, the truth's figures."""
    import json

    from station.run_sar import run_sar, sar_summary

    out = Path(args.out) if args.out else Path("runs") / scn.name
    if args.check:
        from station.run import prepare_run_dir

        prepare_run_dir(out, scn.name, scn.inputs())  # replaceable, writable; no write
        missing = [str(p) for p in scn.inputs() if not p.is_file()]
        if missing:
            raise StationError(f"{scn.name}: {missing[0]} not found")
        found = {"scenario": scn.name, "files": [str(p) for p in scn.inputs()], "out": str(out)}
        print(
            json.dumps(found, indent=2)
            if args.json
            else f"{scn.name}: checks passed (the scenario, the files it reads: "
            f"{', '.join(found['files'])}); into {out}/"
        )
        return 0
    if not args.json and not args.quiet:
        print(f"running the SAR frame {path} into {out}/ ...", file=sys.stderr)
    report = run_sar(scn, out, quicklooks=not args.no_quicklooks)
    print(json.dumps(report, indent=2) if args.json else sar_summary(report, out))
    return exit_made(len(report["products"]), "the run")


def _check(scn: Scenario, out: Path, args: argparse.Namespace) -> int:
    """``--check``: the run's checks (``station.run.check_run``) and what they found."""
    import json

    from station.run import check_run, prepare_run_dir

    prepare_run_dir(out, scn.name, scn.inputs())
    found = check_run(scn, out)
    if args.json:
        print(json.dumps(found, indent=2))
        return 0
    print(check_text(scn.name, found, out))
    return 0


def check_text(name: str, found: Mapping[str, object], out: Path) -> str:
    """``--check``'s line: what was checked and the memory and disk the job takes
    (``station.preflight.check_needs``'s figures, and the files read: ``files`` of a
    scenario, ``archives`` of a reprocessing)."""

    def gib(key: str) -> float:
        value = found.get(key)
        return float(value) / 2**30 if isinstance(value, int | float) else float("nan")

    read = found.get("files") or found.get("archives") or []
    pixels = found.get("pixels")
    return (
        f"{name}: checks passed;"
        + (f" {pixels / 1e6:.1f} Mpx," if isinstance(pixels, int | float) else "")
        + f" about {gib('memory_bytes'):.2f} GiB of memory"
        + (
            f" of {gib('memory_available_bytes'):.1f} available"
            if found.get("memory_available_bytes")
            else ""
        )
        + f", up to {gib('disk_bytes'):.2f} GiB on disk of {gib('disk_free_bytes'):.1f} free"
        + (f"; read {', '.join(map(str, read))}" if isinstance(read, list) and read else "")
        + f"; into {out}/"
    )
