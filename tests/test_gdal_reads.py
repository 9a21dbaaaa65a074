"""Products as GDAL reads them, as written: no export step. A map product (``.nc``) opens
georeferenced as its GeoTIFF export does; a 1A (``.h5``) carries its RPCs where GDAL finds
them (a PAM sidecar beside the product), and GDAL's RPC orthorectification of it over the
run's DEM lands on our level 3 over relief."""

from __future__ import annotations

import re
import warnings
from pathlib import Path

import numpy as np
import pytest

from levels.products import read_product
from levels.quality import image_shift_px
from station.cli import main

ROOT = Path(__file__).resolve().parents[1]
#: The issue's figure: GDAL's warp of our 1A over the DEM against our level 3, per tile.
GDAL_VS_LEVEL3_PX = 0.1
#: Tiles (output pixels) whose shift is measured: big enough for the phase correlation,
#: small enough that the relief's displacement varies from one to the next.
TILE_PX = 64
#: Over flat ground at the reference height instead of the DEM, the same warp misses the
#: relief's displacement: its tiles must scatter by more than this (the test can tell).
FLAT_SCATTER_PX = 0.3

SCENARIO = """
name = "relief"
seed = 1000
[attitude]
roll_offset_urad = 0.0
pitch_offset_urad = 0.0
yaw_offset_urad = 0.0
drift_scale = 0.0
jitter_amplitude_urad = [0.0, 0.0, 0.0]
[bulletins]
bias_m = [0.0, 0.0, 0.0]
drift_m_per_s = [0.0, 0.0, 0.0]
[instrument]
mirror_step = 93
calibration_error_urad = 0.0
n_detectors = 400
n_lines = 400
[world]
base_height_m = 700.0
relief_m = 400.0
[dem]
spacing_arcsec = 3.0
[downlink]
bit_rate_mbps = 2.0
preamble_s = 0.1
postamble_s = 0.1
[processing]
levels = ["1A", "2A", "3"]
reference_height_m = 700.0
"""


@pytest.fixture(scope="module")
def relief_run(tmp_path_factory) -> Path:
    """A reduced P scene at 27° over 400 m of fractal relief (150 m pixels: the relief
    moves pixels by up to about 1.6 px), errors off, its 1A and level 3 over the DEM the
    run exports."""
    d = tmp_path_factory.mktemp("relief")
    scn = d / "relief.toml"
    scn.write_text(SCENARIO)
    out = d / "run"
    assert main(["run", str(scn), "--out", str(out), "-q", "--no-quicklooks"]) == 0
    return out


def _open(spec: str):
    import rasterio

    with warnings.catch_warnings():  # the netCDF driver's notes on the HDF5 groups
        warnings.simplefilter("ignore")
        return rasterio.open(spec)


def _warp(src_spec: str, grid, **options) -> np.ndarray:
    """GDAL's RPC warp (``gdalwarp -rpc``, cubic) of the product's band onto ``grid``."""
    import rasterio.warp
    from affine import Affine
    from rasterio.enums import Resampling

    out = np.zeros(grid.shape, dtype=np.float32)
    with _open(src_spec) as ds:
        assert ds.rpcs is not None, "GDAL finds no RPCs on the product"
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            rasterio.warp.reproject(
                rasterio.band(ds, 1),
                out,
                rpcs=ds.rpcs,
                src_crs="EPSG:4326",
                dst_transform=Affine.from_gdal(*grid.geotransform),
                dst_crs=grid.crs_wkt,
                resampling=Resampling.cubic,
                dst_nodata=0,
                **options,
            )
    return out


def _tile_shifts(ours: np.ndarray, valid: np.ndarray, theirs: np.ndarray) -> np.ndarray:
    """The (rows, columns) shift of every full tile where both images are valid."""
    shifts = []
    for r in range(0, ours.shape[0] - TILE_PX + 1, TILE_PX):
        for c in range(0, ours.shape[1] - TILE_PX + 1, TILE_PX):
            win = (slice(r, r + TILE_PX), slice(c, c + TILE_PX))
            both = valid[win] & (theirs[win] > 0)
            if both.all():
                shifts.append(image_shift_px(ours[win], theirs[win], both))
    return np.array(shifts)


def test_gdal_finds_the_rpcs_of_a_1a_as_written(relief_run) -> None:
    """The netCDF and the HDF5 drivers both find the band's RPCs in the sidecar;
    ERR_RAND is the fit's RMS in metres on the ground (RPC00B), not in pixels: the RMS in
    pixels times the ground sample the RPC itself gives (150 m across at nadir for this
    reduced P scene, more at 27°)."""
    from levels.geo.rpc import Rpc

    path = relief_run / "relief_s000_1A.h5"
    rpc = Rpc.from_tree(read_product(path).geometry["rpc"]["P"])
    gsd = rpc.ground_sample_m()
    assert 150.0 < gsd < 200.0
    for spec in (f'NETCDF:"{path}":P', f'HDF5:"{path}"://P'):
        with _open(spec) as ds:
            assert ds.rpcs is not None and ds.rpcs.line_off == pytest.approx(rpc.line_off)
            assert ds.rpcs.err_rand == pytest.approx(rpc.fit_error_px["rms_px"] * gsd)
    with _open(f'HDF5:"{path}"://P') as ds:  # the HDF5 driver reads the image as stored
        assert np.array_equal(ds.read(1), read_product(path).bands["P"].image)


def test_gdal_orthorectifies_the_1a_as_written_onto_level_3(relief_run) -> None:
    """``gdalwarp -rpc -to RPC_DEM=relief.dem.tif`` of the 1A product itself onto the level
    3 grid: every tile within 0.1 px of our level 3; over flat ground instead of the DEM,
    the tiles scatter (the relief's displacement), so the comparison can tell."""
    l3 = read_product(relief_run / "relief_s000_3.nc")
    grid, band = l3.map_grid, l3.bands["P"]
    assert grid is not None
    # the HDF5 driver (GDAL's own for .h5): the netCDF driver reads an image without a
    # decreasing y coordinate bottom-up, a 1A upside down
    src = f'HDF5:"{relief_run / "relief_s000_1A.h5"}"://P'
    dem = relief_run / "relief.dem.tif"
    on_dem = _tile_shifts(band.image, band.valid, _warp(src, grid, RPC_DEM=str(dem)))
    assert len(on_dem) >= 12
    assert np.max(np.hypot(*on_dem.T)) <= GDAL_VS_LEVEL3_PX
    flat = _tile_shifts(band.image, band.valid, _warp(src, grid, RPC_HEIGHT=700.0))
    assert np.ptp(flat, axis=0).max() > FLAT_SCATTER_PX


@pytest.mark.parametrize("level", ["2A", "3"])
def test_gdal_opens_a_map_product_as_written(level, relief_run, tmp_path) -> None:
    """``gdalinfo relief_s000_3.nc``: GDAL's netCDF driver takes the file, its image band
    the first subdataset (``NETCDF:"relief_s000_3.nc":P``), georeferenced: the CRS and the
    transform of the product's GeoTIFF export (and of its own map grid), the image as
    stored."""
    from rasterio.crs import CRS

    from levels.export import OVERVIEW_MIN_PX, write_geotiff

    path = relief_run / f"relief_s000_{level}.nc"
    product = read_product(path)
    with _open(str(path)) as ds:
        assert ds.driver == "netCDF"
        first = ds.subdatasets[0]
    assert first.lower().startswith("netcdf:") and first.endswith(":P")
    tif = write_geotiff(product, tmp_path / f"{level}.tif")
    with _open(first) as band, _open(str(tif)) as exported:
        assert band.crs == exported.crs == CRS.from_wkt(product.map_grid.crs_wkt)
        assert band.transform.almost_equals(exported.transform, precision=1e-9)
        assert band.transform.to_gdal() == pytest.approx(product.map_grid.geotransform)
        assert np.array_equal(band.read(1), product.bands["P"].image)
        # overviews down to 256 px (a viewer shows the scene from them): of the image and
        # of its mask; counts averaged
        n = max(exported.shape)
        want = [2**k for k in range(1, 12) if n // 2**k >= OVERVIEW_MIN_PX]
        assert exported.overviews(1) == want and want
        assert exported.tags(ns="rio_overview")["resampling"] == "average"


#: OTB's ground spacing from the sensor model against the product's pixel: the 1B's plane
#: is 200 m a pixel on the small scene; OTB estimates it from the RPC at the image centre
#: (199.9 × 200.9 m measured): 2 %.
OTB_SPACING_REL = 0.02


@pytest.mark.parametrize("level", ["1A", "1B"])
def test_an_image_geometry_export_carries_its_rpcs_for_otb(level, run_dir, tmp_path) -> None:
    """Beside a 1A or 1B GeoTIFF, the OSSIM keyword list OTB 8 reads (it takes RPC tags only
    from its own GeoTIFFs): every key OTB's GeomMetadataSupplier reads, split as it splits
    (``key: value``, no empty line), equal to the GeoTIFF's RPC tags; where OTB is installed
    (Debian's otb-bin), ``otbcli_ReadImageInfo`` finds the sensor model (its ground spacing
    the product's pixel), which it does not without the file."""
    import shutil
    import subprocess

    from levels.export import write_geotiff

    product = read_product(run_dir / f"small_test_s000_{level}.h5")
    tif = write_geotiff(product, tmp_path / f"{level}.tif")
    geom = tif.with_suffix(".geom")
    lines = geom.read_text().splitlines()
    assert all(":" in ln for ln in lines)  # OTB splits every line on ':'
    kv = {k.strip(): v.strip() for k, v in (ln.split(":", 1) for ln in lines)}
    assert kv["type"] == "ossimRpcModel" and kv["polynomial_format"] == "B"
    with _open(str(tif)) as ds:
        rpc = ds.rpcs.to_gdal()
    for key in ("LINE_OFF", "SAMP_OFF", "LAT_OFF", "LONG_OFF", "HEIGHT_OFF", "LINE_SCALE",
                "SAMP_SCALE", "LAT_SCALE", "LONG_SCALE", "HEIGHT_SCALE"):  # fmt: skip
        assert float(kv[key.lower()]) == pytest.approx(float(rpc[key]), rel=1e-12)
    for key in ("LINE_NUM_COEFF", "LINE_DEN_COEFF", "SAMP_NUM_COEFF", "SAMP_DEN_COEFF"):
        ours = [float(kv[f"{key.lower()}_{k:02d}"]) for k in range(20)]
        assert ours == pytest.approx([float(c) for c in rpc[key].split()], rel=1e-12)
    otb = shutil.which("otbcli_ReadImageInfo")
    if otb is None:
        pytest.skip("OTB not installed (Debian's otb-bin): the keyword list checked alone")
    said = subprocess.run([otb, "-in", str(tif)], capture_output=True, text=True, timeout=120)
    assert said.returncode == 0, said.stderr
    out = said.stdout + said.stderr
    assert "compatible Sensor Transform" not in out
    spacing = [float(v) for v in re.findall(r"estimatedgroundspacing[xy]: ([\d.]+)", out)]
    pixel = 200.0  # the small scene's: 10 m × 6000 / 300 detectors
    assert spacing and all(abs(s / pixel - 1.0) <= OTB_SPACING_REL for s in spacing), spacing


def test_a_products_own_rpc_sidecar_as_gdal_reads_it(run_dir) -> None:
    """A 1A product's RPCs through GDAL's HDF5 driver (its ``.aux.xml``), as written."""
    import numpy as np

    from levels.geo.rpc import Rpc
    from levels.products import read_product
    from levels.readers.rpc import read_gdal_rpc

    product = run_dir / "small_test_s000_1A.h5"
    ours = Rpc.from_tree(read_product(product).geometry["rpc"]["P"])
    gdal = read_gdal_rpc(f'HDF5:"{product}"://P')
    rng = np.random.default_rng(3)
    lat = ours.lat_off + ours.lat_scale * rng.uniform(-0.9, 0.9, 1000)
    lon = ours.lon_off + ours.lon_scale * rng.uniform(-0.9, 0.9, 1000)
    h = rng.uniform(0.0, 1500.0, 1000)
    (la, sa), (lb, sb) = ours.image_of(lat, lon, h), gdal.image_of(lat, lon, h)
    assert max(np.abs(la - lb).max(), np.abs(sa - sb).max()) <= 1e-6  # round-off only
