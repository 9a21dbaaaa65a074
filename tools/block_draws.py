"""Level 2 of a block's passes over many draws: is each pass's predicted accuracy what it
gets against the truth?

    python tools/block_draws.py                                  # stereo_pair, 16 draws
    python tools/block_draws.py scenarios/blocks/two_passes.toml --draws 8
    python tools/block_draws.py --draws 24 --first 100 --jobs 2

Each draw is the block scenario run whole (``station run``, a process of its own, ``--jobs``
at a time) with its ``seed`` set to ``first + k`` (every pass's errors, control points and
tie points drawn anew). Of each pass's level 2 product: its line-of-sight RMS at the
checkpoints against the truth over its predicted horizontal σ (``predicted_sigma_m``), and
the mean error east and north against the predicted σ on each axis. Printed per pass: the
RMS of the ratio over the draws (1 when the prediction holds; the issue's bar [0.8, 1.25]),
its range, the spread of the mean errors beside the predicted σ (stdout); each draw's line
as it ends (stderr).
"""

from __future__ import annotations

import argparse
import json
import re
import subprocess
import sys
import tempfile
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
LOS = "checkpoints/P/line_of_sight"


def draw(scenario: Path, seed: int, work: Path) -> list[dict[str, float]] | None:
    """One draw: the block run with ``seed``; each pass's level 2 figures (None: failed)."""
    text = re.sub(r"^seed = \d+", f"seed = {seed}", scenario.read_text(), count=1, flags=re.M)
    toml = work / f"{scenario.stem}_{seed}.toml"
    toml.write_text(text)
    out = work / f"{scenario.stem}_{seed}"
    cmd = [sys.executable, "-m", "station.cli", "run", str(toml), "--out", str(out), "-q",
           "--no-quicklooks"]  # fmt: skip
    if subprocess.run(cmd, capture_output=True).returncode:
        return None
    report = json.loads((out / "report.json").read_text())
    rows = []
    for p in report["block"]["products"]:
        q = p["quality"]
        if not p["file"].endswith("_2.nc"):
            continue
        rows.append(
            {
                "pass": p["file"].split("/")[-1].rsplit("_s", 1)[0],
                "los_rms_m": q[f"{LOS}/rms_m"],
                "predicted_m": q["predicted_sigma_m/horizontal"],
                "east_m": q[f"{LOS}/mean_1_m"],
                "north_m": q[f"{LOS}/mean_2_m"],
                "predicted_east_m": q["predicted_sigma_m/east"],
                "predicted_north_m": q["predicted_sigma_m/north"],
            }
        )
    return rows


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("scenario", nargs="?", default=str(ROOT / "scenarios/stereo/stereo_pair.toml"))
    ap.add_argument("--draws", type=int, default=16)
    ap.add_argument("--first", type=int, default=100, help="the first draw's seed")
    ap.add_argument("--jobs", type=int, default=2, help="draws run at once")
    args = ap.parse_args()
    scenario = Path(args.scenario)
    seeds = range(args.first, args.first + args.draws)
    with tempfile.TemporaryDirectory() as tmp, ThreadPoolExecutor(args.jobs) as pool:
        results = []
        for seed, rows in zip(
            seeds, pool.map(lambda s: draw(scenario, s, Path(tmp)), seeds), strict=True
        ):
            if rows is None:
                print(f"seed {seed}: the run failed", file=sys.stderr, flush=True)
                continue
            results.append(rows)
            print(
                f"seed {seed}: "
                + "  ".join(
                    f"{r['pass']} {r['los_rms_m']:.1f} m / {r['predicted_m']:.1f} m = "
                    f"{r['los_rms_m'] / r['predicted_m']:.2f}"
                    for r in rows
                ),
                file=sys.stderr,
                flush=True,
            )
    if not results:
        return 1
    print(f"\n{scenario.name}, {len(results)} draws (seeds {seeds[0]}–{seeds[-1]}):")
    for k in range(len(results[0])):
        rows = [r[k] for r in results]
        ratio = np.array([r["los_rms_m"] / r["predicted_m"] for r in rows])
        east, north = (np.array([r[f"{a}_m"] for r in rows]) for a in ("east", "north"))
        pe, pn = (np.mean([r[f"predicted_{a}_m"] for r in rows]) for a in ("east", "north"))
        print(
            f"  {rows[0]['pass']}: measured/predicted RMS {np.sqrt(np.mean(ratio**2)):.2f} "
            f"({ratio.min():.2f}–{ratio.max():.2f}); mean error east RMS "
            f"{np.sqrt(np.mean(east**2)):.1f} m (predicted {pe:.1f}), north "
            f"{np.sqrt(np.mean(north**2)):.1f} m (predicted {pn:.1f})"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
