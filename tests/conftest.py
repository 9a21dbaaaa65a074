"""Shared test configuration: where the outside reference data live, and the small
scenario's run that several modules read."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

#: ../shared/refdata beside the repository, or $SPOT_REFDATA.
REFDATA = Path(
    os.environ.get("SPOT_REFDATA", Path(__file__).resolve().parents[2] / "shared" / "refdata")
)


def pytest_collection_modifyitems(
    session: pytest.Session, config: pytest.Config, items: list
) -> None:
    """When the whole suite runs: the :data:`_smokes.PART` files handed to a second pytest
    process, and the benchmarks' smoke runs started, both in the background as soon as the
    suite is collected (``tests/_smokes.py``); the tests that read them moved last. Their
    minutes overlap the rest of the suite's instead of adding to it."""
    bench = [i for i in items if i.path.name == "test_benchmarks.py"]
    if not bench or config.option.collectonly:
        return
    import _smokes

    if os.environ.get("SPOT_TESTS_PART") is None:
        part = [i for i in items if i.path.name in _smokes.PART]
        if part:
            config.hook.pytest_deselected(items=part)
            items[:] = [i for i in items if i.path.name not in _smokes.PART]
            _smokes.start_part(sorted({str(i.path) for i in part}))
    last = {id(i) for i in items if i.path.name in ("test_benchmarks.py", "test_part.py")}
    items[:] = [i for i in items if id(i) not in last] + [i for i in items if id(i) in last]
    _smokes.start()


def pytest_terminal_summary(terminalreporter: pytest.TerminalReporter) -> None:
    """The second part's slowest tests and its count and time, after the suite's own."""
    import sys

    smokes = sys.modules.get("_smokes")
    run = smokes.part_result() if smokes is not None else None
    if run is None:
        return
    lines = run.stdout.splitlines()
    start = next((k for k, ln in enumerate(lines) if "slowest" in ln), len(lines) - 1)
    terminalreporter.write_sep("=", "the second part (tests/_smokes.PART)")
    for ln in [*lines[start + 1 : start + 9], lines[-1]] if lines else []:
        terminalreporter.write_line(ln)


def pytest_sessionfinish(session: pytest.Session, exitstatus: int) -> None:
    import sys

    smokes = sys.modules.get("_smokes")
    if smokes is not None:
        smokes.stop()


@pytest.fixture(scope="session")
def refdata() -> Path:
    if not (REFDATA / "dimap").is_dir():
        pytest.fail(
            f"reference data not found at {REFDATA}: clone beside shared/ or set SPOT_REFDATA"
        )
    return REFDATA


@pytest.fixture(scope="session")
def run_dir(tmp_path_factory) -> Path:
    """``scenarios/small_test.toml`` run once by the station's command in a process of its
    own (no quicklooks): the files a station records, which tests read (``levels``' among
    them, as any user of the library reads a station's output), or copy before they change
    anything in it."""
    import subprocess
    import sys

    root = Path(__file__).resolve().parents[1]
    out = tmp_path_factory.mktemp("run") / "small"
    command = [
        sys.executable,
        "-m",
        "station.cli",
        "run",
        str(root / "scenarios" / "small_test.toml"),
    ]
    subprocess.run(
        [*command, "--out", str(out), "--quiet", "--no-quicklooks"], check=True, timeout=600
    )
    return out
