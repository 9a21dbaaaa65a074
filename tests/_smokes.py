"""Work the suite runs beside its own tests: a second pytest process for the :data:`PART`
files, and the benchmarks' smoke runs (``BENCH_SMOKE=1``), started in the background as soon as the
suite is collected (``conftest.pytest_collection_modifyitems``) and run one at a time while
the rest of the suite runs on the other core; ``tests/test_benchmarks.py`` runs last and
reads what each printed. Each is a process of its own, as its users run it
(``python benchmarks/bench_X.py``), in a directory of its own."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
BENCHMARKS = sorted((ROOT / "benchmarks").glob("bench_*.py"))
#: Arguments a benchmark's smoke run takes besides its defaults (its optional parts too).
EXTRA = {"bench_sar.py": ["--flatten"]}
#: A smoke run's bound (s): the slowest takes about 20 s on 2 shared cores; a hang fails.
SMOKE_TIMEOUT_S = 300
#: Smoke runs at once, in the background: one, the suite's own tests have the other core.
AT_ONCE = 1

#: Test files run by a second pytest process beside the suite's own when the whole suite
#: runs (``conftest``): each starts its own servers and subprocesses and shares no fixture
#: with the rest, and the suite alone keeps about one of the 2 cores busy.
PART = (
    "test_day.py",
    "test_live.py",
    "test_sle.py",
    "test_fuzz_files.py",
    "test_distributed.py",
    "test_hostile.py",
    "test_scenarios.py",
    "test_scene1a.py",
)
#: The second process's bound (s): about 9 minutes beside the suite; a hang fails.
PART_TIMEOUT_S = 1200

_runs: dict[str, Future[subprocess.CompletedProcess[str]]] = {}
_part: Future[subprocess.CompletedProcess[str]] | None = None
_pool: ThreadPoolExecutor | None = None
_root: Path | None = None


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


def start() -> None:
    """Every smoke run queued (once)."""
    global _pool, _root
    if _pool is not None:
        return
    _root = Path(tempfile.mkdtemp(prefix="bench-smoke-"))
    _pool = ThreadPoolExecutor(AT_ONCE, thread_name_prefix="bench-smoke")
    for p in BENCHMARKS:
        where = _root / p.stem
        where.mkdir()
        _runs[p.name] = _pool.submit(_smoke, p, where)


def _run_part(files: list[str], base: Path) -> subprocess.CompletedProcess[str]:
    env = os.environ | {"SPOT_TESTS_PART": "1"}
    cmd = [
        sys.executable,
        "-m",
        "pytest",
        "-q",
        "-p",
        "no:cacheprovider",
        "--basetemp",
        str(base / "tmp"),
        "--durations=8",
        *files,
    ]
    log = base / "part.log"
    try:
        with log.open("w") as out:
            rc = subprocess.run(
                cmd, cwd=ROOT, env=env, stdout=out, stderr=subprocess.STDOUT, timeout=PART_TIMEOUT_S
            ).returncode
    except subprocess.TimeoutExpired:
        rc = -9
    return subprocess.CompletedProcess(cmd, rc, log.read_text(), "")


def start_part(files: list[str]) -> None:
    """The :data:`PART` files' tests started in a pytest process of their own (once)."""
    global _part
    if _part is not None:
        return
    base = Path(tempfile.mkdtemp(prefix="pytest-part-"))
    _part = ThreadPoolExecutor(1, thread_name_prefix="pytest-part").submit(_run_part, files, base)
    _cleanup.append(base)


def part_result() -> subprocess.CompletedProcess[str] | None:
    """The second process's run, waited for (None: the files ran in this session)."""
    return None if _part is None else _part.result()


_cleanup: list[Path] = []


def result(name: str) -> subprocess.CompletedProcess[str]:
    """A benchmark's smoke run, waited for (started now if the suite did not)."""
    start()
    return _runs[name].result()


def stop() -> None:
    """The runs not started dropped, those running waited for, their directories removed."""
    global _pool
    if _pool is not None:
        _pool.shutdown(wait=True, cancel_futures=True)
        _pool = None
    if _root is not None:
        shutil.rmtree(_root, ignore_errors=True)
    if _part is not None:
        _part.result()
    for base in _cleanup:
        shutil.rmtree(base, ignore_errors=True)
