"""``station run`` (and ``station`` alone): a scenario end to end into a run directory."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from station.cli._options import add_json, add_out, add_runner, exit_made, runner_of
from station.errors import StationError

__all__ = ["DEFAULT_SCENARIO", "register"]

#: The scenario ``station`` and ``station run`` run when given none.
DEFAULT_SCENARIO = Path(__file__).resolve().parents[2] / "scenarios" / "quickstart.toml"


def register(sub: Any) -> None:
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

    from station.run import run_scenario, summary_table
    from station.scenario import load_scenario

    path = Path(args.scenario) if args.scenario else DEFAULT_SCENARIO
    if not args.scenario and not path.is_file():
        raise StationError(
            f"the default scenario {path} is not there (an install without "
            "the repository's scenarios/); give a scenario file"
        )
    scn = load_scenario(path)
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


def _check(scn: Any, out: Path, args: argparse.Namespace) -> int:
    """``--check``: the run's checks (``station.run.check_run``) and what they found."""
    import json

    from station.run import check_run, prepare_run_dir

    prepare_run_dir(out, scn.name, scn.inputs())
    found = check_run(scn, out)
    if args.json:
        print(json.dumps(found, indent=2))
        return 0
    mem = found["memory_available_bytes"]
    print(
        f"{scn.name}: checks passed; {found['pixels'] / 1e6:.1f} Mpx, about "
        f"{found['memory_bytes'] / 2**30:.2f} GiB of memory"
        + (f" of {mem / 2**30:.1f} available" if mem else "")
        + f", up to {found['disk_bytes'] / 2**30:.2f} GiB on disk of "
        f"{found['disk_free_bytes'] / 2**30:.1f} free"
        + (f"; read {', '.join(found['files'])}" if found["files"] else "")
        + f"; into {out}/"
    )
    return 0
