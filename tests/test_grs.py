"""SPOT's Grid Reference System against real scenes' ``GRID_REFERENCE`` (``station.grs``)."""

from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np
import pytest

from station.grs import kj_of

#: ../shared/refdata beside the repository, or $SPOT_REFDATA (as ``conftest.REFDATA``).
DIMAP = (
    Path(os.environ.get("SPOT_REFDATA", Path(__file__).resolve().parents[2] / "shared" / "refdata"))
    / "dimap"
)
#: The row as SPOT gives it (J and the shift's tenths) against the model's: the four
#: scenes' spread about one origin (``station.grs``'s docstring), a tenth of a row (5 km).
ROW_TOLERANCE = 0.15


def _frames() -> list[tuple[str, int, int, int, float, float]]:
    out = []
    for f in sorted(DIMAP.glob("*.DIM")):
        s = f.read_text(errors="replace")
        grid = re.search(r"<GRID_REFERENCE>(\d{3})(\d{3})", s)
        shift = re.search(r"<SHIFT_VALUE>(-?\d+)", s)
        centre = re.search(
            r"<Scene_Center>.*?<FRAME_LON>([^<]+)</FRAME_LON>\s*<FRAME_LAT>([^<]+)", s, re.S
        )
        if grid and shift and centre:
            k, j = int(grid.group(1)), int(grid.group(2))
            out.append((f.name, k, j, int(shift.group(1)), float(centre.group(2)),
                        float(centre.group(1))))  # fmt: skip
    return out


FRAMES = _frames()


def test_the_real_scenes_are_there() -> None:
    assert len(FRAMES) >= 4, f"the real SPOT scenes' metadata are not in {DIMAP}"


@pytest.mark.parametrize("frame", FRAMES, ids=[f[0][:28] for f in FRAMES])
def test_real_scenes_are_at_their_grid_reference(frame: tuple) -> None:
    """Every real scene's K, and its row within a tenth and a half; the constants were
    fitted on the Izmit scene alone, the three others held out."""
    _name, k, j, shift, lat, lon = frame
    got_k, got_j, row = kj_of(lat, lon)
    assert int(got_k) == k
    assert abs(float(row) - (j + shift / 10)) <= ROW_TOLERANCE
    assert abs(int(got_j) - j) <= 1


def test_the_grid_is_laid_as_described() -> None:
    """Rows 200 and 500 at ±71.42907°, J = 350 ± the origin at the equator; K = 2N − 1 west
    and 2N east of each track; 738 columns round the equator."""
    _, _, north = kj_of(71.42907, 0.0)
    _, _, south = kj_of(-71.42907, 0.0)
    assert south - north == pytest.approx(300.0, abs=1e-6)
    lon = np.linspace(0, 360, 7381, endpoint=False)
    k, _, _ = kj_of(np.zeros_like(lon), lon)
    assert set(np.unique(k)) == set(range(1, 739))
    assert np.all(np.isin(np.diff(k) % 738, (0, 1)))  # eastward, one column at a time
