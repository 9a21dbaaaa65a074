"""Control points of a full P scene found on a 10 m reference ortho-image (issue 51's
target: ≤ 20 s on 2 cores), with their accuracy against the truth.

The default P scene (6000 × 6000, emulated and received first, about a minute), its world
rendered as an exact 10 m panchromatic reference over the scene (``station.spacecraft.
reference``) and as a 3″ DEM; then :func:`levels.reference.reference_control_points` timed
(windows orthorectified on the current model, phase correlation, level 2's adjustment, in
a loop), and the points scored against the truth: where their raw pixel truly looks.
AROSICS (the peer named by the issue) is not installed here (``pip install arosics``): its
figure is not printed.

    python benchmarks/bench_reference.py        (BENCH_SMOKE=1: a 600 × 600 scene, once)
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np
from _smoke import SMOKE
from bench_levels import make_l0

TARGET_S = 20.0


def main() -> None:
    from levels.geo.maps import MapGrid
    from levels.geometry.ellipsoid import WGS84
    from levels.geometry.frames import apply, enu_from_ecef
    from levels.options import ProcessingOptions
    from levels.process import geo_pass
    from levels.readers.l0 import read_l0
    from levels.reference import Reference, raw_images, reference_control_points
    from station.scenario import ReferenceConfig, scenario_from_dict
    from station.spacecraft.dem import world_dem
    from station.spacecraft.emulator import _world
    from station.spacecraft.reference import render_reference
    from station.truth.optical import truth_for

    small = {"instrument": {"n_detectors": 600, "n_lines": 600}} if SMOKE else {}
    scn = scenario_from_dict({"name": "bench", **small})
    with tempfile.TemporaryDirectory() as tmp:
        archive = read_l0(make_l0(Path(tmp)), lazy=True)
        opts = ProcessingOptions(levels=("2",))
        setup = geo_pass(archive, opts)
        scene = setup.scenes[0]
        world = _world(scn)
        lat, lon = scene.corners_lat_rad, scene.corners_lon_rad
        m = np.radians(0.02)
        lr, lo = (lat.min() - m, lat.max() + m), (lon.min() - m, lon.max() + m)
        pixel = 100.0 if SMOKE else 10.0
        t = time.perf_counter()
        ref_img = render_reference(world, lr, lo, ReferenceConfig(pixel_size_m=pixel), 1)
        dem = world_dem(world, lr, lo, 1 / 1200, 0.0, np.random.default_rng(0))
        print(
            f"a {scene.cut.n_lines} × {scene.model.n_columns} P scene; the reference "
            f"{ref_img.image.shape[0]} × {ref_img.image.shape[1]} at {pixel:g} m rendered in "
            f"{time.perf_counter() - t:.0f} s"
        )
        raw_of = raw_images(archive, next(iter(archive.bands)))

        grid = MapGrid(ref_img.crs_wkt, ref_img.geotransform, *ref_img.image.shape)
        ref = Reference(ref_img.image, grid, 0.0, "reference")
        t = time.perf_counter()
        found = reference_control_points(setup.pg, [scene], raw_of, ref, dem, opts, archive.hrv)
        took = time.perf_counter() - t
        g = found.points
        truth = truth_for(scn, archive)
        true = truth.ground(0, g.line + truth.row_offset, g.column)
        la, lo_, _ = WGS84.to_geodetic(true)
        enu = apply(enu_from_ecef(la, lo_), WGS84.to_ecef(g.lat_rad, g.lon_rad, g.h_m) - true)
        err = np.hypot(enu[:, 0], enu[:, 1])
        err = err[np.isfinite(err)]
        shifts = " → ".join(f"{loop['mean_shift_px']:.3f}" for loop in found.loops)
        print(
            f"control points: {len(g)} in {took:.1f} s (target ≤ {TARGET_S:.0f} s: "
            f"{took / TARGET_S:.2f}× it); loops' mean shift {shifts} px"
        )
        print(
            f"against the truth: {np.sqrt(np.mean(err**2)):.2f} m RMS, median "
            f"{np.median(err):.2f} m ({np.median(err) / pixel:.3f} reference px); AROSICS: "
            "not installed (pip install arosics), not measured"
        )


if __name__ == "__main__":
    main()
