"""levels as the processing library: an L0 archive into products without the emulator,
reprocessing that reproduces a run bit for bit, and products that GDAL and xarray open
georeferenced with no export step."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pyproj
import pytest
import rasterio

from levels.products import is_product_file, product_name, read_product
from station.cli import main

ROOT = Path(__file__).resolve().parents[1]
SMALL = ROOT / "scenarios" / "small_test.toml"
LEVELS = ("1A", "1B", "2A")


def test_station_process_reproduces_a_run_bit_for_bit(
    run_dir: Path, tmp_path: Path, capsys
) -> None:
    """With the scenario that made it, reprocessing the run's L0 gives the run's products,
    byte for byte (the truth is emulated again for the checkpoints)."""
    out = tmp_path / "again"
    assert (
        main(
            [
                "process",
                str(run_dir / "small_test.l0.h5"),
                "--scenario",
                str(SMALL),
                "--out",
                str(out),
            ]
        )
        == 0
    )
    made = sorted(p.name for p in out.iterdir() if is_product_file(p))
    assert made == sorted(
        product_name("small_test", 0, lv, lv in ("2A", "2", "3")) for lv in LEVELS
    )
    for name in made:
        assert (out / name).read_bytes() == (run_dir / name).read_bytes(), name
    assert "3 product(s)" in capsys.readouterr().out


def test_station_process_without_the_truth(run_dir: Path, tmp_path: Path, capsys) -> None:
    """Without the scenario: the same images and geometry, quality without checkpoints,
    the options from a file and --levels."""
    opts = tmp_path / "opts.toml"
    opts.write_text("[processing]\ninverse_2a = 'poly5'\n")
    out = tmp_path / "p"
    assert (
        main(
            [
                "process",
                str(run_dir / "small_test.l0.h5"),
                "--options",
                str(opts),
                "--levels",
                "2A",
                "--out",
                str(out),
                "--json",
            ]
        )
        == 0
    )
    rows = json.loads(capsys.readouterr().out)["products"]
    assert [r["level"] for r in rows] == ["2A"]
    assert not any(k.startswith("checkpoints") for k in rows[0])
    p = read_product(out / "small_test_s000_2A.nc")
    assert p.quality["inverse_method"] == "poly5"
    assert p.provenance["scenario"] == "small_test"  # the archive's own provenance


@pytest.mark.parametrize(
    "args, message",
    [
        (["--levels", "1A,4"], "--levels 1A,4"),
        (["--levels", "1A,3"], "level 3 needs a DEM"),
        (["--scenario", str(ROOT / "scenarios" / "quickstart.toml")], "recorded from scenario"),
    ],
)
def test_station_process_bad_input(args, message, run_dir: Path, tmp_path: Path, capsys) -> None:
    assert main(["process", str(run_dir / "small_test.l0.h5"), "--out", str(tmp_path), *args]) == 2
    err = capsys.readouterr().err
    assert err.startswith("station: error: ") and err.count("\n") == 1 and message in err


def test_map_product_opens_georeferenced_in_gdal_and_xarray(run_dir: Path, tmp_path: Path) -> None:
    """GDAL's netCDF driver and xarray read the 2A product itself with the CRS and the
    transform of its GeoTIFF export, exactly; xarray's defaults give rioxarray the CRS."""
    src = run_dir / "small_test_s000_2A.nc"
    tif = tmp_path / "x.tif"
    assert main(["export", str(src), "--geotiff", "--out", str(tif)]) == 0
    with rasterio.open(tif) as t:
        crs, transform, image = t.crs, t.transform, t.read(1)
    with rasterio.open(f'NETCDF:"{src}":P') as n:
        assert n.driver == "netCDF"
        assert n.crs == crs and n.transform == transform
        assert np.array_equal(n.read(1), image)
    xr = pytest.importorskip("xarray")  # the test extra installs it
    with xr.open_dataset(src, engine="h5netcdf") as ds:
        da = ds["P"]
        assert da.dims == ("y", "x") and da.attrs["grid_mapping"] == "crs"
        x, y = ds["x"].values, ds["y"].values
        res = float(x[1] - x[0])
        assert float(y[1] - y[0]) == -res
        # pixel centres → GDAL's corner geotransform
        gt = (float(x[0]) - res / 2, res, 0.0, float(y[0]) + res / 2, 0.0, -res)
        assert gt == transform.to_gdal()
        assert pyproj.CRS.from_wkt(ds["crs"].attrs["crs_wkt"]) == pyproj.CRS(crs.to_wkt())
        assert pyproj.CRS.from_cf(dict(ds["crs"].attrs)).equals(pyproj.CRS(crs.to_wkt()))
        # the counts where valid; the borders (_FillValue = 0) masked as CF says (NaN)
        valid = ds["P_valid"].values.astype(bool)
        assert np.array_equal(da.values[valid], image[valid])
        assert np.isnan(da.values[~valid]).all() and (~valid).any()
    # with xarray's defaults (any engine): the grid mapping is a coordinate carrying the
    # CRS as WKT, which is where rioxarray finds it (``ds.rio.crs``)
    with xr.open_dataset(src) as ds:
        assert "crs" in ds.coords and "crs" not in ds.data_vars
        assert pyproj.CRS.from_wkt(ds.coords["crs"].attrs["spatial_ref"]) == pyproj.CRS(
            crs.to_wkt()
        )
        assert ds["P"].attrs.get("grid_mapping", ds["P"].encoding.get("grid_mapping")) == "crs"


def _as_version_1(src: Path, dst: Path) -> None:
    """A product in the layout of format version 1 (bands under ``bands/<name>/``, no
    dimension scales, grid sizes not beside the grids), made from a version 2 one."""
    import h5py

    with h5py.File(src, "r") as f, h5py.File(dst, "w") as g:
        for k, v in f.attrs.items():
            if k != "attributes_sha256":  # version 1 had no digest
                g.attrs[k] = v
        g.attrs["format_version"] = 1
        for name in json.loads(f.attrs["band_names"]):
            g.create_dataset(f"bands/{name}/image", data=f[name][()])
            g.create_dataset(f"bands/{name}/valid", data=f[f"{name}_valid"][()].astype(bool))
        for tree in ("geometry", "quality", "provenance"):
            f.copy(tree, g)
        for key in ("level_1b", "level_2a"):
            if f"geometry/{key}" in g:
                for k in ("n_rows", "n_cols", "n_raw_lines", "n_raw_columns"):
                    del g[f"geometry/{key}"].attrs[k]


@pytest.mark.parametrize("level", ["1B", "2A"])
def test_version_1_products_are_still_read_and_compared(
    level: str, run_dir: Path, tmp_path: Path
) -> None:
    """A regression campaign compares products of two software versions: a version 1
    product reads as its version 2 twin and compares equal to it."""
    from levels.compare import compare_paths

    src = run_dir / product_name("small_test", 0, level, on_map=level == "2A")
    old = tmp_path / src.name
    _as_version_1(src, old)
    a, b = read_product(old), read_product(src)
    assert a.attrs["format_version"] == 1 and b.attrs["format_version"] == 2
    assert a.map_grid == b.map_grid
    assert np.array_equal(a.bands["P"].image, b.bands["P"].image)
    result = compare_paths(old, src)
    assert result.ok, result.text()


def test_control_points_reach_the_station_as_measured(run_dir: Path) -> None:
    """The run writes the control points as a user has them (docs/gcp.md): the emulator's
    measurements, never the truth, on the L0 archive's rows."""
    from levels.readers.gcp import read_gcps
    from levels.readers.l0 import read_l0
    from station.loader import load_scenario
    from station.spacecraft.emulator import emulate
    from station.truth.optical import truth_for

    archive = read_l0(run_dir / "small_test.l0.h5")
    n_cols = archive.bands["P"].counts.shape[1]
    g = read_gcps(run_dir / "small_test.gcp.csv", archive.n_lines, n_cols)
    scn = load_scenario(SMALL)
    acq = emulate(scn, render=False)
    offset = truth_for(scn, archive).row_offset
    assert len(g) == scn.gcps.count and set(g.hrv) == {1}
    # the file's image positions are the measured ones: the truth plus the pointing error
    d_line = g.line - (acq.gcps.true_line - offset)
    d_col = g.column - acq.gcps.true_column
    assert np.array_equal(g.line, np.round(acq.gcps.line - offset, 3))
    assert 0 < np.abs(np.concatenate([d_line, d_col])).max() < 5 * scn.gcps.pointing_error_px
    assert np.all(g.sigma_px == scn.gcps.pointing_error_px)


@pytest.mark.parametrize(
    "edit, message",
    [
        (lambda t: t.replace(",hrv\n", "\n").replace(",1\n", "\n"), "column 'hrv' is missing"),
        (lambda t: t.replace("hrv1_p0001,", "hrv1_p0000,", 1), "given twice"),
        (lambda t: t.replace(",8,5,0.3,1\n", ",8,5,nan,1\n", 1), "is not finite"),
        (lambda t: t.replace(",8,5,0.3,1\n", ",8,5,0,1\n", 1), "must be positive"),
        (lambda t: t.replace(",8,5,0.3,1\n", ",8,5,0.3,3\n", 1), "expected 1 or 2"),
    ],
)
def test_a_bad_control_point_file_is_named(edit, message, run_dir: Path, tmp_path) -> None:
    from levels.errors import GcpError
    from levels.readers.gcp import read_gcps

    bad = tmp_path / "bad.gcp.csv"
    bad.write_text(edit((run_dir / "small_test.gcp.csv").read_text()))
    with pytest.raises(GcpError, match=message):
        read_gcps(bad)


def test_stored_image_bands_read_the_same_everywhere(run_dir: Path, tmp_path: Path) -> None:
    """``deflate_level = 0`` stores the image bands uncompressed inside the same deflate
    filter: GDAL and h5py read the same pixels as from the compressed product; only the
    size changes (the reduced scene's noise-like 8-bit image: compressed to about 60 %)."""
    opts = tmp_path / "stored.toml"
    opts.write_text("[processing]\ndeflate_level = 0\nlevels = ['2A']\n")
    l0 = run_dir / "small_test.l0.h5"
    argv = ["process", str(l0), "--levels", "2A", "--out"]
    assert main([*argv, str(tmp_path / "z")]) == 0
    assert main([*argv, str(tmp_path / "s"), "--options", str(opts)]) == 0
    z, s = tmp_path / "z" / "small_test_s000_2A.nc", tmp_path / "s" / "small_test_s000_2A.nc"
    a, b = read_product(z), read_product(s)
    assert np.array_equal(a.bands["P"].image, b.bands["P"].image)
    assert np.array_equal(a.bands["P"].valid, b.bands["P"].valid)
    with rasterio.open(f'NETCDF:"{z}":P') as x, rasterio.open(f'NETCDF:"{s}":P') as y:
        assert np.array_equal(x.read(1), y.read(1))
    image_bytes = a.bands["P"].image.nbytes
    assert s.stat().st_size - z.stat().st_size > 0.2 * image_bytes


def test_a_reprocessing_cuts_the_pass_as_the_run_did(tmp_path, capsys) -> None:
    """The archive records how the station cut its pass (``L0Archive.scene_cut``): ``station
    process`` of it alone, with no scenario nor options, makes the run's scenes (it made
    one square scene of 300 lines where the run made two of 150)."""
    from levels.readers.l0 import read_l0
    from station.cli import main

    scn = tmp_path / "cut.toml"
    scn.write_text(SMALL.read_text() + '\n[processing]\nlevels = ["1A"]\nscene_lines = 150\n')
    run, again = tmp_path / "run", tmp_path / "again"
    assert main(["run", str(scn), "--out", str(run), "-q", "--no-quicklooks"]) == 0
    l0 = run / "small_test.l0.h5"
    assert read_l0(l0, lazy=True).scene_cut == {"scene_lines": 150, "overlap_lines": 0}
    assert main(["process", str(l0), "--out", str(again), "-q"]) == 0
    made = sorted(p.name for p in again.glob("*_1A.h5"))
    assert (
        made
        == sorted(p.name for p in run.glob("*_1A.h5"))
        == [
            "small_test_s000_1A.h5",
            "small_test_s001_1A.h5",
        ]
    )
