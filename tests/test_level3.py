"""Level 3: DEMs as users have them, and the orthorectification against the truth."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from levels.geo.level2a import level2a_geometry
from levels.geo.level3 import ANCHOR_TOLERANCE_PX, level3_geometry
from levels.geo.maps import map_crs
from levels.readers.dem import DemError, egm96_grid_installed, read_dem
from station.scenario import ERRORS_OFF, merge_tables, scenario_from_dict
from station.sipc.process import emulated_scene
from station.sipc.truth import Truth, checkpoints_2a, checkpoints_3
from station.spacecraft.dem import read_hgt
from station.spacecraft.emulator import emulate

#: The issue's figures for an exact DEM with the errors off: RMS and max (output pixels).
EXACT_RMS_PX, EXACT_MAX_PX = 0.1, 0.3


@pytest.fixture(scope="module")
def srtm_path(refdata) -> Path:
    return refdata / "dem" / "N00E010.hgt"


def test_dems_in_the_formats_a_station_is_handed(refdata, srtm_path) -> None:
    SRTM = srtm_path
    REFDATA = refdata
    srtm = read_dem(SRTM, "ellipsoid")
    assert srtm.height_m.shape == (1201, 1201)
    assert srtm.spacing == pytest.approx((1 / 1200, 1 / 1200))
    # the same bilinear surface as the emulator's reader of the tile
    grid = read_hgt(SRTM)
    lat, lon = np.radians([0.5, 0.2501, 0.9]), np.radians([10.5, 10.7502, 10.1])
    from scipy.interpolate import RegularGridInterpolator

    ref = RegularGridInterpolator((grid.lat_rad, grid.lon_rad), grid.height_m)
    assert srtm.heights(lat, lon) == pytest.approx(ref(np.stack([lat, lon], axis=-1)), abs=1e-9)
    assert np.isnan(srtm.heights(np.radians([1.5]), np.radians([10.5])))[0]  # outside
    dted = read_dem(REFDATA / "dem" / "n43.dt0", "ellipsoid")
    assert dted.height_m.shape == (121, 121) and dted.void_fraction == 0.0
    etopo = read_dem(REFDATA / "dem" / "ETOPO1_Ice_g_geotiff.resampled-1deg.tif", "ellipsoid")
    assert etopo.heights(np.radians([27.99]), np.radians([86.93]))[0] > 3000.0  # Himalaya


def test_dem_errors_are_clear(tmp_path, srtm_path) -> None:
    SRTM = srtm_path
    with pytest.raises(DemError, match="not found"):
        read_dem(tmp_path / "none.tif", "ellipsoid")
    with pytest.raises(DemError, match="vertical datum"):
        read_dem(SRTM, "geoid")
    junk = tmp_path / "junk.tif"
    junk.write_bytes(b"not a raster")
    with pytest.raises(DemError, match="not a raster"):
        read_dem(junk, "ellipsoid")


def test_egm96_heights_need_the_geoid_grid(srtm_path) -> None:
    """EGM96 heights are turned into ellipsoidal ones through PROJ's grid; without the grid,
    a clear error instead of PROJ's silent null 'ballpark' shift."""
    SRTM = srtm_path
    dem = read_dem(SRTM, "egm96")
    if egm96_grid_installed():
        h = dem.heights(np.radians([0.5]), np.radians([10.5]))
        # EGM96's undulation over Gabon is about +10 m
        assert h[0] - read_dem(SRTM, "ellipsoid").heights(np.radians([0.5]), np.radians([10.5]))[
            0
        ] == pytest.approx(10.0, abs=6.0)
    else:
        with pytest.raises(DemError, match=r"us_nga_egm96_15\.tif"):
            dem.heights(np.radians([0.5]), np.radians([10.5]))


@pytest.fixture(scope="module")
def rugged(srtm_path) -> tuple:
    """The mirror at 27° over the real SRTM tile, errors off, a reduced P scene (1000
    detectors: 60 m pixels over the same swath); the tile is the world and the DEM."""
    scn = scenario_from_dict(
        merge_tables(
            ERRORS_OFF,
            {
                "name": "l3",
                "pass": {"target_lat_deg": 0.5, "target_lon_deg": 10.5},
                "instrument": {"mirror_step": 93, "n_detectors": 1000, "n_lines": 1000},
                "world": {"kind": "dem", "dem_path": str(srtm_path)},
            },
        )
    )
    acq = emulate(scn, render=False)
    _pg, scene, res = emulated_scene(acq)
    return acq, scene, res


def test_level_3_puts_pixels_on_the_terrain(rugged, srtm_path) -> None:
    acq, scene, res = rugged
    crs = map_crs("utm", scene.centre_lat_rad, scene.centre_lon_rad, None)
    geom = level3_geometry(scene, read_dem(srtm_path, "ellipsoid"), res, crs)
    assert geom.anchor_error_px["max_px"] <= ANCHOR_TOLERANCE_PX
    assert geom.heights_m[0] < 100.0 and geom.heights_m[-1] > 900.0  # the tile's relief
    truth = Truth(acq, 0)
    c3 = checkpoints_3(truth, scene, geom, 0, 31)["ground"]
    c2 = checkpoints_2a(truth, scene, level2a_geometry(scene, res, crs), 0, 31)["ground"]
    assert c3["n_points"] > 900
    assert c3["rms_px"] <= EXACT_RMS_PX and c3["max_px"] <= EXACT_MAX_PX
    # 2A at the same points carries the relief displacement: h·tan θ off its surface
    assert c2["rms_px"] > 10 * EXACT_RMS_PX
