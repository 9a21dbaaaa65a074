"""SAR geocoding (issue 38): an ERS-1 frame emulated in slant range (``station.spacecraft.
sar``), located and geocoded by range–Doppler (``levels.sar``), against the truth.

The frames are reduced (150 × 150 samples of 5 azimuth and 2 range looks: about 20 m ×
16 m in slant range, the swath's true geometry), over a flat world and over the fractal
world's relief (700 m RMS). Tolerances are named below with what was measured.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pyproj
import pytest

from levels.geo.maps import MapGrid
from levels.products import read_product
from levels.sar import frame_grid
from levels.sar.geocoding import Geocoded, geocode
from station.spacecraft.dem import world_dem
from station.spacecraft.sar import ErsFrame, SarTruth, emulate_frame
from station.spacecraft.world import DemGrid, World
from station.truth.sar import checkpoint_errors

#: Ground → image against the truth's own solution on the integrated orbit (the issue's
#: 1e-3 px; measured 7e-9 px: the annotation's state vectors every 10 s, Lagrange).
LOCATION_PX = 1e-3
#: Checkpoints of GEC on a flat world and of GTC over relief with the exact DEM, in output
#: pixels (the issue's 0.1 px; measured 0.002 and 0.004 px RMS).
CHECKPOINT_PX = 0.1
#: GEC over relief: each checkpoint's displacement against Δh / tan θ (measured within
#: 0.3 %: the rest is the Earth's curvature over the displacement).
RELIEF_DISPLACEMENT_REL = 0.01
#: Layover and shadow against the truth's (the issue's; measured 0.998 and 0.979 on the
#: ridges world at 25 m, layover 0.987 over the SRTM tile: the levels sample the terrain's
#: profiles, the truth bins their continuous edges).
MASK_IOU = 0.95
#: γ⁰ by terrain flattening against the world's reflectance where that is the terrain's
#: γ⁰, overall and in each sixth of the correction (means; measured 1.011 and within
#: 0.026 over the reduced SRTM frame, where σ⁰ on the ellipsoid spans 0.53–3.37: a cell's
#: texture averaged against its value at a pixel's centre, and the facets the output
#: pixels where the emulator's are twice as fine).
GAMMA0_REL = 0.05
#: The reduced frames' lines and samples.
FRAME = 150
#: The output grid's pixel (m): about the reduced frame's ground range sample.
PIXEL_M = 25.0
LON0 = np.radians(-56.1)
ROOT = Path(__file__).resolve().parents[1]


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


@pytest.fixture(scope="module")
def cliffs() -> tuple:
    """A 100 × 100 frame over ridges running north–south every 1.2 km (a 45° face towards
    the radar, east; an 80° cliff away from it; tops 150–450 m), the world a DEM of them
    every 0.0001°, and its GTC over that DEM on 25 m pixels."""
    lat0 = np.radians(-15.6)
    d = np.radians(1e-4)
    lat, lon = lat0 + np.arange(-300, 301) * d, LON0 + np.arange(-400, 401) * d
    x, y = np.meshgrid((lon - LON0) * 6.37e6 * np.cos(lat0), (lat - lat0) * 6.37e6)
    s = np.mod(x, 1200.0)
    face = np.clip((1200.0 - s) * np.tan(np.radians(45)), 0, None)
    cliff = np.clip((s - 200.0) * np.tan(np.radians(80)), 0, None)
    top = 300.0 + 150.0 * np.sin(y / 700.0)
    h = 200.0 + np.minimum(np.minimum(face, cliff), top)
    world = World(
        lon0_rad=LON0, base_height_m=200.0, relief_m=0.0, terrain_grid=DemGrid(lat, lon, h, 0.0)
    )
    image, truth = emulate_frame(ErsFrame(n_lines=100, n_samples=100), world, render=False)
    dem = world_dem(
        world, (lat[0], lat[-1]), (lon[0], lon[-1]), 1e-4, 0.0, np.random.default_rng(0)
    )
    grid = frame_grid(image.annotation, PIXEL_M, 350.0, 500.0)
    return image, truth, grid, geocode(image, grid, dem=dem)


def _checkpoints(g: Geocoded, truth: SarTruth) -> tuple:
    """Where the product puts terrain points minus where they are (output pixels), their
    heights and incidence (:func:`station.truth.sar.checkpoint_errors`, what a run reports)."""
    cp = checkpoint_errors(g, truth)
    return cp["di"], cp["dj"], cp["height_m"], cp["incidence_rad"]


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
    di, dj, _, _ = _checkpoints(gec, truth)
    assert di.size > 100
    assert np.sqrt(np.mean(di**2 + dj**2)) <= CHECKPOINT_PX
    assert np.isfinite(gec.intensity).mean() > 0.5
    assert not gec.layover.any() and not gec.shadow.any()  # the ellipsoid folds nowhere


def test_gtc_with_the_exact_dem_lands_on_the_truth_and_gec_moves_by_the_relief(rugged, gtc) -> None:
    """GTC over the world's own terrain puts every checkpoint on the truth; GEC at the
    reference height moves each by Δh / tan θ, toward the radar."""
    image, truth, world = rugged
    grid, gtc = gtc
    di, dj, _, _ = _checkpoints(gtc, truth)
    assert di.size > 100
    assert np.sqrt(np.mean(di**2 + dj**2)) <= CHECKPOINT_PX
    # the frame's span of each row is geocoded: the DEM under every pixel of the image,
    # nothing judged outside it; each pixel's (line, column), on asking, in the image
    valid = np.isfinite(gtc.intensity)
    assert np.isfinite(gtc.height_m[valid]).all()
    outside = ~np.isfinite(gtc.height_m)
    assert not valid[outside].any() and not (gtc.layover | gtc.shadow)[outside].any()
    n_l, n_s = image.annotation.shape
    assert np.all((gtc.line[valid] >= 0) & (gtc.line[valid] <= n_l - 1))
    assert np.all((gtc.column[valid] >= 0) & (gtc.column[valid] <= n_s - 1))
    gec = geocode(image, grid, reference_height_m=world.base_height_m)
    di, dj, h, inc = _checkpoints(gec, truth)
    moved_m = np.hypot(di, dj) * PIXEL_M
    predicted_m = np.abs(h - world.base_height_m) / np.tan(inc)
    big = predicted_m > 10 * PIXEL_M
    assert big.sum() > 20
    np.testing.assert_allclose(moved_m[big], predicted_m[big], rtol=RELIEF_DISPLACEMENT_REL)


def test_a_ridge_folds_in_range_and_casts_shadow_where_the_geometry_says() -> None:
    """``layover_and_shadow`` on a ridge across a flat plain seen from 785 km (flat Earth,
    the radar over x = 0, one profile per grid row): a 40° face towards the radar (steeper
    than the incidence: it folds in range) and a 75° face away from it (steeper than the
    complement: it hides the plain behind it). Layover is, in closed form, the points
    whose range another point of the profile shares: the plain before the face down to
    the top's range, the face, and the back face down to the foot's range; shadow the back
    face and the plain behind it up to where the ray over the top lands."""
    from station.spacecraft.sar_masks import layover_and_shadow

    height, x0, dx = 785e3, 330e3, 25.0
    n = np.arange(400)
    x = x0 + n * dx
    top_m = 40 * dx * np.tan(np.radians(40))
    h = np.where((n >= 100) & (n < 140), (n - 100) * dx * np.tan(np.radians(40)), 0.0)
    h = np.where(n >= 140, np.maximum(top_m - (n - 140) * dx * np.tan(np.radians(75)), 0), h)
    r, look = np.hypot(x, height - h), np.arctan2(x, height - h)
    grid = [np.tile(a, (6, 1)) for a in (x / 20.0, r / 7.9, look)]
    rows = np.repeat(np.arange(6.0)[:, None], x.size, axis=1)
    tol_r, tol_look = 0.05, 0.05 * 7.9 / 850e3
    layover, shadow = layover_and_shadow(rows, *grid, 0.5 * dx / 20.0, tol_r, tol_look)
    r_top, r_foot = r[140], r[100]  # the face: points 100 to 140
    want_layover = (r > r_top + tol_r * 7.9) & (r < r_foot - tol_r * 7.9)
    # the ray over the top at its look angle: what lies behind it, lower, is hidden
    behind = (n > 140) & (look < look[140] - tol_look)
    for k in range(6):
        # the face's foot and top themselves: their range is their own only (the closed
        # form's strict inequality), and the profile sees them as fold's ends
        assert set(np.flatnonzero(layover[k] != want_layover)) <= {100, 140}
        np.testing.assert_array_equal(shadow[k], behind)
    assert want_layover.sum() > 70 and behind.sum() > 10  # the ridge does fold and hide
    flat = layover_and_shadow(
        rows, grid[0], grid[0] * 0.39, 0.4 + grid[0] * 1e-6, 0.6, tol_r, tol_look
    )
    assert not flat[0].any() and not flat[1].any()


def test_layover_and_shadow_are_the_truths(cliffs) -> None:
    """GTC over a world of ridges (45° faces towards the radar, 80° cliffs away from it,
    on the DEM the world is made of): the masks against the truth's, the same definitions
    on the world's own terrain four times finer than the output and the truth's own
    geometry: IoU ≥ 0.95 each (the issue's)."""
    _, truth, grid, geocoded = cliffs
    valid = np.isfinite(geocoded.intensity)
    ii, jj = np.nonzero(valid)
    i0, i1, j0, j1 = ii.min(), ii.max() + 1, jj.min(), jj.max() + 1
    x0, y1 = grid.map_of(i0 - 0.5, j0 - 0.5)
    crop = MapGrid.north_up(grid.crs_wkt, float(x0), float(y1), PIXEL_M, i1 - i0, j1 - j0)
    true_layover, true_shadow = truth.masks(crop, oversample=4)
    inside = valid[i0:i1, j0:j1]
    for ours, true in (
        (geocoded.layover[i0:i1, j0:j1], true_layover),
        (geocoded.shadow[i0:i1, j0:j1], true_shadow),
    ):
        ours, true = ours & inside, true & inside
        assert true.sum() > 500  # enough of each to be a figure
        assert (ours & true).sum() / (ours | true).sum() >= MASK_IOU


def test_a_gtc_product_opens_georeferenced_in_gdal(rugged, gtc, tmp_path) -> None:
    """The GTC as a product of the house format: read back equal, compared with itself
    within every tolerance, opened by GDAL with its CRS and transform, as written and as
    its GeoTIFF export."""
    import rasterio

    from levels.compare import compare_products
    from levels.export import write_geotiff
    from levels.makers.sar import sar_product
    from levels.products import read_product, write_product

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
    with rasterio.open(f'NETCDF:"{path}":layover') as ds:  # a mask: its classes, as CF's
        assert ds.dtypes[0] == "uint8"
        tags = ds.tags()
        assert tags["layover#flag_meanings"] == "not_layover layover"
        assert tags["layover#flag_values"].strip("{}").split(",") == ["0", "1"]
    tif = write_geotiff(back, tmp_path / "ers_test_GTC.tif")
    with rasterio.open(tif) as ds:
        assert ds.count == 3 and ds.transform.to_gdal() == pytest.approx(grid.geotransform)
        np.testing.assert_array_equal(ds.read(1), product.bands["intensity"].image)
        assert ds.tags(2)["flag_meanings"] == "not_layover layover"


def _reduced(tmp_path, name: str, **sar) -> object:
    """The shipped scenario ``scenarios/sar/<name>.toml`` with ``[sar]`` keys replaced (a
    reduced frame), as :func:`station.loader.load_sar` reads it."""
    import dataclasses

    from station.loader import load_sar

    scn = load_sar(ROOT / "scenarios" / "sar" / f"{name}.toml")
    return dataclasses.replace(scn, sar=dataclasses.replace(scn.sar, **sar))


def test_station_runs_an_ers_frame_that_gdal_reads_on_the_truth(tmp_path) -> None:
    """``station run`` of the GEC scenario (a flat world at the reference height; the frame
    100 × 100, no speckle): its checkpoints on the truth; its product read through GDAL,
    phase-correlated against the world's own reflectance on the same map grid, within
    the issue's 0.1 px; compared with itself, nothing differs."""
    import cv2
    import rasterio

    from station.compare import compare_inputs
    from station.run_sar import run_sar

    scn = _reduced(tmp_path, "ers_gec", lines=100, samples=100, speckle_looks=0.0)
    report = run_sar(scn, tmp_path / "run")
    (row,) = report["products"]
    assert row["level"] == "GEC" and row["quality"]["checkpoints"]["points"] > 50
    assert row["quality"]["checkpoints"]["rms_px"] <= CHECKPOINT_PX
    with rasterio.open(f'NETCDF:"{tmp_path / "run" / row["file"]}":intensity') as ds:
        image, transform, crs = ds.read(1).astype(np.float64), ds.transform, ds.crs
        assert np.isnan(ds.nodata)  # outside the frame: no-data
    valid = np.isfinite(image)
    jj, ii = np.meshgrid(np.arange(image.shape[1]) + 0.5, np.arange(image.shape[0]) + 0.5)
    x, y = transform @ (jj, ii)
    lon, lat = pyproj.Transformer.from_crs(crs.to_wkt(), "EPSG:4326", always_xy=True).transform(
        x, y
    )
    world = World(lon0_rad=LON0, base_height_m=200.0, relief_m=0.0, seed=scn.world.seed)
    rho = world.reflectance(np.radians(lat).ravel(), np.radians(lon).ravel(), "P")
    rho = rho.reshape(image.shape)
    a = np.where(valid, image - image[valid].mean(), 0.0)
    b = np.where(valid, rho - rho[valid].mean(), 0.0)
    (dx, dy), _ = cv2.phaseCorrelate(b, a)
    assert np.hypot(dx, dy) <= CHECKPOINT_PX  # measured 0.028 px
    found = compare_inputs(tmp_path / "run", tmp_path / "run").findings
    assert not [f for fs in found.values() for f in fs if f.ok is False]


def test_station_runs_an_ers_frame_over_the_srtm_tile(tmp_path, capsys) -> None:
    """The GTC scenario (real relief: the SRTM tile N00E010; a 100 × 100 frame): GTC over
    the exported DEM on the truth, GEC moved by each point's height off the reference over
    tan θ, layover against the truth's. The terrain's γ⁰ the world's reflectance (the
    ``gamma`` law, no speckle): the product's γ⁰ by terrain flattening on it whatever the
    slope, where σ⁰ on the ellipsoid is not."""
    from station.run_sar import run_sar

    scn = _reduced(
        tmp_path, "ers_gtc", lines=100, samples=100, speckle_looks=0.0, backscatter="gamma",
        flatten=True,
    )  # fmt: skip
    report = run_sar(scn, tmp_path / "run")
    gec, gtc = report["products"]
    gamma0 = gtc["quality"]["gamma0"]
    assert gamma0["pixels"] > 5000 and abs(gamma0["mean_to_truth"] - 1) <= GAMMA0_REL
    assert max(abs(m - 1) for m in gamma0["by_correction"]) <= GAMMA0_REL
    plain = gamma0["unflattened_by_correction"]  # the terrain's effect, which it takes off
    assert max(plain) / min(plain) > 2
    assert "gamma0" in read_product(tmp_path / "run" / gtc["file"]).bands
    assert (gec["level"], gtc["level"]) == ("GEC", "GTC")
    assert gtc["quality"]["checkpoints"]["rms_px"] <= CHECKPOINT_PX
    relief = gec["quality"]["relief_displacement"]
    assert relief["points"] > 20 and relief["worst_ratio_error"] <= RELIEF_DISPLACEMENT_REL
    layover = gtc["quality"]["masks"]["layover"]
    assert layover["truth_pixels"] > 100 and layover["iou"] >= MASK_IOU
    assert (tmp_path / "run" / "ers_gtc.dem.tif").is_file()
    _compare_sees_a_band_shifted_one_pixel(tmp_path / "run", gtc["file"], tmp_path / "shifted")
    out = capsys.readouterr().out
    assert f"DIFFERS  {gtc['file']}: bands/intensity/max_abs" in out, out
    _the_frame_file_alone_makes_the_runs_products(scn, tmp_path / "run", tmp_path / "alone")


def _the_frame_file_alone_makes_the_runs_products(scn, run: Path, out: Path) -> None:
    """The run wrote its frame in ESA's format (``<name>.E1``, the house file beside it)
    and processed it from that file; the file processed alone by the library
    (``levels.frame``, no emulator: the run's options, its DEM file) gives the run's GEC
    and GTC, byte for byte; `station process FRAME.E1 --dem DEM` makes both from the file
    and the DEM, with the DEM's own options."""
    from levels.compare import compare_products
    from levels.frame import process_frame
    from levels.readers.dem import read_dem
    from levels.readers.formats import open_frame
    from station.cli import main
    from station.run_sar import frame_options, scenario_provenance

    frame = open_frame(run / f"{scn.name}.E1")
    out.mkdir()
    made = process_frame(
        frame,
        frame_options(scn),
        out,
        dem=read_dem(run / f"{scn.name}.dem.tif", "ellipsoid"),
        dem_source=f"{scn.name}.dem.tif",
        provenance=scenario_provenance(scn),
    )
    for m in made:  # the same images, masks and geometry (its quality: no truth here)
        a = read_product(run / m.path.name)
        for band, image in m.product.bands.items():
            assert np.array_equal(image.image, a.bands[band].image, equal_nan=True), band
        found = compare_products(a, read_product(m.path))
        bad = [f.text() for f in found if not f.ok and f.kind in ("pixels", "geometry", "metadata")]
        assert not bad, bad
    cli = ["process", str(run / f"{scn.name}.E1"), "--dem", str(run / f"{scn.name}.dem.tif")]
    assert main([*cli, "--out", str(out / "cli"), "-q"]) == 0
    no_dem = ["process", str(run / f"{scn.name}.E1"), "--levels", "GTC", "-q"]
    assert main([*no_dem, "--out", str(out / "no_dem")]) == 2  # GTC needs the DEM
    assert not (out / "no_dem").exists()
    assert {p.name for p in (out / "cli").glob("*.nc")} == {
        f"{scn.name}_GEC.nc",
        f"{scn.name}_GTC.nc",
    }


def _compare_sees_a_band_shifted_one_pixel(run: Path, gtc: str, edited: Path) -> None:
    """`station compare` of a SAR run with itself: exit 0; with a copy whose GTC intensity
    is shifted by one pixel east: exit 1, the band named."""
    import shutil

    import h5py

    from station.cli import EXIT_DIFFERENT, main

    assert main(["compare", str(run), str(run), "-q"]) == 0
    shutil.copytree(run, edited)
    with h5py.File(edited / gtc, "r+") as f:
        f["intensity"][...] = np.roll(f["intensity"][()], 1, axis=1)
    assert main(["compare", str(run), str(edited)]) == EXIT_DIFFERENT


def test_station_run_takes_a_sar_scenario_and_refuses_a_gtc_without_a_dem(tmp_path) -> None:
    """``station run`` knows a SAR scenario by its ``[sar]`` table; GTC without ``[dem]``
    and an unknown table are refused in one line (exit 2), nothing written; ``--check``
    checks a good one without writing."""
    from station.cli import main

    bad = tmp_path / "bad.toml"
    bad.write_text('[sar]\nlevels = ["GTC"]\n')
    assert main(["run", str(bad), "--out", str(tmp_path / "out")]) == 2
    bad.write_text("[sar]\nlines = 64\n[instrument]\nmirror_step = 48\n")
    assert main(["run", str(bad), "--out", str(tmp_path / "out")]) == 2
    assert not (tmp_path / "out").exists()
    # --check: the scenario and the files it reads, nothing written
    shipped = str(ROOT / "scenarios" / "sar" / "ers_gtc.toml")
    assert main(["run", shipped, "--check", "--out", str(tmp_path / "out")]) == 0
    assert not (tmp_path / "out").exists()


def test_a_smooth_orbit_error_moves_gec_as_the_geometry_says() -> None:
    """The post-facto orbit's offset (``state_bias_m``) moves every GEC checkpoint alike, on
    a flat world: along the track by the offset itself; radially by ``δ · cos α / sin θ``
    across the track (α the look angle at the antenna, θ the incidence on the ground)."""
    from levels.sar import frame_grid
    from levels.sar.geocoding import geocode

    world = World(lon0_rad=LON0, base_height_m=200.0, relief_m=0.0, seed=3)
    moved = {}
    for bias in ((50.0, 0.0, 0.0), (0.0, 0.0, 20.0)):
        frame = ErsFrame(n_lines=100, n_samples=100, state_bias_m=bias)
        image, truth = emulate_frame(frame, world, render=False)
        grid = frame_grid(image.annotation, PIXEL_M, world.base_height_m, 300.0)
        cp = checkpoint_errors(geocode(image, grid, reference_height_m=200.0), truth)
        di, dj = cp["di"] * PIXEL_M, cp["dj"] * PIXEL_M
        assert np.hypot(di - di.mean(), dj - dj.mean()).max() < 0.02 * np.hypot(di, dj).max()
        moved[bias] = float(np.hypot(di.mean(), dj.mean()))
        inc = float(np.mean(cp["incidence_rad"]))
    assert moved[(50.0, 0.0, 0.0)] == pytest.approx(50.0, rel=0.01)
    look = np.arcsin(np.sin(inc) * 6371e3 / (6371e3 + 785e3))  # the antenna's look angle
    assert moved[(0.0, 0.0, 20.0)] == pytest.approx(20.0 * np.cos(look) / np.sin(inc), rel=0.02)
