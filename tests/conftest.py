"""Shared test configuration: where the outside reference data live."""

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
