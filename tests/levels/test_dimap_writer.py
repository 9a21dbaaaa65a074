"""DIMAP written by :mod:`levels.writers.dimap`: real scenes written back and read again
unchanged, the gyro rates that reproduce the angles, a product's 1A exported as a scene
whose model is the product's, and GDAL's DIMAP driver opening it."""

from __future__ import annotations

import dataclasses
import warnings
from pathlib import Path

import numpy as np
import pytest
from _dimap import EXPORT_MODEL_PX, model_gap_px
from hypothesis import given, settings
from hypothesis import strategies as st

from levels.geometry.attitude import integrate_rates
from levels.geometry.times import Epoch
from levels.products import read_product
from levels.readers.dimap import DimapScene, read_dimap
from levels.writers.dimap import (
    band_descriptions,
    dimap_scene_of,
    rates_reproducing,
    write_dimap,
    write_dimap_xml,
)

REAL = (
    "spot2_hrv1_P_19980220_izmit_METADATA.DIM",
    "spot4_hrvir2_M_20120115_altai_METADATA.DIM",
    "spot5_hrg1_A_20050313_altai_METADATA.DIM",
    "gdal_spot4_hrvir1_M_20011129_frameonly_METADATA.DIM",
)


def _equal(a: object, b: object) -> bool:
    if dataclasses.is_dataclass(a) and dataclasses.is_dataclass(b):
        return all(
            _equal(getattr(a, f.name), getattr(b, f.name))
            for f in dataclasses.fields(a)
            if f.name not in ("path", "hold_s")
        )
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_equal(a[k], b[k]) for k in a)
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return np.array_equal(a, b)
    if isinstance(a, Epoch) and isinstance(b, Epoch):
        return a.t0_utc == b.t0_utc
    return a == b


@pytest.mark.parametrize("name", REAL)
def test_real_scenes_are_written_back_and_read_again_unchanged(
    name: str, refdata: Path, tmp_path: Path
) -> None:
    scene = read_dimap(refdata / "dimap" / name)
    out = write_dimap_xml(scene, tmp_path / "METADATA.DIM")
    again = read_dimap(out)
    for f in dataclasses.fields(DimapScene):
        if f.name != "path":
            assert _equal(getattr(scene, f.name), getattr(again, f.name)), f.name
    # and once more: the writer's own output is a fixed point, byte for byte
    second = write_dimap_xml(again, tmp_path / "again.DIM")
    assert second.read_bytes() == out.read_bytes()


@settings(max_examples=50, deadline=None)
@given(
    n=st.integers(2, 200),
    seed=st.integers(0, 2**32 - 1),
    uneven=st.booleans(),
)
def test_rates_integrate_back_to_the_angles(n: int, seed: int, uneven: bool) -> None:
    rng = np.random.default_rng(seed)
    dt = 0.125 * (rng.uniform(0.5, 3.0, n - 1) if uneven else np.ones(n - 1))
    t = 100.0 + np.concatenate([[0.0], np.cumsum(dt)])
    angles = np.cumsum(1e-6 * rng.standard_normal((n, 3)), axis=0)
    rates = rates_reproducing(t, angles)
    back = integrate_rates(t, rates).angles_rad_samples
    # relative to the first sample: the reader integrates from a null first record
    np.testing.assert_allclose(back, angles - angles[0], rtol=0, atol=1e-15)


@pytest.fixture(scope="module")
def product_1a(run_dir: Path) -> Path:
    return run_dir / "small_test_s000_1A.h5"


def test_the_exported_scene_is_the_products_model(product_1a: Path, tmp_path: Path) -> None:
    product = read_product(product_1a)
    scene = dimap_scene_of(product, mission_index=2)
    image = np.stack([b.image for b in product.bands.values()])
    d = write_dimap(scene, tmp_path / "scene", image, band_names=band_descriptions(product))
    back = read_dimap(d / "METADATA.DIM")
    assert (back.mission, back.mission_index, back.instrument, back.sensor_code) == (
        "SPOT",
        2,
        "HRV",
        "P",
    )
    assert back.mirror_step == product.attrs["mirror_step"]
    assert model_gap_px(product, back) < EXPORT_MODEL_PX
    theirs = back.model(attitude="integrated_zeroed")
    # the frame is located by the same model: station locate reproduces it
    corners = theirs.image_to_ground(back.frame_row - 1.0, back.frame_col - 1.0, 0.0)
    np.testing.assert_allclose(np.degrees(corners.lat_rad), back.frame_lat_deg, atol=1e-9)


def test_gdal_opens_the_exported_scene(product_1a: Path, tmp_path: Path) -> None:
    import rasterio

    product = read_product(product_1a)
    scene = dimap_scene_of(product)
    image = np.stack([b.image for b in product.bands.values()])
    d = write_dimap(scene, tmp_path / "scene", image, band_names=band_descriptions(product))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with rasterio.open(d / "METADATA.DIM") as ds:
            assert ds.driver == "DIMAP"
            assert ds.shape == (scene.n_rows, scene.n_cols)
            np.testing.assert_array_equal(ds.read(1), image[0])
            gcps, crs = ds.gcps
            tags = ds.tags()
    assert crs.to_epsg() == 4326 and len(gcps) == 4
    # GDAL puts DIMAP's 1-based pixel centres at 0.5 (its corner-based origin)
    assert {(g.row, g.col) for g in gcps} == {
        (0.5, 0.5),
        (0.5, scene.n_cols - 0.5),
        (scene.n_rows - 0.5, scene.n_cols - 0.5),
        (scene.n_rows - 0.5, 0.5),
    }
    assert tags["MISSION"] == "SPOT" and tags["SCENE_PROCESSING_LEVEL"] == "1A"
