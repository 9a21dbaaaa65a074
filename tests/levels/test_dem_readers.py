"""DEMs as a station is handed them (:mod:`levels.readers.dem`): SRTM, DTED and GeoTIFF
tiles read against their own samples, and their errors said clearly; EGM96 heights through
PROJ's grid or a clear error."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.interpolate import RegularGridInterpolator

from levels.readers.dem import DemError, egm96_grid_installed, read_dem


@pytest.fixture(scope="module")
def srtm_path(refdata) -> Path:
    return refdata / "dem" / "N00E010.hgt"


def test_dems_in_the_formats_a_station_is_handed(refdata, srtm_path) -> None:
    srtm = read_dem(srtm_path, "ellipsoid")
    assert srtm.height_m.shape == (1201, 1201)
    assert srtm.spacing == pytest.approx((1 / 1200, 1 / 1200))
    # the bilinear surface of the tile's own samples: big-endian int16 rows from the north,
    # 1/1200° apart from N00E010 (the SRTM format), interpolated here by scipy
    raw = np.fromfile(srtm_path, dtype=">i2").reshape(1201, 1201)[::-1].astype(np.float64)
    axis = np.radians(np.arange(1201) / 1200.0)
    ref = RegularGridInterpolator((axis, np.radians(10.0) + axis), raw)
    lat, lon = np.radians([0.5, 0.2501, 0.9]), np.radians([10.5, 10.7502, 10.1])
    assert srtm.heights(lat, lon) == pytest.approx(ref(np.stack([lat, lon], axis=-1)), abs=1e-9)
    assert np.isnan(srtm.heights(np.radians([1.5]), np.radians([10.5])))[0]  # outside
    dted = read_dem(refdata / "dem" / "n43.dt0", "ellipsoid")
    assert dted.height_m.shape == (121, 121) and dted.void_fraction == 0.0
    etopo = read_dem(refdata / "dem" / "ETOPO1_Ice_g_geotiff.resampled-1deg.tif", "ellipsoid")
    assert etopo.heights(np.radians([27.99]), np.radians([86.93]))[0] > 3000.0  # Himalaya


def test_dem_errors_are_clear(tmp_path, srtm_path) -> None:
    with pytest.raises(DemError, match="not found"):
        read_dem(tmp_path / "none.tif", "ellipsoid")
    with pytest.raises(DemError, match="vertical datum"):
        read_dem(srtm_path, "geoid")
    junk = tmp_path / "junk.tif"
    junk.write_bytes(b"not a raster")
    with pytest.raises(DemError, match="not a raster"):
        read_dem(junk, "ellipsoid")


def test_egm96_heights_need_the_geoid_grid(srtm_path) -> None:
    """EGM96 heights are turned into ellipsoidal ones through PROJ's grid; without the grid,
    a clear error instead of PROJ's silent null 'ballpark' shift."""
    dem = read_dem(srtm_path, "egm96")
    if egm96_grid_installed():
        h = dem.heights(np.radians([0.5]), np.radians([10.5]))
        # EGM96's undulation over Gabon is about +10 m
        assert h[0] - read_dem(srtm_path, "ellipsoid").heights(
            np.radians([0.5]), np.radians([10.5])
        )[0] == pytest.approx(10.0, abs=6.0)
    else:
        with pytest.raises(DemError, match=r"us_nga_egm96_15\.tif"):
            dem.heights(np.radians([0.5]), np.radians([10.5]))
