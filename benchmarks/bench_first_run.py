"""The first ``station`` after a fresh install: the default scenario with numba's cache empty.

Figures printed (issue 49's target: ≤ 12 s on 2 cores; issue 21's was 25 s):

1. **First run**, ``station run scenarios/quickstart.toml`` with an empty cache: as a
   newcomer runs it, the processing kernels compiled in a background process while the
   pass is emulated and received (``levels.warmup``);
2. **the same without the warm-up** (``run_scenario(warm_up=False)``), every kernel compiled
   in turn by the run: the peer of figure 1;
3. **the same run with the cache warm** (what every later run costs): the floor.

Each run is a fresh interpreter with its own empty ``NUMBA_CACHE_DIR``; the three are
measured in this order, in the same minutes of the same host. Run:
``python benchmarks/bench_first_run.py`` (about two and a half minutes; ``BENCH_SMOKE=1``:
``small_test`` with this machine's warm cache, the commands alone checked).
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _smoke import SMOKE

ROOT = Path(__file__).resolve().parents[1]
SCENARIO = ROOT / "scenarios" / ("small_test.toml" if SMOKE else "quickstart.toml")

_WITHOUT_WARM_UP = """
import sys
from station.run import run_scenario
from station.loader import load_scenario
run_scenario(load_scenario(sys.argv[1]), sys.argv[2], warm_up=False)
"""


def _timed(cmd: list[str], cache: Path) -> float:
    env = os.environ if SMOKE else os.environ | {"NUMBA_CACHE_DIR": str(cache)}
    t = time.perf_counter()
    subprocess.run(cmd, env=env, check=True, capture_output=True)
    return time.perf_counter() - t


def main() -> None:
    print(f"first station run of {SCENARIO.name}, {os.cpu_count()} cores")
    with tempfile.TemporaryDirectory(prefix="bench-first-run-") as tmp:
        root = Path(tmp)
        station = [sys.executable, "-m", "station.cli"]
        first = _timed(
            [*station, "run", str(SCENARIO), "--out", str(root / "a"), "--quiet"], root / "cache_a"
        )
        alone = _timed(
            [sys.executable, "-c", _WITHOUT_WARM_UP, str(SCENARIO), str(root / "b")],
            root / "cache_b",
        )
        cached = _timed(
            [*station, "run", str(SCENARIO), "--out", str(root / "c"), "--quiet"], root / "cache_a"
        )
    print(
        f"1. first run, kernels compiled in the background meanwhile: {first:.1f} s "
        f"(target ≤ 12 s: {first / 12.0:.2f}× it)"
    )
    print(
        f"2. first run, every kernel compiled in turn:               {alone:.1f} s "
        f"(figure 1 is {alone / first:.2f}× faster)"
    )
    print(
        f"3. the same run, cache warm:                                {cached:.1f} s "
        f"(compiling costs the first run {first - cached:.1f} s)"
    )


if __name__ == "__main__":
    main()
