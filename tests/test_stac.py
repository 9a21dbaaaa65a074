"""The STAC catalogue a run, a reprocessing and a campaign write (issue 35 §6): valid by
stac-validator, every link and asset resolving, and its extension fields equal to what
GDAL reads from the products themselves.

stac-validator fetches schemas from the web; this machine's CI has none, so the core
schemas are mapped onto the copies pystac ships (STAC 1.1.0 and GeoJSON): the core is
validated offline. The extensions' fields are checked here against GDAL instead.
"""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np
import pystac
import pytest

from station.catalog import CATALOG_FILE, EXTENSIONS, footprint_geojson
from station.cli import main

ROOT = Path(__file__).resolve().parents[1]
_SCHEMAS = Path(pystac.__file__).parent / "validation" / "jsonschemas"
_STAC = "https://schemas.stacspec.org/v1.1.0"
SCHEMA_MAP = {
    **{
        f"{_STAC}/{k}-spec/json-schema/{k}.json": str(_SCHEMAS / "stac-spec/v1.1.0" / f"{k}.json")
        for k in ("item", "catalog", "collection")
    },
    **{
        f"{_STAC}/item-spec/json-schema/{k}.json": str(_SCHEMAS / "stac-spec/v1.1.0" / f"{k}.json")
        for k in (
            "bands",
            "basics",
            "common",
            "data-values",
            "datetime",
            "instrument",
            "licensing",
            "provider",
        )
    },
    **{
        f"https://geojson.org/schema/{k}.json": str(_SCHEMAS / "geojson" / f"{k}.json")
        for k in ("Feature", "Geometry")
    },
}


def _valid(path: Path) -> None:
    from stac_validator import stac_validator

    v = stac_validator.StacValidate(str(path), core=True, schema_map=SCHEMA_MAP)
    assert v.run(), v.message


def _check_catalog(root: Path) -> list[pystac.Item]:
    """Every object of the catalogue valid, every link and asset resolving; its Items."""
    catalog = pystac.Catalog.from_file(str(root / CATALOG_FILE))
    _valid(root / CATALOG_FILE)
    for child in catalog.get_children():
        _valid(Path(child.get_self_href()))
    items = list(catalog.get_items(recursive=True))
    for item in items:
        _valid(Path(item.get_self_href()))
        # an extension declared has fields here, and fields here have it declared: a
        # validator that fetches the schemas rejects an extension without one (issue 57)
        used = {
            url
            for pre, url in EXTENSIONS.items()
            if any(k.startswith(pre) for k in item.properties)
        }
        assert set(item.stac_extensions) == used, (item.id, item.stac_extensions)
        for asset in item.assets.values():
            assert Path(asset.get_absolute_href()).is_file(), asset.href
            assert not Path(asset.href).is_absolute()  # moved with its directory
    return items


@pytest.fixture(scope="module")
def run(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("stac") / "run"
    scenario = ROOT / "scenarios" / "small_test.toml"
    assert main(["run", str(scenario), "--out", str(out), "--quiet"]) == 0
    return out


def test_the_runs_catalogue_is_valid_and_says_what_gdal_reads(run: Path) -> None:
    import rasterio

    items = {i.id: i for i in _check_catalog(run)}
    products = {p.stem for p in run.glob("small_test_s000_*") if p.suffix in (".nc", ".h5")}
    assert set(items) == products
    assert json.loads((run / "report.json").read_text())["catalog"] == CATALOG_FILE
    twoa = items["small_test_s000_2A"]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with rasterio.open(run / "small_test_s000_2A.nc") as nc:
            band = nc.subdatasets[0]  # the image variable, georeferenced
        with rasterio.open(band) as ds:
            assert twoa.properties["proj:code"] == f"EPSG:{ds.crs.to_epsg()}"
            assert twoa.properties["proj:shape"] == [ds.height, ds.width]
            np.testing.assert_allclose(twoa.properties["proj:transform"], list(ds.transform)[:6])
    for item in items.values():
        p = item.properties
        assert p["processing:level"] == f"L{item.id.rsplit('_', 1)[1]}"
        assert item.assets["thumbnail"].roles == ["thumbnail"]
        assert p["view:off_nadir"] == 0.0  # small_test's mirror at step 48
        assert 0 <= p["view:incidence_angle"] < 1.0  # at nadir, but for Earth's curvature
        assert 0 < p["view:sun_elevation"] < 90 and p["sat:orbit_state"] == "descending"
        assert item.datetime is not None and item.datetime.year == 1998
        lon = np.array(item.geometry["coordinates"][0])[:, 0]
        assert item.bbox[0] == lon.min() and item.bbox[2] == lon.max()
    assert items["small_test_s000_1A"].properties["proj:code"] is None
    assert "rpc" in items["small_test_s000_1A"].assets  # located by its RPCs
    quality = twoa.properties["spot:quality"]
    assert 150 < quality["checkpoints/P/line_of_sight/rms_m"] < 300


def test_a_campaigns_catalogue_has_a_child_per_archive(run: Path, tmp_path: Path) -> None:
    out = tmp_path / "campaign"
    assert main(["campaign", str(run / "small_test.l0.h5"), "--out", str(out), "--quiet"]) == 0
    items = _check_catalog(out)
    catalog = pystac.Catalog.from_file(str(out / CATALOG_FILE))
    assert [c.id for c in catalog.get_children()] == ["small_test"]
    assert len(items) == 3  # the default levels of a reprocessing: 1A, 1B, 2A


def test_a_reprocessings_catalogue(run: Path, tmp_path: Path) -> None:
    out = tmp_path / "process"
    args = ["process", str(run / "small_test.l0.h5"), "--levels", "1A,2A", "--out", str(out)]
    assert main([*args, "--quiet"]) == 0
    assert {i.id for i in _check_catalog(out)} == {"small_test_s000_1A", "small_test_s000_2A"}


def _ring_area(ring: list[list[float]]) -> float:
    x, y = np.array(ring).T
    return 0.5 * float(np.sum(x[:-1] * y[1:] - x[1:] * y[:-1]))


def test_footprints_are_counter_clockwise_and_split_at_the_antimeridian() -> None:
    lat = np.array([10.0, 10.0, 9.0, 9.0])  # a descending scene's corners: clockwise
    geometry, bbox = footprint_geojson(lat, np.array([20.0, 21.0, 21.0, 20.0]))
    assert geometry["type"] == "Polygon" and _ring_area(geometry["coordinates"][0]) > 0
    assert bbox == [20.0, 9.0, 21.0, 10.0]
    # across 180°: two polygons within ±180°, bbox west > east (STAC's convention)
    geometry, bbox = footprint_geojson(lat, np.array([179.6, -179.6, -179.6, 179.6]))
    assert geometry["type"] == "MultiPolygon"
    parts = [np.array(p[0]) for p in geometry["coordinates"]]
    for part in parts:
        assert np.all(np.abs(part[:, 0]) <= 180.0) and _ring_area(part.tolist()) > 0
    assert bbox[0] == pytest.approx(179.6) and bbox[2] == pytest.approx(-179.6)
    total = sum(_ring_area(p.tolist()) for p in parts)
    assert total == pytest.approx(0.8 * 1.0)


def test_the_validator_catches_an_invalid_item(run: Path, tmp_path: Path) -> None:
    """The offline validation is not vacuous: an Item without its datetime fails it."""
    item = json.loads((run / "stac/small_test_s000_2A/small_test_s000_2A.json").read_text())
    del item["properties"]["datetime"]
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(item))
    with pytest.raises(AssertionError):
        _valid(bad)


def test_a_sar_runs_catalogue_is_valid(tmp_path: Path) -> None:
    """A SAR frame's run (``scenarios/sar/ers_gec.toml``, reduced): its GEC an Item of a
    valid catalogue, over the map grid's footprint, at the frame's time."""
    import dataclasses

    from station.loader import load_sar
    from station.run_sar import run_sar

    scn = load_sar(Path(__file__).resolve().parents[1] / "scenarios/sar/ers_gec.toml")
    scn = dataclasses.replace(scn, sar=dataclasses.replace(scn.sar, lines=64, samples=64))
    run_sar(scn, tmp_path / "run")
    (item,) = _check_catalog(tmp_path / "run")
    assert item.properties["processing:level"] == "GEC"
    assert item.properties["constellation"] == "ers"
    assert item.datetime is not None and item.datetime.year == 1995
