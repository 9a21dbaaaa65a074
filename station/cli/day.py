"""``station day DAY.toml``: a day at the station on a clock (:mod:`station.day.run`)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

from station.cli._options import add_json, emit
from station.errors import StationError

if TYPE_CHECKING:
    from station.cli._options import Subparsers

__all__ = ["day_text", "register"]


def register(sub: Subparsers) -> None:
    d = sub.add_parser(
        "day",
        help="a day at the station: passes on a clock, orders on a pool of workers",
        description="Run a day file (scenarios/day/): the capacity model's passes over the "
        "station in its window, each emulated and sent to a station serve front end at its "
        "time on a clock C times faster than real, archived and catalogued; the orders "
        "drawn as the model draws them looked up in the catalogue and made by a pool of "
        "workers, urgent first, each product catalogued. Writes OUT/day.json (per stage "
        "utilisation and waits, per level latencies, the backlog) and OUT/queues.png; "
        "station capacity validate OUT checks the capacity model against it.",
    )
    d.add_argument("day", help="a day file (.toml)")
    d.add_argument("--clock", type=float, metavar="C", help="times faster than real (the file's)")
    g = d.add_mutually_exclusive_group()
    g.add_argument("--workers", type=int, metavar="N", help="local processing workers (the file's)")
    g.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help="the processing workers are those of the Dask cluster at ADDRESS (e.g. "
        "tcp://127.0.0.1:8786), as many as its threads; they must see OUT at the same path",
    )
    d.add_argument("--out", help="output directory (default runs/<name>/)")
    d.add_argument(
        "--resume",
        action="store_true",
        help="go on with a killed day in OUT: nothing archived or made is done again",
    )
    d.add_argument(
        "--no-calibrate",
        action="store_true",
        help="do not measure the service times before the clock and after it (OUT/"
        "service_day.json); station capacity validate then measures them itself",
    )
    add_json(d, "the report as JSON")
    d.set_defaults(func=_day)


def _day(args: argparse.Namespace) -> int:
    from station.day.config import load_day, with_workers
    from station.day.run import run_day

    scn = with_workers(load_day(args.day), args.workers, args.clock)
    out = Path(args.out) if args.out else Path("runs") / scn.name
    report = run_day(
        scn,
        out,
        resume=args.resume,
        say=not getattr(args, "quiet", False),
        calibrate=not args.no_calibrate,
        scheduler=args.scheduler,
    )
    emit(args, report, lambda r: day_text(r, out))
    counts = report["counts"]
    if counts["made"] == 0 and counts["orders_in_window"] > 0:
        raise StationError(f"the day made no product of its {counts['orders_in_window']} orders")
    return 0


def day_text(r: dict, out: Path) -> str:
    """The day's report in a few lines."""
    c = r["counts"]
    lines = [
        f"day {r['day']}: {c['passes_archived']} of {c['passes']} passes archived, "
        f"{c['made']} products of {c['orders_in_window']} orders ({c['urgent']} urgent); "
        f"{c['not_held']} not held, {c['failed']} failed, backlog at the end "
        f"{c['backlog_at_end']}; clock {r['clock']:g}x, {r['workers']} workers",
        "stage    units  utilisation  mean wait (h)",
    ]
    for name, s in r["stages"].items():
        w = s["wait"]["mean_h"]
        lines.append(
            f"{name:8s} {s['units']:5d}  {s['utilisation']:11.3f}  "
            f"{'-' if w is None else f'{w:.3f}':>13s}"
        )
    lines.append("level  products  latency from acquisition p50/p95 (h)  from order p50/p95 (h)")
    for lv, s in r["levels"].items():
        a, o = s["from_acquisition"], s["from_order"]
        if a["n"]:
            lines.append(
                f"{lv:5s}  {a['n']:8d}  {a['p50_h']:17.2f} / {a['p95_h']:<17.2f}"
                f"{o['p50_h']:8.2f} / {o['p95_h']:.2f}"
            )
    lines.append(f"in {out}/: day.json, queues.png, events.jsonl, plan.json, archive/, products/")
    return "\n".join(lines)
