"""``station capacity``: the simpy model of a station, and ``capacity calibrate``."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from station.cli._options import add_json, add_out, add_runner, emit, runner_of
from station.errors import StationError

if TYPE_CHECKING:
    from station.cli._options import Subparsers

__all__ = ["register"]


def register(sub: Subparsers) -> None:
    cap = sub.add_parser(
        "capacity",
        help="capacity planning: a simpy model of the station, or `calibrate`",
        description="Simulate a station's passes, recording and processing queues over a "
        "capacity scenario (scenarios/capacity/), with replications and what-if "
        "sweeps; or `station capacity calibrate` to measure this code's service "
        "times on this machine.",
    )
    cap.add_argument("scenario", help="a capacity scenario (.toml), or 'calibrate', or 'validate'")
    cap.add_argument(
        "day_run", nargs="?", metavar="DAY_RUN", help="validate: a station day's directory"
    )
    cap.add_argument(
        "--service",
        metavar="F",
        help="validate: the day's service times from F (default: the day's own, else measured now)",
    )
    cap.add_argument(
        "--sessions",
        type=int,
        default=None,
        metavar="K",
        help="validate: measure K calibration sessions now (default: the day's own, measured "
        "before its clock and after it; else 2), their spread in the interval",
    )
    cap.add_argument(
        "--sweep",
        action="append",
        help="SECTION.KEY=V1,V2,... (e.g. resources.cor_workers=1,2,3,4); given for several "
        "keys, every combination of their values (a grid)",
    )
    cap.add_argument("--replications", type=int, help="replications (default: the scenario's)")
    add_out(
        cap,
        "output directory (default runs/<name>/); for calibrate, the service-time "
        "file (default service_times.json)",
    )
    add_runner(cap, "replications (of every sweep value)")
    add_json(cap, "the summary as JSON")
    cap.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    cap.set_defaults(func=_capacity)


def _capacity(args: argparse.Namespace) -> int:
    if args.scenario == "validate":
        return _validate(args)
    if args.day_run or args.service or args.sessions:
        raise StationError("DAY_RUN and --service are validate's: station capacity validate DIR")
    if args.scenario == "calibrate":
        from station.capacity.calibrate import (
            SERVICE_TIMES_FORMAT,
            calibrate,
            service_times_format,
            write_service_times,
        )
        from station.outdir import replaceable_file

        if args.sweep or args.replications:
            raise StationError("capacity calibrate takes only --out FILE")
        out = replaceable_file(
            args.out or "service_times.json",
            service_times_format,
            SERVICE_TIMES_FORMAT,
            lambda f: "a service-time table" if f == SERVICE_TIMES_FORMAT else f"a {f} file",
        )
        print("measuring this code's stages on this machine ...", file=sys.stderr)
        table = calibrate()
        path = write_service_times(out, table)
        print(
            f"wrote {path}: ingest {table['ingest_s_per_signal_s']:.3f} s per s of signal; "
            "per full scene, GEO "
            + ", ".join(f"{m} {v:.3f}" for m, v in table["geo_s_per_scene"].items())
            + " s; COR "
            + "; ".join(
                f"{m} " + ", ".join(f"{lv} {t:.2f}" for lv, t in lvs.items())
                for m, lvs in table["cor_s"].items()
            )
            + " s"
        )
        return 0
    from station.capacity.config import load_capacity
    from station.capacity.study import parse_sweeps, run_study, study_table

    scn = load_capacity(args.scenario)
    sweep = parse_sweeps(args.sweep) if args.sweep else None
    if args.replications is not None and args.replications < 1:
        raise StationError(f"--replications {args.replications}: expected at least 1")
    out = Path(args.out) if args.out else Path("runs") / scn.name
    with runner_of(args) as runner:
        summary = run_study(
            scn, out, sweep, args.replications, plots=not args.no_plots, runner=runner
        )
    files = "summary.json, stages.csv, levels.csv, station.csv, queues.csv" + (
        ""
        if args.no_plots
        else ", queues.png, latency.png"
        + (", queues_<k>.png (the k-th value's), sweep.png" if sweep else "")
    )
    emit(args, summary, lambda s: f"{study_table(s)}\nin {out}/: {files}")
    return 0


def _validate(args: argparse.Namespace) -> int:
    from station.day.validation import validate_day, validation_text

    if not args.day_run:
        raise StationError("capacity validate DAY_RUN: give a station day's directory")
    if args.sweep:
        raise StationError("capacity validate takes no --sweep")
    result = validate_day(
        Path(args.day_run),
        args.service,
        args.replications,
        say=not getattr(args, "quiet", False),
        sessions=args.sessions,
    )
    emit(args, result, validation_text)
    return 0 if result["consistent"] else 1
