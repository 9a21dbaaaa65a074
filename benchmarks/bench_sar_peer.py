"""SAR geocoding beside sarsen (B-Open's, its backward geocoding; issue 38): the same ERS-1
orbit and the same DEM, each DEM cell's (azimuth time, slant range) by both, their
agreement and their time on one thread.

The frame: a full ERS-1 frame (8300 lines of 3 azimuth looks × 5000 slant-range samples,
100 km × 100 km) over the fractal world, its geometry emulated (``render=False``); the
DEM the world's terrain every arc-second (30 m) over the frame. sarsen: its DEM in ECEF
(``sarsen.scene.convert_to_dem_ecef``), its orbit a polynomial fit of the annotation's
state vectors (``OrbitPolyfitInterpolator``, degree 5, every 10 s), its zero-Doppler
solution per cell by Newton's method from a seed grid every 32 cells (its fast path,
``backward_geocode(seed_step=(32, 32))``). Ours: :func:`levels.sar.geocode` onto the DEM's
own grid over that DEM (anchors every 16 cells at 3 heights, the cells' heights, the
per-cell kernel), the masks left out as sarsen's geocoding has none. Both on one thread
(numba's, BLAS's). Printed: each one's time, their ratio (the issue: ours ≥ 3× faster),
and the differences per cell in lines and range samples (RMS, at most).

    pip install sarsen   # the peer (not a dependency of the project)
    python benchmarks/bench_sar_peer.py [--lines 8300 --samples 5000]
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from _smoke import SMOKE, size

TARGET_RATIO = 3.0


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--lines", type=int, default=size(8300, 300))
    p.add_argument("--samples", type=int, default=size(5000, 200))
    args = p.parse_args(argv)
    try:
        import sarsen.geocoding
        import sarsen.orbit
        import sarsen.scene
        import xarray as xr
    except ImportError:
        print("sarsen is not installed (pip install 'spot-station[bench]'): no peer")
        return 0 if SMOKE else 1
    import numba
    from threadpoolctl import threadpool_limits

    from levels.geo.maps import MapGrid
    from levels.sar.geocoding import geocode
    from station.spacecraft.dem import world_dem
    from station.spacecraft.sar import ErsFrame, emulate_frame
    from station.spacecraft.world import World

    world = World(lon0_rad=np.radians(-56.1), base_height_m=200.0, relief_m=400.0, seed=3)
    frame = ErsFrame(n_lines=args.lines, n_samples=args.samples, azimuth_looks=3, range_looks=1)
    image, _ = emulate_frame(frame, world, render=False)
    ann = image.annotation
    # the DEM: the frame's footprint at the terrain's extremes, every arc-second
    n_l, n_s = ann.shape
    lat, lon = (
        np.concatenate(a)
        for a in zip(
            *(
                ann.ground_of_image(
                    np.array([0, 0, n_l - 1, n_l - 1.0]), np.array([0, n_s - 1, 0, n_s - 1.0]), h
                )
                for h in (-1500.0, 2500.0)
            ),
            strict=True,
        )
    )
    step = 1 / 3600
    dem = world_dem(
        world, (lat.min(), lat.max()), (lon.min(), lon.max()), step, 0.0, np.random.default_rng(0)
    )
    z = dem.height_m[::-1]  # south-up for sarsen (its y ascending)
    gt = dem.geotransform
    xs = gt[0] + (np.arange(z.shape[1]) + 0.5) * gt[1]
    ys = gt[3] + (np.arange(z.shape[0])[::-1] + 0.5) * gt[5]
    print(
        f"frame {n_l} × {n_s} slant px ({ann.line_interval_s * 1e3:.2f} ms, "
        f'{ann.range_spacing_m:.2f} m); DEM {z.shape[0]} × {z.shape[1]} cells of 1" '
        f"({z.size / 1e6:.1f} M cells)"
    )
    epoch = np.datetime64(str(ann.epoch.t0_utc).replace("Z", "")[:26], "ns")

    def azimuth(t_s: np.ndarray) -> np.ndarray:
        return epoch + np.round(np.asarray(t_s) * 1e9).astype("timedelta64[ns]")

    position = xr.DataArray(
        ann.state_r_m,
        dims=("azimuth_time", "axis"),
        coords={"azimuth_time": azimuth(ann.state_t_s), "axis": [0, 1, 2]},
    )
    numba.set_num_threads(1)
    with threadpool_limits(1):
        # sarsen
        t = time.perf_counter()
        dem_da = xr.DataArray(z, dims=("y", "x"), coords={"y": ys, "x": xs})
        dem_ecef = sarsen.scene.convert_to_dem_ecef(dem_da, source_crs="EPSG:4326")
        orbit = sarsen.orbit.OrbitPolyfitInterpolator.from_position(position)
        t_guess = float(
            (azimuth(ann.first_line_s + 0.5 * n_l * ann.line_interval_s) - orbit.epoch)
            / np.timedelta64(1, "s")
        )
        acq = sarsen.geocoding.backward_geocode(dem_ecef, orbit, t_guess, seed_step=(32, 32))
        slant = np.sqrt((acq.dem_distance**2).sum("axis")).values
        az = acq.azimuth_time.values
        t_sarsen = time.perf_counter() - t
        # ours, on the DEM's own grid (north-up, as the DEM is)
        t = time.perf_counter()
        grid = MapGrid.north_up(dem.crs_wkt, gt[0], gt[3], gt[1], *dem.height_m.shape)
        g = geocode(image, grid, dem=dem, masks=False)
        ours_l, ours_c = g.line[::-1], g.column[::-1]  # per cell, south-up as sarsen's
        t_ours = time.perf_counter() - t
    line_sarsen = (az - epoch) / np.timedelta64(1, "ns") * 1e-9
    line_sarsen = (line_sarsen - ann.first_line_s) / ann.line_interval_s
    col_sarsen = (slant - ann.near_range_m) / ann.range_spacing_m
    inside = (ours_l >= 0) & (ours_l <= n_l - 1) & (ours_c >= 0) & (ours_c <= n_s - 1)
    dl, dc = (line_sarsen - ours_l)[inside], (col_sarsen - ours_c)[inside]
    ratio = t_sarsen / t_ours
    print(f"  sarsen backward_geocode    {t_sarsen:7.1f} s")
    print(f"  ours (levels.sar.geocode)  {t_ours:7.1f} s   sarsen / ours {ratio:.1f}x")
    verdict = "met" if ratio >= TARGET_RATIO else "NOT met"
    print(f"  ours ≥ {TARGET_RATIO:.0f}x faster on one thread: {verdict}")
    print(
        f"  agreement over {dl.size / 1e6:.1f} M cells in the frame: lines RMS "
        f"{np.sqrt(np.mean(dl**2)):.2e}, at most {np.max(np.abs(dl)):.2e}; range samples RMS "
        f"{np.sqrt(np.mean(dc**2)):.2e}, at most {np.max(np.abs(dc)):.2e}"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
