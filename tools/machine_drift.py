"""How much this machine's speed drifts from one minute to the next: the same processing job
made again and again on one worker (or ``--workers`` N, N jobs in flight) for a few
minutes, its mean time in windows of ``--window`` seconds, and their spread.

    python tools/machine_drift.py [--minutes 4] [--window 20] [--workers 1] [--json]

The job is a day's order (:func:`station.day.work.make_order`: level 2A of the warm-up
archive's first scene, read, made and catalogued), in spawned workers warmed as a day's
are, nothing else running. On a machine of its own the windows agree to a
few per cent; on a shared VM they do not, and that spread bounds how closely any
calibration measured minutes before (or after) a day can predict the day's service times:
``station capacity validate``'s 10 % on a stage's utilisation is out of reach where the
windows themselves differ by more (``docs/day.md``).
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np


def drift(minutes: float, window_s: float, workers: int = 1) -> dict[str, object]:
    """The windows' mean job times and their spread (module docstring)."""
    from levels.warmup import WARM_UP_ARCHIVE
    from station.day.pool import day_pool
    from station.day.work import make_order

    times: list[tuple[float, float]] = []
    with tempfile.TemporaryDirectory() as tmp, day_pool(workers) as pool:
        cat = str(Path(tmp) / "catalogue.sqlite")
        for f in [pool.submit(time.sleep, 0.2) for _ in range(workers)]:
            f.result()  # every worker spawned and warm
        end = time.time() + 60.0 * minutes
        k = 0

        def job() -> tuple[float, object]:
            nonlocal k
            k += 1
            args = (str(WARM_UP_ARCHIVE), 0, "2A", f"{tmp}/{k}", cat)
            return time.time(), pool.submit(make_order, *args)

        flying = [job() for _ in range(workers)]  # ``workers`` jobs in flight throughout
        while flying:
            t, f = flying.pop(0)
            f.result()  # type: ignore[attr-defined]
            times.append((t, time.time() - t))
            if time.time() < end:
                flying.append(job())
    t0 = times[0][0]
    w = np.array([int((t - t0) // window_s) for t, _ in times])
    d = np.array([x for _, x in times])
    full = [i for i in np.unique(w) if (w == i).sum() >= 3]
    means = np.array([d[w == i].mean() for i in full])
    within = [d[w == i].std(ddof=1) / d[w == i].mean() for i in full]
    return {
        "jobs": len(times),
        "job_mean_s": float(d.mean()),
        "window_s": window_s,
        "window_means_s": [round(float(m), 4) for m in means],
        "window_cv": float(means.std(ddof=1) / means.mean()) if means.size > 1 else 0.0,
        "window_range": float(means.max() / means.min() - 1.0) if means.size else 0.0,
        "within_window_cv": float(np.mean(within)) if within else 0.0,
    }


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--minutes", type=float, default=4.0)
    ap.add_argument("--window", type=float, default=20.0, help="seconds a window (20)")
    ap.add_argument("--workers", type=int, default=1, help="jobs in flight at once (1)")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    r = drift(args.minutes, args.window, args.workers)
    if args.json:
        print(json.dumps(r, indent=1))
        return 0
    print(
        f"{r['jobs']} jobs of {r['job_mean_s']:.3f} s on average over {args.minutes:g} min; "
        f"windows of {args.window:g} s: {', '.join(f'{m:.3f}' for m in r['window_means_s'])}"
    )
    print(
        f"between windows: cv {100 * r['window_cv']:.1f} %, slowest {100 * r['window_range']:.0f} "
        f"% slower than fastest; within a window: cv {100 * r['within_window_cv']:.1f} %"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
