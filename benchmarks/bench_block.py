"""Speed of the block adjustment: 100 full P scenes in 4 strips, against the target.

Figures printed (issue 36's target in brackets):

* a block of 4 adjacent strips × 25 full P scenes (150 000 lines each, nadir tracks over
  one target on 4 dates of the 26-day cycle, the mirror at −1.8°, −0.6°, +0.6°, +1.8°:
  neighbours share about 40 km of their 60 km swaths), 12 control points in the first strip,
  tie points between neighbours from the truth (0.2 px; ``station.truth.optical``), the
  world's DEM every 10″ with 5 m of error under them (observed with the station's default
  ``tie_height_sigma_m``, 10 m, as ``station process --adjustment block`` does with a
  ``dem_path``): the wall time of :func:`levels.adjust.adjust_block` (≤ 2 s), best of 3,
  with its unknowns, and the scenes' RMS against the truth beside the predicted σ (a
  sanity check).
* the same block without the DEM, once: at base-to-height ratios of 0.02 the tie points'
  free heights let a relative along-track tilt of the strips absorb their y-parallax noise,
  a valley the iterations creep along (``docs/blocks.md``): its time, iterations and
  errors.
* its peer, measured in the same run: the same 100 scenes adjusted strip by strip with
  :func:`levels.adjust.adjust` (what a station without tie points does; the strips
  without control points take their priors).

Run: ``python benchmarks/bench_block.py [scenes_per_strip]`` (default 25). Emulation
(geometry only) and the tie points are not timed.
"""

from __future__ import annotations

import dataclasses
import functools
import operator
import sys
import time

import numpy as np
from _smoke import size

from levels.adjust import Strip, adjust, adjust_block
from levels.options import ProcessingOptions
from levels.readers.gcp import ControlPointSet
from station.chain.gcps import control_points
from station.fixtures import emulated_pass
from station.scenario import scenario_from_dict
from station.spacecraft.dem import world_dem
from station.spacecraft.emulator import emulate
from station.truth.optical import Truth, true_tie_points

TARGET_S = 2.0
DEM_SPACING_DEG = 10 / 3600
DEM_ERROR_M = 5.0
SCENE = size(6000, 1000)
PIXEL_M = 10.0
STEPS = (45, 47, 49, 51)  # the mirror of each strip: −1.8°, −0.6°, +0.6°, +1.8°
DATES = ("1998-02-20", "1998-03-18", "1998-04-13", "1998-05-09")


def strip(k: int, n_scenes: int):
    scn = scenario_from_dict(
        {
            "name": f"strip{k}",
            "seed": 500 + k,
            "pass": {"date_utc": DATES[k], "aim": "nadir"},
            "instrument": {"mirror_step": STEPS[k], "n_lines": n_scenes * SCENE},
            "world": {"relief_m": 400.0},
            "gcps": {"count": 12 if k == 0 else 0},
        }
    )
    acq = emulate(scn, render=False)
    pg, scenes = emulated_pass(acq, SCENE)
    return acq, pg, scenes


def renamed(t: ControlPointSet, prefix: str) -> ControlPointSet:
    """The same tie points under ids unique to their pair of strips."""
    return dataclasses.replace(t, id=tuple(f"{prefix}{i}" for i in t.id))


def tie_dem(acq, ties: list[list[ControlPointSet]]):
    """The world's terrain under every tie point, every ``DEM_SPACING_DEG``, with
    ``DEM_ERROR_M`` of white error."""
    lat = np.concatenate([t[0].lat_rad for t in ties])
    lon = np.concatenate([t[0].lon_rad for t in ties])
    pad = np.radians(0.02)
    return world_dem(
        acq.world,
        (lat.min() - pad, lat.max() + pad),
        (lon.min() - pad, lon.max() + pad),
        DEM_SPACING_DEG,
        DEM_ERROR_M,
        np.random.default_rng(5),
    )


def main() -> None:
    n_scenes = int(sys.argv[1]) if len(sys.argv) > 1 else size(25, 2)
    strips = [strip(k, n_scenes) for k in range(len(STEPS))]
    per: list[list[ControlPointSet]] = [[] for _ in strips]
    rng = np.random.default_rng(36)
    for k in range(len(strips) - 1):
        a, b = true_tie_points(strips[k][0], strips[k + 1][0], size(60, 20), 0.2, rng, 450.0)
        per[k].append(renamed(a, f"p{k}_"))
        per[k + 1].append(renamed(b, f"p{k}_"))
    ties = [[functools.reduce(operator.add, sets)] for sets in per]
    passes = [[Strip(pg, scenes, control_points(acq))] for acq, pg, scenes in strips]
    opts = ProcessingOptions()
    n_ties = len({i for t in ties for i in t[0].id})
    dem = tie_dem(strips[0][0], ties)
    times = []
    for _ in range(size(3, 1)):
        t0 = time.perf_counter()
        res = adjust_block(passes, ties, opts, dem=dem, dem_sigma_m=opts.tie_height_sigma_m)
        times.append(time.perf_counter() - t0)
    ours = min(times)
    n_params = sum(12 * len(p[0].scenes) + 6 for p in passes)
    print(
        f"block of {len(strips)} strips × {n_scenes} scenes ({len(strips) * n_scenes} scenes), "
        f"{n_ties} tie points ({3 * n_ties} ground unknowns), {n_params} parameters: "
        f"{ours:.2f} s [≤ {TARGET_S:g} s: {ours / TARGET_S:.2f}× the target], "
        f"{res[0][0].timings_s['iterations']:.0f} Levenberg–Marquardt iterations (tie points' "
        f"heights observed on a {DEM_SPACING_DEG * 3600:.0f}″ DEM, {DEM_ERROR_M:g} m error)"
    )
    t0 = time.perf_counter()
    free = adjust_block(passes, ties, opts)
    t_free = time.perf_counter() - t0
    print(
        f"the same block, tie points' heights free (no DEM): {t_free:.2f} s, "
        f"{free[0][0].timings_s['iterations']:.0f} iterations"
    )
    t0 = time.perf_counter()
    alone = [adjust(p[0].pg, p[0].scenes, p[0].gcps, opts) for p in passes]
    peer = time.perf_counter() - t0
    print(f"peer, each strip alone (adjust): {peer:.2f} s ({peer / ours:.2f}× the block's)")
    for k, ((acq, pg, scenes), r, f, a) in enumerate(zip(strips, res, free, alone, strict=True)):
        t = Truth(acq, 0)
        sample = scenes[:: max(1, len(scenes) // 5)]

        def rms_px(adj, t=t, pg=pg, sample=sample) -> float:
            e = [np.mean(np.hypot(*t.model_error_en(adj.refine(pg, s))) ** 2) for s in sample]
            return float(np.sqrt(np.mean(e))) / PIXEL_M

        pred = np.sqrt(np.mean(r[0].predicted_sigma_m[:, 2] ** 2)) / PIXEL_M
        print(
            f"  strip {k + 1}: RMS over {len(sample)} of its scenes {rms_px(r[0]):.2f} px in the "
            f"block (predicted {pred:.2f} px), {rms_px(f[0]):.2f} px with free heights, "
            f"{rms_px(a):.2f} px alone"
        )


if __name__ == "__main__":
    main()
