"""Speed of level 3: L0 → 3 of a full P scene over a 30 m DEM, against GDAL's warp.

Figures printed (issue 19's target in brackets):

1. **L0 → 3 of a full P scene** (6000 × 6000, mirror at +27° over about 1000 m of fractal
   relief), the DEM the world's 1" export (about 30 m), wall time on every core of this
   machine from reading the L0 archive to the product written (< 10 s on 2 cores), with the
   anchor grids (GEO) and the resampling (COR) timed apart. The product's checkpoints
   against the truth are left out (they need the emulator, not the station).
2. **GDAL's warp of the same scene through an equivalent transformation**: geolocation
   arrays (GDAL's ``GEOLOCATION`` metadata: the terrain point each raw pixel sees, every
   16 lines and columns, computed by our rigorous model on the same DEM: Shu Ning's direct
   method) onto the same output grid, cubic, ``rasterio.warp.reproject``, on one thread and
   on every core, measured in the same run. The geolocation arrays are not timed (GDAL
   takes them as given); GDAL neither finds hidden pixels nor interpolates the butting
   segments apart.

Run: ``python benchmarks/bench_level3.py [DIR]``. The scene is emulated and received once
into DIR (about a minute and a half; kept there for the next run), or a temporary
directory. Best of 2.
"""

from __future__ import annotations

import dataclasses
import sys
import tempfile
from pathlib import Path

import numba
import numpy as np
import pyproj
from _smoke import SMOKE, size
from bench_levels import best  # the same best-of-N timer (run as a script: its directory)

from levels.cor.radiometry import calibrate, deconvolution_taps, deconvolve
from levels.geo.level3 import level3_geometry, on_terrain
from levels.geo.maps import map_crs
from levels.options import ProcessingOptions
from levels.process import ProcessingRequest, geo_pass, nominal_pixel_size_m, process
from levels.readers.dem import read_dem
from levels.readers.l0 import read_l0
from station.scenario import ERRORS_OFF, merge_tables, scenario_from_dict

REPEATS = size(2, 1)
GEOLOC_STEP = 16
REFERENCE_HEIGHT_M = 700.0


def make_inputs(directory: Path) -> tuple[Path, Path]:
    """The full P scene's L0 archive and its 1" DEM (emulated once, kept in ``directory``)."""
    from station.chain.session import downlink, record
    from station.spacecraft.dem import export_dem
    from station.spacecraft.emulator import emulate

    l0, dem = directory / "bench3.l0.h5", directory / "bench3.dem.tif"
    if l0.is_file() and dem.is_file():
        return l0, dem
    print("emulating and receiving a full P scene at 27° over 1000 m of relief …", flush=True)
    scn = scenario_from_dict(
        merge_tables(
            ERRORS_OFF,
            {
                "name": "bench3",
                "instrument": {"mirror_step": 93}
                | ({"n_detectors": 600, "n_lines": 600} if SMOKE else {}),
                "world": {"base_height_m": 700.0, "relief_m": 200.0},
                "dem": {"spacing_arcsec": 1.0},
            },
        )
    )
    acq = emulate(scn)
    export_dem([acq], scn.dem, scn.seed, dem)
    record(acq, downlink(acq), l0)
    return l0, dem


def bench_chain(l0: Path, dem: Path, out: Path) -> None:
    opts = dataclasses.replace(
        ProcessingOptions(),
        levels=("3",),
        dem_path=str(dem),
        reference_height_m=REFERENCE_HEIGHT_M,
    )
    t_total, result = best(
        lambda: process(ProcessingRequest.of(read_l0(l0), opts, out, "bench3"))[0], REPEATS
    )
    scene = result.scenes[0]
    t = scene.timings_s
    print(
        f"\n1. L0 → 3, full P scene at 27°, 30 m DEM, {numba.get_num_threads()} threads: "
        f"{t_total:.2f} s (target < 10 s on 2 cores)"
    )
    print(
        f"   GEO (pass) {result.timings_s['geo']:.2f} s; level 3 anchor grids "
        f"{t['geometry_3']:.2f} s; resampling {t['3']:.2f} s; "
        + ", ".join(f"{k} {v:.2f} s" for k, v in t.items() if k not in ("3", "geometry_3"))
    )
    path = scene.paths["3"]
    q = scene.quality["3"]
    print(
        f"   product {path.stat().st_size / 1e6:.1f} MB; anchor error max "
        f"{q['anchor_error_px/P/max_px']:.4f} px (≤ 0.05), hidden "
        f"{q['hidden_fraction/P']:.4f}"
    )


def bench_gdal(l0: Path, dem_path: Path) -> None:
    import rasterio
    import rasterio.warp
    from affine import Affine
    from rasterio.enums import Resampling

    from levels.cor.ortho import resample_3

    archive = read_l0(l0)
    opts = dataclasses.replace(ProcessingOptions(), reference_height_m=REFERENCE_HEIGHT_M)
    setup = geo_pass(archive, opts)
    scene = setup.scenes[0]
    band = archive.bands["P"]
    res = nominal_pixel_size_m(band.look)
    crs = map_crs("utm", scene.centre_lat_rad, scene.centre_lon_rad)
    dem = read_dem(dem_path, "ellipsoid")
    geom = level3_geometry(scene, dem, res, crs)
    valid = band.pixel_valid()
    img, ok = deconvolve(
        calibrate(band.counts, valid, band.gain, band.offset_counts), valid, deconvolution_taps(1.2)
    )
    n_threads = numba.get_num_threads()
    numba.set_num_threads(1)
    t_one, (ours, _ok, _h) = best(lambda: resample_3(img, ok, geom, "cubic"), REPEATS)
    numba.set_num_threads(n_threads)
    t_all, _ = best(lambda: resample_3(img, ok, geom, "cubic"), REPEATS)
    # the terrain point of every 16th raw pixel, by the rigorous model on the same DEM
    nl, nc = img.shape
    gl = np.arange(0, nl, GEOLOC_STEP, dtype=float)
    gc = np.arange(0, nc, GEOLOC_STEP, dtype=float)
    ll, cc = np.meshgrid(gl, gc, indexing="ij")
    lat, lon, _hh, hit = on_terrain(
        scene.model, ll.ravel(), cc.ravel(), geom.dem, float(np.mean(geom.heights_m))
    )
    lon_deg = np.where(hit, np.degrees(lon), -999.0).reshape(ll.shape)
    lat_deg = np.where(hit, np.degrees(lat), -999.0).reshape(ll.shape)
    src = np.nan_to_num(img, nan=0.0).astype(np.float32)
    dst = np.zeros((geom.map_grid.n_rows, geom.map_grid.n_cols), dtype=np.float32)
    with tempfile.TemporaryDirectory() as tmp:
        geo_tif = Path(tmp) / "geoloc.tif"
        with rasterio.open(
            geo_tif,
            "w",
            driver="GTiff",
            width=gc.size,
            height=gl.size,
            count=2,
            dtype="float64",
            nodata=-999.0,
        ) as ds:
            ds.write(np.stack([lon_deg, lat_deg]))
        raw_tif = Path(tmp) / "raw.tif"
        with rasterio.open(
            raw_tif, "w", driver="GTiff", width=nc, height=nl, count=1, dtype="float32"
        ) as ds:
            ds.write(src, 1)
            ds.update_tags(
                ns="GEOLOCATION",
                X_DATASET=str(geo_tif),
                X_BAND="1",
                Y_DATASET=str(geo_tif),
                Y_BAND="2",
                PIXEL_OFFSET="0",
                LINE_OFFSET="0",
                PIXEL_STEP=str(GEOLOC_STEP),
                LINE_STEP=str(GEOLOC_STEP),
                SRS=pyproj.CRS.from_epsg(4326).to_wkt(),
                GEOREFERENCING_CONVENTION="PIXEL_CENTER",
            )

        def gdal(threads: int) -> np.ndarray:
            with rasterio.open(raw_tif) as ds:
                rasterio.warp.reproject(
                    rasterio.band(ds, 1),
                    dst,
                    dst_transform=Affine.from_gdal(*geom.map_grid.geotransform),
                    dst_crs=crs,
                    resampling=Resampling.cubic,
                    num_threads=threads,
                    dst_nodata=0,
                    SRC_METHOD="GEOLOC_ARRAY",
                )
            return dst

        t_gdal1, _ = best(lambda: gdal(1), REPEATS)
        t_gdal, _ = best(lambda: gdal(n_threads), REPEATS)
    mpx = geom.map_grid.n_rows * geom.map_grid.n_cols / 1e6
    print(
        f"\n2. level 3 cubic resampling, {geom.map_grid.n_rows} × {geom.map_grid.n_cols} "
        f"output ({mpx:.1f} Mpx) "
        f"from {nl} × {nc}:"
    )
    print(
        f"   ours, 1 thread {t_one:.2f} s, {n_threads} threads {t_all:.2f} s; GDAL "
        f"{rasterio.__gdal_version__} cubic warp through geolocation arrays, 1 thread "
        f"{t_gdal1:.2f} s, {n_threads} threads {t_gdal:.2f} s"
    )
    print(
        f"   ratio GDAL / ours: {t_gdal1 / t_one:.1f}× on one thread each, "
        f"{t_gdal / t_all:.1f}× on {n_threads} each"
    )
    inside = (ours > 0) & (dst > 0)
    diff = np.abs(ours[inside].astype(float) - np.clip(np.rint(dst[inside]), 0, 255))
    print(
        f"   agreement with GDAL (its geolocation arrays are interpolated between every "
        f"{GEOLOC_STEP}th pixel; a sanity check): median |Δ| {np.median(diff):.1f} counts, "
        f"{inside.mean():.3f} of the grid compared"
    )


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        where = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(tmp)
        where.mkdir(parents=True, exist_ok=True)
        l0, dem = make_inputs(where)
        bench_chain(l0, dem, Path(tmp) / "out")
        bench_gdal(l0, dem)


if __name__ == "__main__":
    main()
