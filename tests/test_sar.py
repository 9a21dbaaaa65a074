"""SAR geocoding (issue 38): an ERS-1 frame emulated in slant range (``station.spacecraft.
sar``), located and geocoded by range–Doppler (``levels.sar``), against the truth.

The frames are reduced (150 × 150 samples of 5 azimuth and 2 range looks: about 20 m ×
16 m in slant range, the swath's true geometry), over a flat world and over the fractal
world's relief (700 m RMS). Tolerances are named below with what was measured.
"""

from __future__ import annotations

import numpy as np
import pyproj
import pytest

from levels.geo.inverse_grid import bilinear_grid, invert_by_newton
from levels.sar import Geocoded, frame_grid, geocode
from station.spacecraft.dem import world_dem
from station.spacecraft.sar import ErsFrame, SarTruth, emulate_frame
from station.spacecraft.world import World

#: Ground → image against the truth's own solution on the integrated orbit (the issue's
#: 1e-3 px; measured 7e-9 px: the annotation's state vectors every 10 s, Lagrange).
LOCATION_PX = 1e-3
#: Checkpoints of GEC on a flat world and of GTC over relief with the exact DEM, in output
#: pixels (the issue's 0.1 px; measured 0.002 and 0.004 px RMS).
CHECKPOINT_PX = 0.1
#: GEC over relief: each checkpoint's displacement against Δh / tan θ (measured within
#: 0.3 %: the rest is the Earth's curvature over the displacement).
RELIEF_DISPLACEMENT_REL = 0.01
#: The reduced frames' lines and samples.
FRAME = 150
#: The output grid's pixel (m): about the reduced frame's ground range sample.
PIXEL_M = 25.0
LON0 = np.radians(-56.1)


@pytest.fixture(scope="module")
def flat() -> tuple:
    world = World(lon0_rad=LON0, base_height_m=200.0, relief_m=0.0, seed=3)
    image, truth = emulate_frame(ErsFrame(n_lines=100, n_samples=100), world)
    return image, truth, world


@pytest.fixture(scope="module")
def rugged() -> tuple:
    world = World(lon0_rad=LON0, base_height_m=200.0, relief_m=400.0, seed=3)
    image, truth = emulate_frame(ErsFrame(n_lines=FRAME, n_samples=FRAME), world)
    return image, truth, world


@pytest.fixture(scope="module")
def gtc(rugged) -> tuple:
    """GTC of the rugged frame over the world's own terrain (a 0.0001° DEM of it)."""
    image, _, world = rugged
    lat0 = np.radians(-15.6)
    dem = world_dem(
        world, (lat0 - 0.003, lat0 + 0.003), (LON0 - 0.004, LON0 + 0.004), 1e-4, 0.0,
        np.random.default_rng(0),
    )  # fmt: skip
    grid = frame_grid(image.annotation, PIXEL_M, world.base_height_m)
    return grid, geocode(image, grid, dem=dem)


def _checkpoints(
    g: Geocoded, truth: SarTruth, world: World, n: int = 200
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Where the product puts terrain points (output pixels) minus where they are, and
    their heights and incidence: the truth's (line, column) of each point taken back onto
    the output grid through the product's own per-pixel (line, column)."""
    rng = np.random.default_rng(1)
    grid = g.grid
    i = rng.uniform(20, grid.n_rows - 20, n)
    j = rng.uniform(20, grid.n_cols - 20, n)
    x, y = grid.map_of(i, j)
    lon, lat = pyproj.Transformer.from_crs(grid.crs_wkt, "EPSG:4326", always_xy=True).transform(
        x, y
    )
    lat, lon = np.radians(lat), np.radians(lon)
    h, _, _ = world.height(lat, lon)
    lt, ct = truth.image_of(lat, lon, h)
    n_l, n_s = truth.annotation.shape
    ok = (lt > 1) & (lt < n_l - 2) & (ct > 1) & (ct < n_s - 2)
    rows = np.arange(grid.n_rows, dtype=np.float64)
    cols = np.arange(grid.n_cols, dtype=np.float64)

    def raw_of(ii: np.ndarray, jj: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return bilinear_grid(rows, cols, g.line, ii, jj), bilinear_grid(
            rows, cols, g.column, ii, jj
        )

    gi, gj = invert_by_newton(raw_of, lt[ok], ct[ok], (i[ok], j[ok]), 8)
    inc = truth.annotation.incidence(lat[ok], lon[ok], h[ok])
    return gi - i[ok], gj - j[ok], h[ok], inc


def test_pixel_location_is_the_truths(rugged) -> None:
    """Ground → (line, column) by the annotation's state vectors against the truth's
    solution on the integrated orbit; image → ground → image comes back."""
    image, truth, _ = rugged
    ann = image.annotation
    rng = np.random.default_rng(0)
    line, col = rng.uniform(0, FRAME - 1, 300), rng.uniform(0, FRAME - 1, 300)
    h = rng.uniform(-200.0, 1500.0, 300)
    lat, lon = ann.ground_of_image(line, col, h)
    back_l, back_c = ann.image_of(lat, lon, h)
    np.testing.assert_allclose(back_l, line, atol=1e-6)
    np.testing.assert_allclose(back_c, col, atol=1e-6)
    true_l, true_c = truth.image_of(lat, lon, h)
    assert np.max(np.hypot(back_l - true_l, back_c - true_c)) <= LOCATION_PX


def test_gec_on_a_flat_world_lands_on_the_truth(flat) -> None:
    image, truth, world = flat
    grid = frame_grid(image.annotation, PIXEL_M, world.base_height_m)
    gec = geocode(image, grid, reference_height_m=world.base_height_m)
    assert gec.kind == "GEC" and gec.anchor_error["max_px"] < 0.01
    di, dj, _, _ = _checkpoints(gec, truth, world)
    assert di.size > 100
    assert np.sqrt(np.mean(di**2 + dj**2)) <= CHECKPOINT_PX
    assert np.isfinite(gec.intensity).mean() > 0.5
    assert not gec.layover.any() and not gec.shadow.any()  # the ellipsoid folds nowhere


def test_gtc_with_the_exact_dem_lands_on_the_truth_and_gec_moves_by_the_relief(rugged, gtc) -> None:
    """GTC over the world's own terrain puts every checkpoint on the truth; GEC at the
    reference height moves each by Δh / tan θ, toward the radar."""
    image, truth, world = rugged
    grid, gtc = gtc
    di, dj, _, _ = _checkpoints(gtc, truth, world)
    assert di.size > 100
    assert np.sqrt(np.mean(di**2 + dj**2)) <= CHECKPOINT_PX
    gec = geocode(image, grid, reference_height_m=world.base_height_m)
    di, dj, h, inc = _checkpoints(gec, truth, world)
    moved_m = np.hypot(di, dj) * PIXEL_M
    predicted_m = np.abs(h - world.base_height_m) / np.tan(inc)
    big = predicted_m > 10 * PIXEL_M
    assert big.sum() > 20
    np.testing.assert_allclose(moved_m[big], predicted_m[big], rtol=RELIEF_DISPLACEMENT_REL)


def test_a_fold_in_range_is_layover_and_a_ridge_casts_shadow() -> None:
    """``layover_and_shadow`` on one profile of 40 points 25 m apart: the slant range grows
    with the ground range except over a slope steeper than the incidence, where it folds
    back (points 10–14): the cells it folds over hold two patches; the look angle drops
    behind a ridge (points 30–32): shadow. A flat profile has neither."""
    from levels.sar import layover_and_shadow

    g = np.arange(40, dtype=np.float64)
    col = g * 1.6  # 1.6 range samples a point on open ground
    col[10:15] = col[9] - np.arange(1, 6) * 0.9  # folds back over samples of points 6–9
    col[15:] -= 9.0
    look = 0.4 + g * 1e-5
    look[30:33] = look[29] - 2e-5
    line = np.zeros(40)
    gap = 60.0 / 840e3
    layover, shadow = layover_and_shadow(line, col, look, g, 1.0, 1e-9, gap)
    assert shadow[30:33].all() and shadow.sum() == 3
    assert layover[10:15].any() and layover[5:10].any()  # both patches of a folded cell
    assert not layover[:4].any() and not layover[20:].any()
    flat_l, flat_s = layover_and_shadow(line, g * 1.6, 0.4 + g * 1e-5, g, 1.0, 1e-9, gap)
    assert not flat_l.any() and not flat_s.any()


def test_a_gtc_product_opens_georeferenced_in_gdal(rugged, gtc, tmp_path) -> None:
    """The GTC as a product of the house format: read back equal, compared with itself
    within every tolerance, opened by GDAL with its CRS and transform, as written and as
    its GeoTIFF export."""
    import rasterio

    from levels.compare import compare_products
    from levels.export import write_geotiff
    from levels.products import read_product, write_product
    from levels.sar import sar_product

    image = rugged[0]
    grid, geocoded = gtc
    product = sar_product(geocoded, image, "ers_test", dem_source="world")
    path = write_product(tmp_path / "ers_test_GTC.nc", product)
    back = read_product(path)
    assert back.level == "GTC" and set(back.bands) == {"intensity", "layover", "shadow"}
    np.testing.assert_array_equal(back.bands["intensity"].image, product.bands["intensity"].image)
    assert "ERS-1" in back.attrs["title"]
    again = write_product(tmp_path / "again_GTC.nc", product)
    assert not [f for f in compare_products(back, read_product(again)) if f.ok is False]
    with rasterio.open(f'NETCDF:"{path}":intensity') as ds:
        assert ds.crs is not None and ds.crs.to_wkt()
        assert ds.transform.to_gdal() == pytest.approx(grid.geotransform)
    tif = write_geotiff(back, tmp_path / "ers_test_GTC.tif")
    with rasterio.open(tif) as ds:
        assert ds.count == 3 and ds.transform.to_gdal() == pytest.approx(grid.geotransform)
        np.testing.assert_array_equal(ds.read(1), product.bands["intensity"].image)
