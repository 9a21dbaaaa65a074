"""Speed and accuracy of the algebraic model (RPC00B) against the rigorous one.

Figures printed (issue 20's targets in brackets):

1. **RPC fit of a full P scene** (6000 × 6000, mirror at +27°, the default errors: the
   gyro-integrated attitude with its drift and jitter) over 0–1500 m, wall time, best of 5
   (< 0.5 s), with the fit's error against the rigorous model on the check lattice.
2. **Ground → image of 1 M points**, spread over the scene and the height range: through
   the RPC and through the rigorous model (secant iteration on the line, the project's
   ``PushbroomModel.ground_to_image``), measured in the same run, and how far apart the
   two land (PHOTOMOD's comparison of the physical and the algebraic model, paper
   ``003_…``).
3. **Real DIMAP scenes** (``../shared/refdata/dimap``): fit time and error for each.
4. With an L0 archive given: its first scene's 1A and 2A products, the 1A exported with its
   RPCs and warped by GDAL (``rasterio.warp.reproject`` with the RPC transformer at the
   reference height, cubic) onto the 2A grid: the shift between GDAL's image and our 2A
   (phase correlation; ≤ 0.5 px), and GDAL's warp time beside our 2A resampling's.

Run: ``python benchmarks/bench_rpc.py [L0.h5]`` (``bench_level3.py``'s archive, for one, is
a full P scene at 27°).
"""

from __future__ import annotations

import dataclasses
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from _smoke import size
from bench_levels import best  # the same best-of-N timer (run as a script: its directory)

from levels.geo.rpc import rpc_of_model
from levels.quality import image_shift_px
from levels.readers.dimap import read_dimap
from station.fixtures import emulated_scene
from station.scenario import scenario_from_dict
from station.spacecraft.emulator import emulate

HEIGHTS_M = (0.0, 1500.0)
N_POINTS = size(1_000_000, 20_000)
REFDATA = Path(__file__).resolve().parents[2] / "shared" / "refdata" / "dimap"


def main() -> None:
    scn = scenario_from_dict({"name": "bench_rpc", "instrument": {"mirror_step": 93}})
    _pg, scene, _res = emulated_scene(emulate(scn, render=False))
    model = scene.model
    t_fit, rpc = best(lambda: rpc_of_model(model, HEIGHTS_M), 5)
    e = rpc.fit_error_px
    print(
        f"1. RPC fit, full P scene at 27° ({model.n_lines} × {model.n_columns}), default "
        f"errors, heights {HEIGHTS_M[0]:.0f}–{HEIGHTS_M[1]:.0f} m: {t_fit:.3f} s "
        "(target < 0.5 s)"
    )
    print(
        f"   error against the rigorous model ({e['n_points']} check points): RMS "
        f"{e['rms_px']:.4f} px, max {e['max_px']:.4f} px (line {e['line_max_px']:.4f}, "
        f"sample {e['sample_max_px']:.4f}): the CCD buttings' along-track steps and the "
        "attitude's jitter, which a smooth function does not follow"
    )
    rng = np.random.default_rng(1)
    line = rng.uniform(0, model.n_lines - 1, N_POINTS)
    col = rng.uniform(0, model.n_columns - 1, N_POINTS)
    h = rng.uniform(*HEIGHTS_M, N_POINTS)
    g = model.image_to_ground(line, col, h)
    lat, lon = np.degrees(g.lat_rad), np.degrees(g.lon_rad)
    t_rpc, (rl, rc) = best(lambda: rpc.image_of(lat, lon, h), 3)
    t0 = time.perf_counter()
    rig = model.ground_to_image(g.lat_rad, g.lon_rad, h)
    t_rig = time.perf_counter() - t0
    d = np.hypot(rl - rig.line, rc - rig.column)
    print(
        f"\n2. ground → image of {N_POINTS:,} points: RPC {t_rpc:.3f} s, rigorous model "
        f"{t_rig:.2f} s ({t_rig / t_rpc:.0f}× the RPC's time); the two apart by RMS "
        f"{np.sqrt(np.mean(d**2)):.4f} px, max {d.max():.4f} px; the rigorous model "
        f"against the points' own (line, column): max "
        f"{np.max(np.hypot(rig.line - line, rig.column - col)):.1e} px"
    )
    print("\n3. real DIMAP scenes, heights 0–3000 m:")
    for path in sorted(REFDATA.glob("*.DIM")):
        dim = read_dimap(path)
        if dim.ephemeris is None or not dim.look_angles:
            print(f"   {path.name}: frame only, no model")
            continue
        m = dim.model()
        t, r = best(lambda m=m: rpc_of_model(m, (0.0, 3000.0)), 3)
        e = r.fit_error_px
        print(
            f"   {dim.name} ({m.n_lines} × {m.n_columns}): fit {t:.3f} s, RMS "
            f"{e['rms_px']:.5f} px, max {e['max_px']:.5f} px"
        )


def warp_check(l0: Path) -> None:
    import rasterio
    import rasterio.warp
    from affine import Affine
    from rasterio.enums import Resampling

    from levels.export import write_geotiff
    from levels.options import ProcessingOptions
    from levels.process import ProcessingRequest, process
    from levels.products import read_product
    from levels.readers.l0 import read_l0

    with tempfile.TemporaryDirectory() as tmp:
        opts = dataclasses.replace(ProcessingOptions(), levels=("1A", "2A"))
        result = process(ProcessingRequest.of(read_l0(l0), opts, Path(tmp), "rpcwarp"))[0]
        scene = result.scenes[0]
        p1, p2 = (read_product(scene.paths[k]) for k in ("1A", "2A"))
        tif = write_geotiff(p1, Path(tmp) / "1a.tif")
        grid = p2.map_grid
        assert grid is not None
        height = json.loads(p2.provenance["processing"])["reference_height_m"]
        warped = np.zeros(p2.bands["P"].image.shape, dtype=np.float32)
        with rasterio.open(tif) as ds:
            t0 = time.perf_counter()
            rasterio.warp.reproject(
                rasterio.band(ds, 1),
                warped,
                rpcs=ds.rpcs,
                src_crs="EPSG:4326",
                dst_transform=Affine.from_gdal(*grid.geotransform),
                dst_crs=grid.crs_wkt,
                resampling=Resampling.cubic,
                dst_nodata=0,
                num_threads=1,
                RPC_HEIGHT=height,
            )
            t_gdal = time.perf_counter() - t0
        both = p2.bands["P"].valid & (warped > 0)
        dr, dc = image_shift_px(p2.bands["P"].image, warped, both)
        e = p1.geometry["rpc"]["P"]["fit_error_px"]
        print(
            f"\n4. gdalwarp -rpc of the exported 1A ({p1.bands['P'].image.shape[0]} × "
            f"{p1.bands['P'].image.shape[1]}, RPC fit RMS {e['rms_px']:.3f} px, max "
            f"{e['max_px']:.3f} px) at {height:.0f} m onto our 2A grid: shift "
            f"({dr:+.3f}, {dc:+.3f}) px (rows, columns; ≤ 0.5 px), {both.mean():.2f} of the "
            f"grid compared; GDAL's warp {t_gdal:.1f} s on one thread, our 2A resampling "
            f"{scene.timings_s['2A']:.1f} s on every core"
        )


if __name__ == "__main__":
    main()
    if len(sys.argv) > 1:
        warp_check(Path(sys.argv[1]))
