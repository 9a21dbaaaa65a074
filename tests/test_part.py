"""The suite's second part (``tests/_smokes.py``: :data:`_smokes.PART`): when the whole
suite runs, those files run in a pytest process of their own beside it, and this test says
whether every one of their tests passed, with the failures' lines."""

from __future__ import annotations

import pytest
from _smokes import PART, part_result


def test_the_files_run_beside_the_suite_pass() -> None:
    run = part_result()
    if run is None:
        pytest.skip(f"{', '.join(PART)}: run in this session (no second process)")
    lines = run.stdout.splitlines()
    failures = [ln for ln in lines if ln.startswith(("FAILED", "ERROR"))]
    said = "\n".join(failures or lines[-60:])
    assert run.returncode == 0, f"the second part exited {run.returncode}:\n{said}"
    assert any(" passed" in ln for ln in lines[-3:]), said
