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


@pytest.fixture(scope="session")
def refdata() -> Path:
    if not (REFDATA / "dimap").is_dir():
        pytest.fail(
            f"reference data not found at {REFDATA}: clone beside shared/ or set SPOT_REFDATA"
        )
    return REFDATA


@pytest.fixture(scope="session")
def run_dir(tmp_path_factory) -> Path:
    """``scenarios/small_test.toml`` run once (no quicklooks): tests read it, or copy it
    before they change anything in it."""
    from station.cli import main

    scenario = Path(__file__).resolve().parents[1] / "scenarios" / "small_test.toml"
    out = tmp_path_factory.mktemp("run") / "small"
    assert main(["run", str(scenario), "--out", str(out), "--quiet", "--no-quicklooks"]) == 0
    return out
