"""Every benchmark runs in its smoke mode (``BENCH_SMOKE=1``: reduced sizes, the same code
and the same printed figures; ``benchmarks/_smoke.py``), so that none can rot: a crash, a
renamed function or a stale argument fails CI. No figure is judged here (timings on a
shared machine say nothing): each must run to its end, exit 0 and print its figures.

The benchmarks run as their users run them, ``python benchmarks/bench_X.py`` in a
subprocess of their own, two at a time (they are processes: the suite's wall time is
what CI waits for); a benchmark whose peer is not installed (pandora, sarsen: the
``bench`` extra) says so and measures the rest. ``bench_pass`` starts its Dask clusters
itself, bound to 127.0.0.1, and stops them.
"""

from __future__ import annotations

import os
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
BENCHMARKS = sorted((ROOT / "benchmarks").glob("bench_*.py"))
#: Arguments a benchmark's smoke run takes besides its defaults (its optional parts too).
EXTRA = {"bench_sar.py": ["--flatten"]}
#: A smoke run's bound (s): the slowest takes about 20 s on 2 shared cores; a hang fails.
SMOKE_TIMEOUT_S = 300
#: Smoke runs at once.
AT_ONCE = 2


def _smoke(path: Path, tmp: Path) -> subprocess.CompletedProcess[str]:
    env = os.environ | {"BENCH_SMOKE": "1"}
    try:
        return subprocess.run(
            [sys.executable, str(path), *EXTRA.get(path.name, [])],
            cwd=tmp,
            env=env,
            capture_output=True,
            text=True,
            timeout=SMOKE_TIMEOUT_S,
        )
    except subprocess.TimeoutExpired as exc:  # the child is killed by run(); said here
        return subprocess.CompletedProcess(exc.cmd, -9, str(exc.stdout or ""), "timed out")


@pytest.fixture(scope="module")
def smoke_runs(
    tmp_path_factory: pytest.TempPathFactory,
) -> dict[str, subprocess.CompletedProcess[str]]:
    """Every benchmark's smoke run, :data:`AT_ONCE` at a time, each in a directory of
    its own."""
    with ThreadPoolExecutor(AT_ONCE) as pool:
        runs = {p.name: pool.submit(_smoke, p, tmp_path_factory.mktemp(p.stem)) for p in BENCHMARKS}
        return {name: f.result() for name, f in runs.items()}


def test_every_benchmark_is_found() -> None:
    assert len(BENCHMARKS) >= 15, [p.name for p in BENCHMARKS]


@pytest.mark.parametrize("name", [p.name for p in BENCHMARKS])
def test_the_benchmark_runs_in_its_smoke_mode(name: str, smoke_runs) -> None:
    run = smoke_runs[name]
    said = f"{name} exited {run.returncode}:\n{run.stdout[-2000:]}\n{run.stderr[-3000:]}"
    assert run.returncode == 0, said
    figures = [ln for ln in run.stdout.splitlines() if any(c.isdigit() for c in ln)]
    if len(figures) < 2 and "is not installed" in run.stdout:  # a peer alone, not here
        pytest.skip(run.stdout.strip().splitlines()[-1])
    assert len(figures) >= 2, said  # it printed its figures
