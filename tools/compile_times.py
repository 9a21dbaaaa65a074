"""Where a first run's time goes: numba's compile time of every kernel the default scenario
calls, in one process with an empty cache (issue 49, finding 9: the first run's 12 s).

    NUMBA_CACHE_DIR=$(mktemp -d) python tools/compile_times.py [SCENARIO] [OUT]

Prints the run's wall time, then the compile time by module and the costliest kernels
(numba's ``numba:compile`` events; a kernel compiled inside another counts in both, so
the sum exceeds the wall time). With the cache warm a run takes what
``benchmarks/bench_first_run.py`` prints as its figure 3; the compile time on top is the
work a first run cannot avoid: spread over two cores at best, it bounds the first run
below by (warm run + compile) / 2.

Measured (2026-11-27, 2 cores): quickstart 22.0 s in one process; the processing kernels
9.7 s (``levels.warmup`` alone: 11.5 s cold, 1.8 s warm), the emulator's and the
receiver's 7.8 s (a run with only those cold: 14.3 s against 6.5 s warm); the costliest
``_kernel_2a`` 3.5 s, the frame decoder 2.4 s, the inverse grid's walk 2.3 s.
"""

from __future__ import annotations

import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

from numba.core import event

ROOT = Path(__file__).resolve().parents[1]


class _Timer(event.Listener):
    """Each kernel's compile time, from numba's compile events."""

    def __init__(self) -> None:
        self.started: dict[int, float] = {}
        self.totals: dict[str, float] = defaultdict(float)

    def on_start(self, ev: event.Event) -> None:
        d = ev.data
        if isinstance(d, dict) and "dispatcher" in d:
            self.started[id(d["dispatcher"])] = time.perf_counter()

    def on_end(self, ev: event.Event) -> None:
        d = ev.data
        if isinstance(d, dict) and "dispatcher" in d:
            t0 = self.started.pop(id(d["dispatcher"]), None)
            f = d["dispatcher"].py_func
            if t0 is not None:
                self.totals[f"{f.__module__}.{f.__name__}"] += time.perf_counter() - t0


def main(argv: list[str]) -> int:
    from station.loader import load_scenario
    from station.run import run_scenario

    scenario = Path(argv[0]) if argv else ROOT / "scenarios" / "quickstart.toml"
    timer = _Timer()
    event.register("numba:compile", timer)
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(argv[1]) if len(argv) > 1 else Path(tmp) / "run"
        t0 = time.perf_counter()
        run_scenario(load_scenario(scenario), out, warm_up=False)
        wall = time.perf_counter() - t0
    totals = timer.totals
    print(f"{scenario.name}: {wall:.1f} s in one process; {len(totals)} kernels compiled")
    by_module: dict[str, float] = defaultdict(float)
    for name, t in totals.items():
        by_module[name.rsplit(".", 1)[0]] += t
    for name, t in sorted(by_module.items(), key=lambda x: -x[1])[:12]:
        print(f"  {t:6.2f} s  {name}")
    print("the costliest kernels:")
    for name, t in sorted(totals.items(), key=lambda x: -x[1])[:10]:
        print(f"  {t:6.2f} s  {name}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
