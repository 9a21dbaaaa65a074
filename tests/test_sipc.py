"""The processing centre end to end on a reduced scene: L0 → 1A, 1B, 2A products."""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np
import pyproj
import pytest

from levels.errors import ProductError
from levels.process import ProcessingRequest, process
from levels.products import PRODUCT_FORMAT, read_product
from levels.readers.l0 import read_l0
from station.loader import load_scenario
from station.reprocess import process_scenario

ROOT = Path(__file__).resolve().parents[1]
#: 1A leaves the stripes of the calibration table's errors (0.2 % of gain, 0.2 counts) and
#: the scene's own noise in 300-line column means: well under a count.
STRIPE_AFTER_MAX_COUNTS = 1.5


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    out = tmp_path_factory.mktemp("sipc")
    scn = load_scenario(ROOT / "scenarios" / "small_test.toml")
    products, l0 = process_scenario(scn, out)
    return scn, products, l0, out


def test_products_written_per_scene_and_level(run) -> None:
    scn, products, _l0, _out = run
    assert len(products.scenes) == 1 and products.tail_lines == 0
    paths = products.scenes[0].paths
    assert set(paths) == {"1A", "1B", "2A"}
    for level, path in paths.items():
        p = read_product(path)
        assert p.level == level and set(p.bands) == {"P"}
        assert p.provenance["scenario"] == scn.name
        band = p.bands["P"]
        assert band.valid.mean() > 0.5 and (band.image[~band.valid] == 0).all()
        with h5py.File(path) as f:
            assert f["P"].attrs["units"] == "1"
            assert f["geometry/ephemeris/r_ecef_m"].attrs["units"] == "m"
    assert read_product(paths["1A"]).bands["P"].image.shape == (300, 300)


def test_quality_against_truth(run) -> None:
    _scn, products, _l0, _out = run
    q = products.scenes[0].quality
    assert q["1A"]["stripe_level/P/raw_counts"] > 3.0
    assert q["1A"]["stripe_level/P/level_1a_counts"] < STRIPE_AFTER_MAX_COUNTS
    # system-corrected: hundreds of metres off, as the default error budget implies
    for level in ("1B", "2A"):
        assert 100.0 < q[level]["checkpoints/P/line_of_sight/rms_m"] < 500.0
    assert q["2A"]["inverse_vs_model/nearest4/max_px"] < 0.05


def test_2a_geometry_redoes_the_map(run) -> None:
    _scn, products, _l0, _out = run
    p = read_product(products.scenes[0].paths["2A"], images=False)
    g = p.geometry["level_2a"]
    crs = pyproj.CRS.from_wkt(g["crs_wkt"])
    assert crs.to_epsg() == 32721  # UTM 21 S for Cuiabá
    x0, dx, _, y0, _, dy = g["geotransform"]
    assert dx == -dy == p.attrs["pixel_size_m"]
    # the scene centre is inside the map grid
    e, n = pyproj.Transformer.from_crs("EPSG:4326", crs, always_xy=True).transform(
        p.geometry["scene"]["centre_lon_deg"], p.geometry["scene"]["centre_lat_deg"]
    )
    assert 0 < (e - x0) / dx < p.attrs["n_cols"] and 0 < (y0 - n) / dx < p.attrs["n_rows"]


def test_reprocessing_gives_identical_products(run, tmp_path) -> None:
    scn, products, l0, _out = run
    again = process(ProcessingRequest.of(read_l0(l0), scn.processing, tmp_path, scn.name))[0]
    for level, path in products.scenes[0].paths.items():
        a, b = read_product(path), read_product(again.scenes[0].paths[level])
        assert np.array_equal(a.bands["P"].image, b.bands["P"].image)
        assert np.array_equal(a.bands["P"].valid, b.bands["P"].valid)


def test_bad_products_are_refused(run, tmp_path) -> None:
    _scn, products, _l0, _out = run
    with pytest.raises(ProductError, match="no such"):
        read_product(tmp_path / "missing.h5")
    junk = tmp_path / "junk.h5"
    junk.write_bytes(b"not hdf5")
    with pytest.raises(ProductError, match="not a readable HDF5"):
        read_product(junk)
    good = products.scenes[0].paths["1A"]
    cut = tmp_path / "cut.h5"
    cut.write_bytes(good.read_bytes()[: good.stat().st_size // 2])
    with pytest.raises(ProductError):
        read_product(cut)
    other = tmp_path / "other.h5"
    with h5py.File(other, "w") as f:
        f.attrs["format"] = "SPOT-L0"
    with pytest.raises(ProductError, match=PRODUCT_FORMAT):
        read_product(other)
