"""Speed and accuracy of the stereo chain on a full P pair, beside CNES's pandora.

Figures printed (issue 37's targets in brackets):

1. **The full P pair** (``scenarios/stereo/stereo_pair.toml`` at full size: 6000 × 6000,
   10 m, mirror −22.8° and +27°, B/H 1.09): wall time of each stage of
   :func:`levels.stereo.stereo_dem` (epipolar grids, resampling, coarse range, matching,
   triangulation, gridding) and their sum (≤ 120 s on 2 cores).
2. **The peer on the same epipolar images**: pandora (census 5 × 5, libsgm's SGM with the
   same P1/P2, WTA, V-fit sub-pixel, cross-checking; what CARS runs) and ours
   (:func:`levels.stereo.match`: OpenCV SGBM and the least-squares refinement), on one
   ``TILE_PX`` tile of the pair (pandora keeps the whole cost volume in memory: the full
   pair would need tens of GB, CARS tiles it the same way): the time of each and their
   disparities against the exact one (the truth), RMS and NMAD on the pixels each keeps.

Run: ``python benchmarks/bench_stereo.py [DIR]``: the full-size pair is emulated and run
once into DIR by ``tools/stereo.py`` (about ten minutes; kept for the next run), or read
from it. Best of 2 for our stages.
"""

from __future__ import annotations

import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from _smoke import SMOKE, size

REPEATS = size(2, 1)
TARGET_S = 120.0
TILE_PX = size(1024, 256)


def _stages(pair, d_range):
    from levels.stereo import (
        BLUNDER_FLOOR_PX,
        blunder_cells,
        coarse_range,
        dem_grid,
        grid_points,
        match,
        triangulate,
    )

    t = {}
    t0 = time.perf_counter()
    left, right = pair.image(0), pair.image(1)
    t["resample"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    rng = coarse_range(left, right, d_range)
    t["coarse range"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    disparity = match(left, right, *rng)
    t["matching"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    points, _ = triangulate(pair, disparity, rng, 1)
    t["triangulation"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    grid = dem_grid(points, pair.frame.crs_wkt, 2 * pair.frame.pixel_m)
    h, _, _ = grid_points(points, grid)
    blunder_cells(h, BLUNDER_FLOOR_PX * pair.height_per_px_m)
    t["gridding"] = time.perf_counter() - t0
    return t, left, right, rng


def _pandora(left: np.ndarray, right: np.ndarray, d_lo: float, d_hi: float) -> np.ndarray:
    """Pandora's disparity of two epipolar tiles (its convention: ``right(u + d) =
    left(u)``, ours)."""
    import logging

    import pandora
    import rasterio
    from pandora.check_configuration import check_conf
    from pandora.img_tools import create_dataset_from_inputs
    from pandora.state_machine import PandoraMachine

    logging.getLogger().setLevel(logging.WARNING)
    with tempfile.TemporaryDirectory() as d:
        paths = []
        for name, img in (("left", left), ("right", right)):
            p = Path(d) / f"{name}.tif"
            profile = {"driver": "GTiff", "width": img.shape[1], "height": img.shape[0]}
            with rasterio.open(p, "w", count=1, dtype="float32", **profile) as ds:
                ds.write(np.nan_to_num(img, nan=-9999.0).astype(np.float32), 1)
            paths.append(str(p))
        cfg = {
            "input": {
                "left": {
                    "img": paths[0],
                    "disp": [int(np.floor(d_lo)), int(np.ceil(d_hi))],
                    "nodata": -9999,
                },
                "right": {"img": paths[1], "nodata": -9999},
            },
            "pipeline": {
                "matching_cost": {"matching_cost_method": "census", "window_size": 5},
                "optimization": {
                    "optimization_method": "sgm",
                    "penalty": {"penalty_method": "sgm_penalty", "P1": 8, "P2": 32},
                },
                "disparity": {"disparity_method": "wta", "invalid_disparity": "NaN"},
                "refinement": {"refinement_method": "vfit"},
                "validation": {"validation_method": "cross_checking_accurate"},
            },
        }
        pandora.import_plugin()
        machine = PandoraMachine()
        cfg = check_conf(cfg, machine)
        img_l = create_dataset_from_inputs(input_config=cfg["input"]["left"])
        cfg["input"]["right"]["disp"] = [
            -cfg["input"]["left"]["disp"][1],
            -cfg["input"]["left"]["disp"][0],
        ]
        img_r = create_dataset_from_inputs(input_config=cfg["input"]["right"])
        out, _ = pandora.run(machine, img_l, img_r, cfg)
    d = out["disparity_map"].values.astype(np.float64)
    if "validity_mask" in out:
        d[out["validity_mask"].values != 0] = np.nan
    return d


def _errors(d: np.ndarray, exact: dict, r0: int, c0: int) -> str:
    k = (exact["v"] >= r0) & (exact["v"] < r0 + TILE_PX)
    k &= (exact["u"] >= c0) & (exact["u"] < c0 + TILE_PX)
    got = d[(exact["v"][k] - r0).astype(int), (exact["u"][k] - c0).astype(int)]
    e = got - exact["d"][k]
    ok = np.isfinite(e)
    e = e[ok]
    nmad = 1.4826 * np.median(np.abs(e - np.median(e)))
    return (
        f"kept {ok.mean():.1%}, RMS {np.sqrt(np.mean(e**2)):.3f} px, NMAD {nmad:.3f} px, "
        f"beyond 1 px {np.mean(np.abs(e) > 1):.2%}"
    )


def main(argv: list[str]) -> int:
    from stereo import pair_and_truth  # tools/stereo.py

    from levels.stereo import match
    from station.truth.stereo import exact_disparity

    where = Path(argv[0]) if argv else Path(tempfile.mkdtemp(prefix="bench_stereo_"))
    t0 = time.perf_counter()
    pair, truth, d_range = pair_and_truth(where, full=not SMOKE)
    t_pair = time.perf_counter() - t0
    best: dict[str, float] = {}
    for _ in range(REPEATS):
        t, left, right, rng = _stages(pair, d_range)
        best = {k: min(v, best.get(k, np.inf)) for k, v in t.items()}
    total = sum(best.values())
    print(
        f"full P pair {pair.frame.shape[1]} × {pair.frame.shape[0]} epipolar px, B/H "
        f"{pair.base_to_height:.2f}, disparities {rng[0]:.0f} … {rng[1]:.0f} px"
    )
    print(f"  the pair's products read, the truth, the epipolar grids: {t_pair:.1f} s")
    for k, v in best.items():
        print(f"  {k:14s} {v:6.1f} s")
    print(
        f"  total          {total:6.1f} s   target ≤ {TARGET_S:.0f} s: "
        f"{'met' if total <= TARGET_S else 'NOT met'} ({total / TARGET_S:.2f} of it)"
    )
    # the peer, on one tile of the same epipolar images
    rows, cols = left.shape
    r0, c0 = (rows - TILE_PX) // 2, (cols - TILE_PX) // 2
    exact = exact_disparity(pair, truth, 2, (r0, r0 + TILE_PX, c0, c0 + TILE_PX))
    tl = left[r0 : r0 + TILE_PX, c0 : c0 + TILE_PX]
    tr = right[r0 : r0 + TILE_PX, c0 : c0 + TILE_PX]
    lo, hi = float(np.nanmin(exact["d"])) - 8, float(np.nanmax(exact["d"])) + 8
    t0 = time.perf_counter()
    ours = match(tl, tr, lo, hi).d
    t_ours = time.perf_counter() - t0
    print(f"a {TILE_PX} × {TILE_PX} tile, disparities {lo:.0f} … {hi:.0f} px:")
    print(f"  ours (SGBM + least squares) {t_ours:6.1f} s: {_errors(ours, exact, r0, c0)}")
    try:
        t0 = time.perf_counter()
        theirs = _pandora(tl, tr, lo, hi)
        t_theirs = time.perf_counter() - t0
    except ImportError:
        print("  pandora is not installed (pip install 'spot-station[bench]'): no peer")
        return 0 if SMOKE else 1
    print(f"  pandora (census, libsgm)    {t_theirs:6.1f} s: {_errors(theirs, exact, r0, c0)}")
    print(f"  ours / pandora time: {t_ours / t_theirs:.2f}")
    report = where / "report.json"
    if report.is_file():
        q = json.loads(report.read_text())["stereo"]["dems"][0]["quality"]
        print(f"the run's own figures: disparity {q['disparity']['rms_px']:.3f} px RMS")
    return 0


if __name__ == "__main__":
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tools"))
    raise SystemExit(main(sys.argv[1:]))
