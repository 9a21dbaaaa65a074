"""The processing's runners (:mod:`levels.tasks`): tasks in process run in order and a
failure carries its task's name; a Dask worker of one core runs its kernels on one thread.
The cluster's own tests, with the station's commands, are ``tests/test_distributed.py``."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from levels.errors import L0Error
from levels.tasks import InProcess, TaskFailure

#: How long a one-worker cluster may take to start and stop (a worker imports numpy, numba
#: and h5py).
START_S, STOP_S = 90.0, 10.0


def test_in_process_tasks_run_in_order_and_failures_carry_their_name() -> None:
    runner = InProcess()
    handles = [runner.submit(f"t{k}", lambda k: 10 // k, k) for k in (1, 0, 5)]
    results = [r for _, r in runner.completed(handles)]
    assert results[0] == 10 and results[2] == 2
    failure = results[1]
    assert isinstance(failure, TaskFailure) and failure.name == "t0" and not failure.bad_input
    assert failure.line().startswith("t0: ZeroDivisionError")
    assert TaskFailure("x", L0Error("damaged")).bad_input


#: A program whose main module imports numba, as ``station`` and the benchmarks do: a
#: spawned worker imports it again before the nanny sets its environment.
_THREADS_PROBE = """
import numba  # at the top of the main module
from levels.tasks import dask_runner

def threads():
    import numba
    return numba.get_num_threads()

if __name__ == "__main__":
    with dask_runner(workers=1, cores_per_worker=1) as runner:
        [(_, n)] = list(runner.completed([runner.submit("probe", threads)]))
    print(n)
"""


@pytest.mark.skipif((os.cpu_count() or 1) < 2, reason="one core: every worker has one anyway")
def test_a_one_core_worker_runs_its_kernels_on_one_thread(tmp_path) -> None:
    """``--workers N`` with one core each: a task's kernels run on one numba thread even
    when the program's main module imported numba (it took both cores: the pass
    benchmark's one worker was a two-core one)."""
    script = tmp_path / "probe.py"
    script.write_text(_THREADS_PROBE)
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_NUM_THREADS"}
    env.pop("DASK_SCHEDULER_ADDRESS", None)
    done = subprocess.run(
        [sys.executable, str(script)],
        capture_output=True,
        text=True,
        timeout=START_S + STOP_S,
        cwd=tmp_path,
        env=env,
        check=False,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    assert done.stdout.split()[-1] == "1"
