"""The same day with one worker and with three: the capacity model's predicted change of each
level's latency beside the measured change (issue 60's what-if check).

    python tools/day_workers.py [scenarios/day/cuiaba_day.toml] [--out runs/day_workers]

Runs ``station day`` with ``--workers 1`` and ``--workers 3`` (each about three and a half
minutes at the shipped day's clock, with its service times measured on calibration passes of
their own before its clock and after it, never the day's), validates each (``station
capacity validate``), then predicts the change of the
2A p95 latency from acquisition (and the others) from the two models' replications with the
same seeds (common random numbers: the difference's interval is not drowned in the two
runs' noise) and says whether the measured change lies inside the 95 % interval of the
predicted one. Prints a table; ``--json`` the rows.
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
FIGURES = [
    f"{lv}.{w}.{s}"
    for lv in ("1A", "1B", "2A")
    for w in ("from_acquisition", "from_order")
    for s in ("mean_h", "p95_h")
] + ["cor.utilisation", "cor.wait_mean_h"]


def _day(day: Path, out: Path, workers: int) -> Path:
    where = out / f"workers{workers}"
    if not (where / "day.json").is_file():
        subprocess.run(
            [sys.executable, "-m", "station.cli", "day", str(day), "--out", str(where),
             "--workers", str(workers), "-q"],
            check=True,
        )  # fmt: skip
    if not (where / "validation.json").is_file():
        subprocess.run(
            [sys.executable, "-m", "station.cli", "capacity", "validate", str(where), "-q"],
            check=False,  # a figure outside is said in the table, not fatal here
        )
    return where


def _predicted(where: Path, replications: int) -> dict[str, np.ndarray]:
    from station.capacity.plan import read_plan
    from station.capacity.validate import DayUnits, predict
    from station.day.config import load_day, with_workers

    report = json.loads((where / "day.json").read_text())
    scn = with_workers(load_day(where / "day.toml"), int(report["workers"]), None)
    service = json.loads((where / "service_day.json").read_text())
    res = scn.capacity.resources
    units = DayUnits(res.ingest_workers, res.geo_workers, scn.day.workers, scn.day.clock)
    return predict(read_plan(where / "plan.json"), units, service, replications, scn.capacity.seed)


def _measured(where: Path) -> dict[str, float]:
    from station.capacity.validate import _measured as measured

    return measured(json.loads((where / "day.json").read_text()))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("day", nargs="?", default=str(ROOT / "scenarios" / "day" / "cuiaba_day.toml"))
    ap.add_argument("--out", default="runs/day_workers")
    ap.add_argument("--replications", type=int, default=200)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    out = Path(args.out)
    one, three = (_day(Path(args.day), out, w) for w in (1, 3))
    p1, p3 = _predicted(one, args.replications), _predicted(three, args.replications)
    m1, m3 = _measured(one), _measured(three)
    rows = []
    for key in FIGURES:
        if key not in p1 or not (math.isfinite(m1.get(key, math.nan))
                                 and math.isfinite(m3.get(key, math.nan))):  # fmt: skip
            continue
        d = p3[key] - p1[key]
        d = d[np.isfinite(d)]
        lo, hi = (float(x) for x in np.percentile(d, [2.5, 97.5]))
        change = m3[key] - m1[key]
        rows.append({"figure": key, "measured_1": m1[key], "measured_3": m3[key],
                     "measured_change": change, "predicted_change": float(d.mean()),
                     "interval": [lo, hi], "inside": bool(lo <= change <= hi)})  # fmt: skip
    if args.json:
        print(json.dumps(rows, indent=1))
        return 0
    print(f"{args.day}: one worker against three; the model's change over "
          f"{args.replications} replications with the same seeds, 95 % interval")  # fmt: skip
    print(f"{'figure':32s} {'1 worker':>9s} {'3 workers':>9s} {'change':>9s} {'model':>9s}"
          "   interval              inside")  # fmt: skip
    for r in rows:
        lo, hi = r["interval"]
        print(f"{r['figure']:32s} {r['measured_1']:9.4f} {r['measured_3']:9.4f} "
              f"{r['measured_change']:9.4f} {r['predicted_change']:9.4f}   "
              f"[{lo:8.4f}, {hi:8.4f}]  {'yes' if r['inside'] else 'NO'}")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
