"""Blocks at full size: the figures of issue 36, measured against the emulated truth.

Geometry only (no image): a block of two adjacent strips × three full P scenes (6000 ×
18000 lines each), on two dates 26 days apart, their views overlapping through the mirror
(nadir tracks over one target, the mirror at −1.2° and +1.2°: about 25 km of the 60 km
swaths in common), the default
errors drawn independently per pass; **one control point**, at the start of the first
strip; tie points between the strips from the truth (``station.truth.optical.true_tie_points``,
0.2 px of noise: the matcher's figure, ``docs/blocks.md``) and the world's 3″ DEM with 5 m
of error under them. Each scene's model against the truth's line of sight, 11 × 11 lattice.

    python tools/blocks.py             # 10 blocks (about 1 min)
    python tools/blocks.py --blocks 3
    python tools/blocks.py --set gcps.horizontal_error_m=0 --set attitude.yaw_offset_urad=0

``--set section.key=value`` changes the emulated errors of both strips (the processing's
priors stay the defaults): the block's error budget, one source switched off at a time.

Printed per block and over all: RMS of every scene in P pixels (10 m) for each strip alone
(its control point or none: the priors) and in the block; the block's predicted σ and the
ratio measured / predicted.
"""

from __future__ import annotations

import argparse
from typing import Any

import numpy as np
from overrides import scenario_changes  # tools/overrides.py

from levels.adjust import Strip, adjust, adjust_block
from levels.options import ProcessingOptions
from station.chain.gcps import control_points
from station.fixtures import emulated_pass
from station.scenario import merge_tables, scenario_from_dict
from station.spacecraft.dem import world_dem
from station.spacecraft.emulator import emulate
from station.truth.optical import Truth, true_tie_points

SCENE = 6000
PIXEL_M = 10.0
TIE_SIGMA_PX = 0.2
DEM_SIGMA_M = 5.0
#: date, mirror step, control points, their line ranges: both nadir tracks over the
#: target (the world is centred on it: one ground), the views ±1.2° aside, ~17 km each way
STRIPS = (
    ("1998-02-20", 46, 1, [0.0, 0.05]),
    ("1998-03-18", 50, 0, [0.05, 0.95]),
)


def strip(seed: int, k: int, changes: dict | None = None, opposite: bool = False):
    """Strip ``k`` of block ``seed``; ``opposite``: the second strip gets a control point
    too, at its far end (the block's opposite corner)."""
    date, step, count, ranges = STRIPS[k]
    if opposite and k == 1:
        count, ranges = 1, [0.95, 1.0]
    scn = scenario_from_dict(
        merge_tables(
            {
                "name": f"block{seed}_{k}",
                "seed": 1000 * seed + k,
                "pass": {"date_utc": date, "aim": "nadir"},
                "instrument": {"mirror_step": step, "n_lines": 3 * SCENE},
                "world": {"relief_m": 400.0},
                "gcps": {"count": count, "line_ranges": ranges},
            },
            changes or {},
        )
    )
    acq = emulate(scn, render=False)
    pg, scenes = emulated_pass(acq, SCENE)
    return acq, pg, scenes


def block_dem(acq) -> Any:
    """The world's terrain every 3″ over the block, with ``DEM_SIGMA_M`` of white error."""
    lat, lon = np.radians(-15.6), np.radians(-56.1)
    return world_dem(
        acq.world,
        (lat - np.radians(0.9), lat + np.radians(0.9)),
        (lon - np.radians(0.45), lon + np.radians(0.45)),
        3 / 3600,
        DEM_SIGMA_M,
        np.random.default_rng(5),
    )


def errors_px(acq, pg, scenes, adj) -> np.ndarray:
    t = Truth(acq, 0)
    return (
        np.array(
            [np.sqrt(np.mean(np.hypot(*t.model_error_en(adj.refine(pg, s))) ** 2)) for s in scenes]
        )
        / PIXEL_M
    )


def a_priori_px(acq, pg, scenes) -> np.ndarray:
    """Each scene's system model (2A's) against the truth: what a strip without a control
    point and without tie points keeps (the station makes no level 2 of it)."""
    t = Truth(acq, 0)
    return np.array([np.sqrt(np.mean(np.hypot(*t.model_error_en(s)) ** 2)) for s in scenes]) / (
        PIXEL_M
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--blocks", type=int, default=10)
    ap.add_argument("--set", action="append", default=[], metavar="SECTION.KEY=VALUE")
    ap.add_argument(
        "--opposite", action="store_true", help="a second control point, in the opposite corner"
    )
    args = ap.parse_args()
    changes = scenario_changes(args.set)
    opts = ProcessingOptions()
    alone_all, block_all, pred_all = [], [], []
    for seed in range(args.blocks):
        a, b = strip(seed, 0, changes), strip(seed, 1, changes, args.opposite)
        ta, tb = true_tie_points(a[0], b[0], 40, TIE_SIGMA_PX, np.random.default_rng(seed), 450.0)
        dem = block_dem(a[0])
        sa, sb = (Strip(p[1], p[2], control_points(p[0])) for p in (a, b))
        res = adjust_block([[sa], [sb]], [[ta], [tb]], opts, dem=dem, dem_sigma_m=DEM_SIGMA_M)
        alone = [
            errors_px(*a, adjust(a[1], a[2], control_points(a[0]), opts)),
            errors_px(*b, adjust(b[1], b[2], control_points(b[0]), opts))
            if len(control_points(b[0]))
            else a_priori_px(*b),
        ]
        block = [errors_px(*a, res[0][0]), errors_px(*b, res[1][0])]
        pred = [
            res[0][0].predicted_sigma_m[:, 2] / PIXEL_M,
            res[1][0].predicted_sigma_m[:, 2] / PIXEL_M,
        ]
        alone_all.append(np.concatenate(alone))
        block_all.append(np.concatenate(block))
        pred_all.append(np.concatenate(pred))
        print(
            f"block {seed}: {len(ta.id)} tie points; strip 1 alone "
            + " ".join(f"{x:.2f}" for x in alone[0])
            + " px; in the block "
            + " ".join(f"{x:.2f}" for x in block[0])
            + " | strip 2 in the block "
            + " ".join(f"{x:.2f}" for x in block[1])
            + " px (predicted "
            + " ".join(f"{x:.2f}" for x in pred[1])
            + ")"
        )
    blk, prd = np.array(block_all), np.array(pred_all)
    alone_a, alone_b = np.array(alone_all)[:, :3], np.array(alone_all)[:, 3:]
    rms = lambda x: float(np.sqrt(np.nanmean(np.square(x))))  # noqa: E731
    print(
        f"over {args.blocks} blocks, every scene: block RMS {rms(blk):.2f} px (max scene "
        f"{np.nanmax(blk):.2f} px; target ≤ 1.5), predicted {rms(prd):.2f} px, measured / "
        f"predicted {rms(blk) / rms(prd):.2f} (target [0.7, 1.5]); strip 1 alone with its one "
        f"control point {rms(alone_a):.2f} px; strip 2 alone: "
        + (
            f"no control point, no level 2 (its system model {rms(alone_b):.2f} px)"
            if not args.opposite
            else f"its one control point {rms(alone_b):.2f} px"
        )
    )


if __name__ == "__main__":
    main()
