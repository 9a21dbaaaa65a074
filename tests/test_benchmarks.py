"""Every benchmark runs in its smoke mode (``BENCH_SMOKE=1``: reduced sizes, the same code
and the same printed figures; ``benchmarks/_smoke.py``), so that none can rot: a crash, a
renamed function or a stale argument fails CI. No figure is judged here (timings on a
shared machine say nothing): each must run to its end, exit 0 and print its figures.

The benchmarks run as their users run them, ``python benchmarks/bench_X.py`` in a
subprocess of their own, one at a time in the background from the suite's start while its
other tests run (``tests/_smokes.py``); these tests run last and read them. A benchmark
whose peer is not installed (pandora, sarsen: the ``bench`` extra) says so and measures
the rest. ``bench_pass`` starts its Dask clusters
itself, bound to 127.0.0.1, and stops them.
"""

from __future__ import annotations

import pytest
from _smokes import BENCHMARKS, result


def test_every_benchmark_is_found() -> None:
    assert len(BENCHMARKS) >= 15, [p.name for p in BENCHMARKS]


@pytest.mark.parametrize("name", [p.name for p in BENCHMARKS])
def test_the_benchmark_runs_in_its_smoke_mode(name: str) -> None:
    run = result(name)
    said = f"{name} exited {run.returncode}:\n{run.stdout[-2000:]}\n{run.stderr[-3000:]}"
    assert run.returncode == 0, said
    figures = [ln for ln in run.stdout.splitlines() if any(c.isdigit() for c in ln)]
    if len(figures) < 2 and "is not installed" in run.stdout:  # a peer alone, not here
        pytest.skip(run.stdout.strip().splitlines()[-1])
    assert len(figures) >= 2, said  # it printed its figures
