"""SPOT 1–4 level-1A DIMAP scenes in (``levels.readers.scene1a``): the emulated pass's 1A
written as SPOT World Heritage's zip and processed again gives the L0 route's levels; real
DIMAP files with an image of their size give levels whose RPCs land on the producer's
frame; what cannot make levels is refused in one line."""

from __future__ import annotations

import shutil
import zipfile
from pathlib import Path

import numpy as np
import pytest

from tests._cli import one_line

ROOT = Path(__file__).resolve().parents[1]

#: The issue's bound between the two routes' geometry (raw pixels); they differ by the
#: DIMAP's rounding of the centre time to the microsecond and its 11 significant digits
#: (measured 1e-5 px on the P pass, 3e-7 px on the XS one).
ROUTE_GEOMETRY_PX = 0.01
#: Counts may differ where the two geometries, 1e-5 px apart, straddle a half count of the
#: 2A's cubic resampling: one count, on a few pixels in ten thousand (0.02 % measured).
ROUTE_COUNTS_SHARE = 0.999
#: The producer's frame against GDAL's RPC transformer on our 1A, on the ellipsoid (m):
#: the issue's bound; our model reproduces it within 2.5 m and the RPCs fit it within
#: 0.01 px (40 cm at 10 m).
REAL_FRAME_M = 10.0

_XS = """name = "route_xs"
seed = 11

[instrument]
mode = "XS"
mirror_step = 70
n_detectors = 300
n_lines = 300

[world]
base_height_m = 500.0
relief_m = 300.0

[dem]
spacing_arcsec = 3.0

[downlink]
bit_rate_mbps = 0.4
preamble_s = 0.1
postamble_s = 0.1

[processing]
reference_height_m = 500.0
"""


def _assert_same(levels: dict) -> None:
    for level, row in levels.items():
        assert row["geometry_max_px"] <= ROUTE_GEOMETRY_PX, (level, row)
        assert row["counts_identical"] >= ROUTE_COUNTS_SHARE and row["counts_max_diff"] <= 1, (
            level,
            row,
        )
        if row["truth_rms_m_l0"] is not None:  # the same truth, the same figure
            assert row["truth_rms_m_dimap"] == pytest.approx(row["truth_rms_m_l0"], abs=0.05)


def test_a_p_pass_by_the_dimap_route_is_the_l0_routes(tmp_path) -> None:
    """small_test's pass to 1A, 1B, 2A and level 2 (its control points) by the L0 route,
    its 1A zipped as SWH delivers it, processed again from the zip: the same products."""
    from station.loader import load_scenario
    from station.routes import compare_routes

    scn = load_scenario(ROOT / "scenarios" / "small_test.toml")
    result = compare_routes(scn, tmp_path, ("1A", "1B", "2A", "2"))
    _assert_same(result["levels"])
    assert result["levels"]["1A"]["counts_identical"] == 1.0
    assert result["levels"]["1B"]["counts_identical"] == 1.0  # the 1A's counts, resampled
    with zipfile.ZipFile(result["zip"]) as z:
        names = z.namelist()
    assert "SCENE01/METADATA.DIM" in names and "SCENE01/IMAGERY.TIF" in names


@pytest.mark.filterwarnings("ignore::rasterio.errors.NotGeoreferencedWarning")
def test_an_xs_pass_to_level_3_by_the_dimap_route(tmp_path) -> None:
    """Three XS bands, level 2 and level 3 over the exported DEM: the same both routes."""
    from station.loader import load_scenario
    from station.routes import compare_routes

    toml = tmp_path / "route_xs.toml"
    toml.write_text(_XS, encoding="utf-8")
    result = compare_routes(load_scenario(toml), tmp_path / "out", ("1A", "2A", "2", "3"))
    _assert_same(result["levels"])
    from levels.products import read_product

    p3 = read_product(next((tmp_path / "out" / "dimap_route").glob("*_3.nc")), images=False)
    assert list(p3.bands) == ["XS1", "XS2", "XS3"]
    prov = p3.provenance
    assert prov["route"] == "DIMAP 1A scene" and prov["source"] == "route_xs.zip"
    assert prov["attitude"] == "integrated_zeroed"  # the rates the writer made reproduce it
    assert set(prov["radiance"]) == {"XS1", "XS2", "XS3"}
    _four_bands_as_spot4_hrvir_gives_them(tmp_path / "out" / "route_xs.zip", tmp_path / "xi")
    # the command line, as a user runs it: the zip, its control points and DEM given
    from station.cli import main

    run = tmp_path / "out" / "l0_route"
    cli = ["process", str(tmp_path / "out" / "route_xs.zip"), "--levels", "2,3", "--gcps"]
    cli += [str(run / "route_xs.gcp.csv"), "--dem", str(run / "route_xs.dem.tif")]
    assert main([*cli, "--scenario", str(toml), "--out", str(tmp_path / "cli"), "-q"]) == 0
    for level in ("2", "3"):
        a = read_product(tmp_path / "cli" / f"route_xs_s000_{level}.nc")
        b = read_product(tmp_path / "out" / "dimap_route" / f"route_xs_s000_{level}.nc")
        assert all(np.array_equal(a.bands[k].image, b.bands[k].image) for k in a.bands)


def _four_bands_as_spot4_hrvir_gives_them(pack: Path, where: Path) -> None:
    """The XS scene made a SPOT 4 HRVIR XI scene (``SENSOR_CODE`` I, a fourth band: XS3's
    counts and look angles again): four bands made, the SWIR's 2A XS3's exactly."""
    import dataclasses

    import rasterio

    from levels.products import read_product
    from levels.readers.dimap import read_dimap
    from levels.writers.dimap import write_dimap
    from station.cli import main

    scene = read_dimap(pack)
    with rasterio.open(f"/vsizip/{pack}/SCENE01/IMAGERY.TIF") as ds:
        image = ds.read()
    xi = dataclasses.replace(
        scene,
        mission_index=4,
        instrument="HRVIR",
        sensor_code="I",
        n_bands=4,
        look_angles={**scene.look_angles, 4: scene.look_angles[3]},
        calibration={**scene.calibration, 4: scene.calibration[3]},
        band_descriptions={**scene.band_descriptions, 4: "SWIR"},
    )
    write_dimap(xi, where / "SCENE01", np.concatenate([image, image[2:3]]))
    out = where / "out"
    assert main(["process", str(where / "SCENE01"), "--levels", "2A", "--out", str(out), "-q"]) == 0
    p2a = read_product(out / "SCENE01_s000_2A.nc")
    assert list(p2a.bands) == ["XS1", "XS2", "XS3", "SWIR"]
    assert np.array_equal(p2a.bands["SWIR"].image, p2a.bands["XS3"].image)
    assert p2a.provenance["mission"] == "SPOT 4" and p2a.provenance["instrument"].startswith(
        "HRVIR"
    )


def _real_scene(refdata: Path, name: str, where: Path, rows_of_zeros: int = 0) -> Path:
    """A real ``METADATA.DIM`` beside an ``IMAGERY.TIF`` of its size (a texture), the first
    ``rows_of_zeros`` rows lost."""
    import rasterio

    from levels.readers.dimap import read_dimap

    where.mkdir(parents=True)
    shutil.copy(refdata / "dimap" / name, where / "METADATA.DIM")
    scene = read_dimap(where / "METADATA.DIM")
    rng = np.random.default_rng(3)
    image = rng.integers(20, 200, (scene.n_bands, scene.n_rows, scene.n_cols), dtype=np.uint8)
    image[:, :rows_of_zeros] = 0
    profile = {"driver": "GTiff", "width": scene.n_cols, "height": scene.n_rows}
    with rasterio.open(
        where / "IMAGERY.TIF", "w", count=scene.n_bands, dtype="uint8", **profile
    ) as ds:
        ds.write(image)
    return where


@pytest.mark.filterwarnings("ignore::rasterio.errors.NotGeoreferencedWarning")
@pytest.mark.parametrize(
    "name",
    ["spot2_hrv1_P_19980220_izmit_METADATA.DIM", "spot4_hrvir2_M_20120115_altai_METADATA.DIM"],
)
def test_real_scenes_make_a_1a_whose_rpcs_land_on_the_producers_frame(
    refdata, tmp_path, name
) -> None:
    """A real SPOT 2 P and SPOT 4 M scene (their metadata, a texture of their size) through
    ``station process DIR --levels 1A``: GDAL's RPC transformer on the 1A as written puts
    the frame's corners and centre, on the ellipsoid, within 10 m of the producer's."""
    import rasterio
    from pyproj import Geod
    from rasterio.transform import RPCTransformer

    from levels.products import read_product
    from levels.readers.dimap import read_dimap
    from station.cli import main

    scene_dir = _real_scene(refdata, name, tmp_path / "SCENE01", rows_of_zeros=5)
    out = tmp_path / "out"
    assert main(["process", str(scene_dir), "--levels", "1A", "--out", str(out), "-q"]) == 0
    [p1a] = out.glob("SCENE01_s000_1A.h5")
    product = read_product(p1a)
    band = next(iter(product.bands))
    assert band == ("P" if "_P_" in name else "M")
    assert not product.bands[band].valid[:5].any() and product.bands[band].valid[5:].all()
    dim = read_dimap(scene_dir)
    with rasterio.open(f'HDF5:"{p1a}"://{band}') as ds:
        rpcs = ds.rpcs
    assert rpcs is not None
    rows = np.append(dim.frame_row, dim.center_row) - 1
    cols = np.append(dim.frame_col, dim.center_col) - 1
    with RPCTransformer(rpcs) as t:
        lon, lat = t.xy(rows, cols, zs=np.zeros(rows.size))
    lat0 = np.append(dim.frame_lat_deg, dim.center_lat_deg)
    lon0 = np.append(dim.frame_lon_deg, dim.center_lon_deg)
    _, _, dist = Geod(ellps="WGS84").inv(lon0, lat0, lon, lat)
    assert np.max(dist) <= REAL_FRAME_M, dist
    prov = product.provenance
    assert (
        prov["mission"] == f"SPOT {dim.mission_index}" and prov["imaging_date"] == dim.imaging_date
    )
    assert prov["attitude"] == "none"  # what reproduces a real SPOT 1–4 producer's frame


@pytest.mark.filterwarnings("ignore::rasterio.errors.NotGeoreferencedWarning")
def test_a_real_scene_zip_to_2a(refdata, tmp_path) -> None:
    """The SPOT 2 scene zipped in a folder, as SWH delivers it, read in place: its 2A made,
    on a UTM grid at 10 m."""
    from levels.products import read_product
    from station.cli import main

    scene_dir = _real_scene(refdata, "spot2_hrv1_P_19980220_izmit_METADATA.DIM", tmp_path / "s")
    pack = tmp_path / "SWH_SPOT2_HRV1_19980220.zip"
    with zipfile.ZipFile(pack, "w", zipfile.ZIP_DEFLATED) as z:
        for f in ("METADATA.DIM", "IMAGERY.TIF"):
            z.write(scene_dir / f, f"SWH_SPOT2_HRV1_19980220/SCENE01/{f}")
    shutil.rmtree(scene_dir)
    out = tmp_path / "out"
    assert main(["process", str(pack), "--levels", "2A", "--out", str(out), "-q"]) == 0
    p2a = read_product(out / "SWH_SPOT2_HRV1_19980220_s000_2A.nc", images=False)
    grid = p2a.map_grid
    assert grid is not None and abs(grid.geotransform[1]) == 10.0 and "UTM" in grid.crs_wkt
    assert p2a.provenance["source"] == pack.name
    import json

    [item] = [
        json.loads(f.read_text())
        for f in out.rglob("*.json")
        if json.loads(f.read_text()).get("type") == "Feature"
    ]
    props = item["properties"]  # the catalogue says what the scene is, not "emulated"
    assert (props["platform"], props["instruments"]) == ("spot-2", ["hrv1"])
    assert props["spot:source"] == pack.name and props["datetime"].startswith("1998-02-20")


def _edited(refdata: Path, tmp_path: Path, old: str, new: str) -> Path:
    d = _real_scene(refdata, "spot2_hrv1_P_19980220_izmit_METADATA.DIM", tmp_path / "e")
    dim = d / "METADATA.DIM"
    text = dim.read_text(encoding="utf-8")
    assert old in text
    dim.write_text(text.replace(old, new), encoding="utf-8")
    return d


@pytest.mark.filterwarnings("ignore::rasterio.errors.NotGeoreferencedWarning")
def test_scenes_that_cannot_make_levels_are_refused_in_one_line(refdata, tmp_path, capsys) -> None:
    """A frame-only DIMAP, a level 2A scene, a SPOT 5 scene, an image of another size, a
    zip with two scenes: exit 2, one line naming the file and the reason."""
    from station.cli import main

    frame_only = tmp_path / "f"
    frame_only.mkdir()
    shutil.copy(
        refdata / "dimap" / "gdal_spot4_hrvir1_M_20011129_frameonly_METADATA.DIM",
        frame_only / "METADATA.DIM",
    )
    code = main(["process", str(frame_only), "--out", str(tmp_path / "o1"), "-q"])
    one_line(capsys, code, 2, "frame-only")

    level_2a = _edited(refdata, tmp_path / "a", "<PROCESSING_LEVEL>1A<", "<PROCESSING_LEVEL>2A<")
    code = main(["process", str(level_2a), "--out", str(tmp_path / "o2"), "-q"])
    one_line(capsys, code, 2, "level 2A scene", "level 1A")

    spot5 = tmp_path / "s5"
    spot5.mkdir()
    shutil.copy(
        refdata / "dimap" / "spot5_hrg1_A_20050313_altai_METADATA.DIM", spot5 / "METADATA.DIM"
    )
    code = main(["process", str(spot5 / "METADATA.DIM"), "--out", str(tmp_path / "o3"), "-q"])
    one_line(capsys, code, 2, "SPOT 5", "station locate")

    import rasterio

    wrong = _real_scene(refdata, "spot2_hrv1_P_19980220_izmit_METADATA.DIM", tmp_path / "w")
    # removed first: GDAL creating a GeoTIFF over the scene's image deletes the dataset it
    # was, the DIMAP's METADATA.DIM with it
    (wrong / "IMAGERY.TIF").unlink()
    with rasterio.open(
        wrong / "IMAGERY.TIF", "w", driver="GTiff", width=600, height=600, count=1, dtype="uint8"
    ) as ds:  # a tenth of the scene's side
        ds.write(np.ones((1, 600, 600), np.uint8))
    code = main(["process", str(wrong), "--out", str(tmp_path / "o4"), "-q"])
    one_line(capsys, code, 2, "IMAGERY.TIF", "metadata says")

    two = tmp_path / "two.zip"
    with zipfile.ZipFile(two, "w") as z:
        for k in (1, 2):
            z.write(wrong / "METADATA.DIM", f"SCENE0{k}/METADATA.DIM")
    code = main(["process", str(two), "--out", str(tmp_path / "o5"), "-q"])
    one_line(capsys, code, 2, "2 METADATA.DIM")
