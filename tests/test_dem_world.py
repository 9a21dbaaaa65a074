"""A real DEM as the emulated terrain: the SRTM tile of refdata (Gabon, N00E010)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.interpolate import RegularGridInterpolator

from station.scenario import scenario_from_dict
from station.spacecraft.emulator import emulate, truth_model
from station.spacecraft.hgt import DemError, read_hgt
from station.spacecraft.imaging import HEIGHT_TOL_M, trace_pixels

REPROJECTION_TOL_PX = 0.01


@pytest.fixture(scope="module")
def tile(refdata: Path) -> Path:
    return refdata / "dem" / "N00E010.hgt"


def test_read_hgt_orientation_and_voids(tile: Path) -> None:
    dem = read_hgt(tile)
    raw = np.fromfile(tile, dtype=">i2").reshape(1201, 1201)
    assert dem.height_m.shape == (1201, 1201)
    assert dem.lat_rad[0] == 0.0 and np.degrees(dem.lat_rad[-1]) == pytest.approx(1.0)
    assert np.degrees(dem.lon_rad[0]) == pytest.approx(10.0)
    assert dem.height_m[-1, 0] == raw[0, 0]  # the file's first row is the north edge
    assert dem.height_m[0, -1] == raw[-1, -1]
    finite = dem.height_m[np.isfinite(dem.height_m)]
    assert 0 <= finite.min() and finite.max() < 1500  # western Gabon: coast to low hills


def test_read_hgt_errors(tmp_path: Path, tile: Path) -> None:
    (tmp_path / "dem.bin").write_bytes(b"")
    with pytest.raises(DemError, match=r"named like N00E010\.hgt"):
        read_hgt(tmp_path / "dem.bin")
    cut = tmp_path / "N00E010.hgt"
    cut.write_bytes(tile.read_bytes()[:-2])
    with pytest.raises(DemError, match="truncated"):
        read_hgt(cut)
    with pytest.raises(DemError, match="not found"):
        read_hgt(tmp_path / "S10W050.hgt")


def test_imaging_over_a_real_dem(tile: Path) -> None:
    scn = scenario_from_dict(
        {
            "world": {"kind": "dem", "dem_path": str(tile)},
            "pass": {"target_lat_deg": 0.5, "target_lon_deg": 10.5, "ground_pass_days": 0.0},
            "instrument": {"n_detectors": 200, "n_lines": 200, "psf_samples": 1},
        }
    )
    acq = emulate(scn)
    assert not acq.bands[0].failed.any()
    rng = np.random.default_rng(8)
    line, col = rng.uniform(0, 199, 300), rng.uniform(0, 199, 300)
    t = acq.line_times_s[0] + line * acq.hrv.line_period_s
    pts, ok = trace_pixels(acq.orbit, acq.attitude, acq.hrv.bands[0], acq.world, t, col)
    assert ok.all()
    # each ground point is on the DEM, bilinearly interpolated (scipy as the reference)
    dem = read_hgt(tile)
    ref = RegularGridInterpolator((dem.lat_rad, dem.lon_rad), dem.height_m)(pts[:, :2])
    assert np.abs(pts[:, 2] - ref).max() < HEIGHT_TOL_M
    back = truth_model(acq).ground_to_image(pts[:, 0], pts[:, 1], pts[:, 2])
    assert np.abs(back.line - line).max() < REPROJECTION_TOL_PX
    assert np.abs(back.column - col).max() < REPROJECTION_TOL_PX
