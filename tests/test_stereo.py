"""Stereo (issue 37): ``scenarios/stereo/stereo_pair.toml`` end to end (its kernels are
``tests/levels/test_stereo_kernels.py``'s): two
passes at −22.8° and +27°, their block, the pair's DEM against the true terrain, its
GeoTIFF read by GDAL, and level 3 of both scenes over it.

The reduced pair has 100 m pixels over 400 m of fractal relief: its figures are checked
against bounds measured on it with margin (named below); the full-size figures are
``tools/stereo.py``'s (``docs/stereo.md``).
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

#: The exact disparity's v-parallax on the reduced pair: the epipolar grid's own error plus
#: the adjusted models' relative error across the rows (measured 0.012 px; 0.11 px at full
#: size, where the pixel is 10 times smaller than the same metres of model error).
V_PARALLAX_PX = 0.1
#: The reduced pair's disparity against the exact one: measured 0.135 px RMS (0.119 px NMAD)
#: at 100 m pixels; the issue's 0.2 px RMS is for full P, where 0.19 px is measured
#: (docs/stereo.md).
DISPARITY_RMS_PX = 0.25
#: Share of the pixels both images see where a disparity is kept (measured 0.97).
VALID_SHARE = 0.9
#: Share of the DEM's cells both images see that hold a height (measured 0.99; ≥ 0.95 asked).
COVERAGE = 0.95
#: The DEM's NMAD against the terrain in pixels of 100 m (measured 0.116 px): the matching.
DEM_NMAD_PX = 0.2
#: Its RMSE once the plane the control points leave under it is taken out, in pixels
#: (measured 0.123 px; the plane itself, −32 m at 100 m pixels, is the control points').
DEM_RELATIVE_RMSE_PX = 0.2
#: The DEM's predicted precision against its measured one (the issue's [0.7, 1.5]; 0.88).
PRECISION_RATIO = (0.7, 1.5)
#: Level 3 over the pair's own DEM on the terrain, in pixels (measured 0.20–0.22 px).
LEVEL3_PX = 0.5


#: The block adjustments the stereo run made (each call's passes), counted by its fixture.
ADJUSTED: list[int] = []


@pytest.fixture(scope="module")
def stereo_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    import levels.process
    from station.cli import main

    path = Path(__file__).resolve().parents[1] / "scenarios" / "stereo" / "stereo_pair.toml"
    out = tmp_path_factory.mktemp("stereo") / "run"
    adjust_block = levels.process.adjust_block

    def counted(passes, *args, **kwargs):
        ADJUSTED.append(len(passes))
        return adjust_block(passes, *args, **kwargs)

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(levels.process, "adjust_block", counted)
        assert main(["run", str(path), "--out", str(out), "-q", "--no-quicklooks"]) == 0
    return out


def test_the_pair_is_adjusted_once_and_its_catalogue_declares_what_it_holds(
    stereo_run: Path,
) -> None:
    """Level 3 over the pair's own DEM is made on the block's level 2 as adjusted (adjusted
    again with that DEM under its tie points, it counted the pair's own measurements twice:
    its predicted σ across the base was 11 m where draws give 17, tools/block_draws.py);
    the catalogue's DEM item declares the projection and processing extensions, not view
    and sat, whose fields it has none of."""
    from test_stac import _check_catalog

    assert ADJUSTED == [2]
    from levels.inspect import product_summary, summary_text
    from levels.products import read_product

    dem_path = next((stereo_run / "stereo").glob("*_DEM.nc"))
    said = summary_text(product_summary(read_product(dem_path), dem_path))
    assert "None" not in said  # its provenance says what it knows ("scenario None" before)
    items = {i.id: i for i in _check_catalog(stereo_run)}
    dem = next(i for k, i in items.items() if k.endswith("_DEM"))
    assert not any("/view/" in e or "/sat/" in e for e in dem.stac_extensions)


def test_the_pair_makes_a_dem_measured_against_the_terrain(stereo_run: Path) -> None:
    from levels.products import read_product

    report = json.loads((stereo_run / "report.json").read_text())
    (entry,) = report["stereo"]["dems"]
    dem = read_product(stereo_run / entry["file"])
    assert dem.level == "DEM"
    assert set(dem.bands) == {"height_m", "points", "sigma_m"}
    q = dem.quality
    pixel = dem.geometry["stereo"]["epipolar_pixel_m"]
    assert 0.9 <= dem.geometry["stereo"]["base_to_height"] <= 1.2  # −22.8° and +27°
    assert q["disparity"]["v_parallax_rms_px"] <= V_PARALLAX_PX
    assert q["disparity"]["rms_px"] <= DISPARITY_RMS_PX
    assert q["disparity"]["valid_fraction"] >= VALID_SHARE
    assert q["heights"]["nmad"] <= DEM_NMAD_PX * pixel
    assert q["heights"]["coverage_of_seen"] >= COVERAGE
    rest = q["heights"]["datum_removed"]
    assert rest["rmse"] <= DEM_RELATIVE_RMSE_PX * pixel
    assert PRECISION_RATIO[0] <= rest["measured_over_predicted"] <= PRECISION_RATIO[1]
    assert set(q["heights"]["datum"]) == {"bias_m", "tilt_east_m_per_km", "tilt_north_m_per_km"}
    # the five control points of pass a, measured in b's image too ([gcps] shared)
    from levels.readers.gcp import read_gcps

    shared = read_gcps(stereo_run / "stereo_pair_b" / "stereo_pair_b.gcp.csv")
    assert len(shared) == 5 and all(i.startswith("stereo_pair_a_") for i in shared.id)
    # holes are holes: no height where no point was triangulated
    h, n = dem.bands["height_m"], dem.bands["points"]
    assert np.all(np.isnan(h.image[n.image == 0]))
    assert np.all(n.image[h.valid] > 0)


def test_the_dem_geotiff_opens_georeferenced_in_gdal(stereo_run: Path) -> None:
    import rasterio

    from levels.products import read_product

    report = json.loads((stereo_run / "report.json").read_text())
    (entry,) = report["stereo"]["dems"]
    dem = read_product(stereo_run / entry["file"])
    with rasterio.open(stereo_run / "stereo" / entry["geotiff"]) as ds:
        assert ds.crs is not None and ds.crs.to_wkt()
        assert ds.units == ("m",)  # heights in metres, as GDAL and QGIS say them
        assert ds.transform.to_gdal() == pytest.approx(dem.map_grid.geotransform)
        heights = ds.read(1)
    np.testing.assert_array_equal(heights, dem.bands["height_m"].image)
    # the product itself through GDAL's netCDF driver: its holes no-data, not 0 m (they
    # read as 0 m before the band declared its fill value)
    with rasterio.open(f'NETCDF:"{stereo_run / entry["file"]}":height_m') as ds:
        assert ds.nodata is not None and np.isnan(ds.nodata)
        netcdf = ds.read(1)
    holes = ~dem.bands["height_m"].valid
    assert holes.any() and np.all(np.isnan(netcdf[holes]))
    np.testing.assert_array_equal(netcdf[~holes], dem.bands["height_m"].image[~holes])


def test_level_3_over_the_pairs_own_dem(stereo_run: Path) -> None:
    """No DEM from outside: level 3 of both scenes over the pair's, on the terrain."""
    from levels.products import read_product

    for name in ("stereo_pair_a", "stereo_pair_b"):
        level3 = read_product(stereo_run / "block" / f"{name}_s000_3.nc", images=False)
        assert level3.quality["dem"]["source"].endswith("_DEM.tif")
        ground = level3.quality["checkpoints"]["P"]["ground"]["rms_m"]
        assert ground <= LEVEL3_PX * level3.attrs["pixel_size_m"]


def test_compare_sees_a_dems_heights_in_metres(stereo_run: Path) -> None:
    """`compare` of two DEMs: their heights compared in metres, not as counts (a float band
    cast to integers hid half a metre everywhere); the same DEM is within tolerance."""
    from dataclasses import replace

    from levels.compare import compare_products
    from levels.products import BandImage, read_product

    report = json.loads((stereo_run / "report.json").read_text())
    (entry,) = report["stereo"]["dems"]
    dem = read_product(stereo_run / entry["file"])
    same = compare_products(dem, dem)
    assert not [f for f in same if f.ok is False]
    h = dem.bands["height_m"]
    raised = replace(
        dem, bands={**dem.bands, "height_m": BandImage(h.image + np.float32(0.5), h.valid)}
    )
    found = {f.what: f for f in compare_products(dem, raised)}
    assert found["bands/height_m/max_abs"].ok is False
    assert found["bands/height_m/mean_difference"].value == pytest.approx(-0.5, abs=1e-4)
    assert found["bands/sigma_m/max_abs"].ok is True


def test_compare_of_two_stereo_runs_names_a_dem_raised_half_a_metre(
    stereo_run: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`station compare` of a stereo run (a block: each pass's run, the tie points, the
    block's level 2 and 3, the pair's DEM) with itself: exit 0; with a copy whose DEM is
    raised by 0.5 m: exit 1, the DEM's heights named in metres."""
    import shutil

    import h5py

    from station.cli import EXIT_DIFFERENT, main

    assert main(["compare", str(stereo_run), str(stereo_run)]) == 0
    out = capsys.readouterr().out
    assert "outside tolerance" in out and "0 outside" in out, out
    edited = tmp_path / "run"
    shutil.copytree(stereo_run, edited)
    report = json.loads((stereo_run / "report.json").read_text())
    (entry,) = report["stereo"]["dems"]
    with h5py.File(edited / entry["file"], "r+") as f:
        f["height_m"][...] = f["height_m"][()] + np.float32(0.5)
    assert main(["compare", str(stereo_run), str(edited)]) == EXIT_DIFFERENT
    out = capsys.readouterr().out
    assert f"{entry['file']}: bands/height_m/max_abs = 0.5" in out, out


def _archives(run: Path) -> list[str]:
    return [str(run / n / f"{n}.l0.h5") for n in ("stereo_pair_a", "stereo_pair_b")]


def test_station_process_makes_the_runs_dem_and_level_3_from_its_archives(
    stereo_run: Path, tmp_path: Path
) -> None:
    """The library plans several archives itself: `station process A B --levels 2,DEM,3`
    with the block's scenario (for the truth) makes the run's tie points, level 2, DEM and
    level 3, which `compare` finds within tolerance (exit 0)."""
    from station.cli import main

    out = tmp_path / "proc"
    scenario = Path(__file__).resolve().parents[1] / "scenarios" / "stereo" / "stereo_pair.toml"
    args = ["process", *_archives(stereo_run), "--levels", "2,DEM,3", "--scenario", str(scenario)]
    assert main([*args, "--out", str(out), "-q"]) == 0
    report = json.loads((stereo_run / "report.json").read_text())
    (entry,) = report["stereo"]["dems"]
    made = [entry["file"], *(f"block/stereo_pair_{s}_s000_{lv}.nc" for s in "ab" for lv in "23")]
    for name in made:
        assert main(["compare", str(stereo_run / name), str(out / name), "-q"]) == 0, name
    done = json.loads((out / "process.json").read_text())
    assert done["ties"]["pairs"][0]["points"] == report["ties"]["pairs"][0]["points"]


def test_station_process_takes_the_runs_ties_and_adjustment(
    stereo_run: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """`station process A B --levels 2,DEM --ties RUN/ties --adjustment-from RUN/block`:
    no control point, nothing matched or adjusted, and the run's level 2 and DEM again
    (with the block's scenario, for the truth they are measured against)."""
    import levels.process
    from station.cli import main

    scenario = Path(__file__).resolve().parents[1] / "scenarios" / "stereo" / "stereo_pair.toml"
    solved: list[int] = []
    monkeypatch.setattr(levels.process, "adjust_block", lambda *a, **k: solved.append(1))
    out = tmp_path / "taken"
    taken = ["--ties", str(stereo_run / "ties"), "--adjustment-from", str(stereo_run / "block")]
    args = ["process", *_archives(stereo_run), "--levels", "2,DEM", *taken, "-q"]
    args += ["--scenario", str(scenario)]
    assert main([*args, "--out", str(out)]) == 0
    assert solved == []
    (entry,) = json.loads((stereo_run / "report.json").read_text())["stereo"]["dems"]
    for name in [entry["file"], *(f"block/stereo_pair_{s}_s000_2.nc" for s in "ab")]:
        assert main(["compare", str(stereo_run / name), str(out / name), "-q"]) == 0, name
    assert not (out / "ties").exists()  # taken, not matched into the products


@dataclasses.dataclass(frozen=True)
class _Toy:
    """A toy kind of a pair, declared in this test module alone: the two scenes' level 2
    means, as one pixel of counts."""

    @staticmethod
    def make(a, b, out: Path, measure) -> object:
        from levels.block import PairMade
        from levels.products import BandImage, Product, read_product, write_product

        means = [
            float(p.bands["P"].image[p.bands["P"].valid].mean())
            for p in (read_product(s.products["2"]) for s in (a, b))
        ]
        mean = np.array([[round(sum(means) / 2)]], np.uint8)
        product = Product(
            attrs={"level": "toy", "name": f"{a.name}_{b.name}", "n_rows": 1, "n_cols": 1},
            bands={"P": BandImage(mean, np.ones((1, 1), bool))},
            quality={"means": np.array(means)},
        )
        path = write_product(out / f"{a.name}_{b.name}_toy.h5", product)
        return PairMade(path, None, {"means": means}, {})


def test_a_kind_of_pair_registered_here_is_made_by_station_process(
    stereo_run: Path, tmp_path: Path
) -> None:
    """A new kind is one declaration and one registry entry: a toy pair kind registered
    from this module is planned after level 2 and made by `station process` of two
    archives, with no change to the library; its product reads back."""
    from levels.block import PairMaker
    from levels.kinds import Export, Inspection, ProductKind, Unit
    from levels.products import read_product
    from levels.registry import register_kind, unregister_kind
    from station.cli import main

    toy = ProductKind(
        name="toy",
        doc="the mean of a pair's level 2 (a toy kind)",
        unit=Unit.PAIR,
        on_map=False,
        geometry_trees=(),
        export=Export.NONE,
        inspect=lambda p: Inspection(f"toy of {p.attrs['name']}"),
        requires=("2",),
        maker=PairMaker(_Toy.make, needs=("2",)),
    )
    register_kind(toy)
    try:
        out = tmp_path / "toy"
        args = ["process", *_archives(stereo_run), "--levels", "2,toy", "--out", str(out), "-q"]
        assert main(args) == 0
        made = read_product(out / "stereo" / "stereo_pair_a_stereo_pair_b_toy.h5")
        assert made.level == "toy" and made.bands["P"].image.shape == (1, 1)
        assert main(["inspect", str(out / "stereo" / "stereo_pair_a_stereo_pair_b_toy.h5")]) == 0
    finally:
        unregister_kind("toy")
