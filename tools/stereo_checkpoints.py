"""PHOTOMOD's checkpoints on many draws of the full P stereo pair, geometry only (no image).

The pair of ``scenarios/stereo/stereo_pair.toml`` at full size (6000 × 6000, mirror −22.8°
and +27°, 400 m of relief), the default errors drawn anew per draw: five control points of
the first pass, each also measured in the second's image with the scenario's pointing
error (``[gcps] shared``), tie points from the truth
(``station.truth.optical.true_tie_points``: a 10 × 10 lattice, 0.2 px of noise, the
matcher's figure), one block adjustment; then 25 checkpoints of the terrain, their true
image positions in both scenes with ``--pointing`` px of error (default 0.3, the control
points'), triangulated on the adjusted models (``levels.stereo.triangulate_raw``: the
middle of the common perpendicular). Printed per draw and over all: plan and height RMS,
and the height bias.

    python tools/stereo_checkpoints.py [--draws 10] [--pointing 0.3] [--set gcps.count=15]

Where the height error comes from (``docs/stereo.md``): switch one error on at a time,
e.g. ``--pointing 0 --set gcps.horizontal_error_m=0.1 --set gcps.pointing_error_px=0.02``
leaves the control points' heights alone.
"""

from __future__ import annotations

import argparse

import numpy as np
from overrides import scenario_changes  # tools/overrides.py

from levels.adjust import Strip, adjust_block
from levels.geometry.ellipsoid import WGS84
from levels.options import ProcessingOptions
from levels.readers.gcp import ControlPointSet
from levels.stereo import triangulate_raw
from station.chain.gcps import control_points
from station.fixtures import emulated_pass
from station.scenario import merge_tables, scenario_from_dict
from station.spacecraft.emulator import emulate, truth_model
from station.truth.optical import Truth, true_tie_points

SCENE = 6000
TIE_SIGMA_PX = 0.2
PASSES = (("1998-02-20", 10, 5), ("1998-02-23", 93, 0))


def _pass(seed: int, k: int, changes: dict):
    date, step, count = PASSES[k]
    scn = scenario_from_dict(
        merge_tables(
            {
                "name": f"pair{seed}_{k}",
                "seed": 1000 * seed + k,
                "pass": {"date_utc": date},
                "instrument": {"mirror_step": step, "n_lines": SCENE},
                "world": {"relief_m": 400.0},
                "gcps": {"count": count},
            },
            changes if k == 0 else {k: v for k, v in changes.items() if k != "gcps"},
        )
    )
    acq = emulate(scn, render=False)
    pg, scenes = emulated_pass(acq, SCENE)
    return acq, pg, scenes


def _shared(acq_a, acq_b, rng: np.random.Generator) -> ControlPointSet:
    """``acq_a``'s control points measured in ``acq_b``'s image (its true model), with the
    control points' pointing error."""
    cp, g = control_points(acq_a), acq_a.gcps
    seen = truth_model(acq_b).ground_to_image(g.true_lat_rad, g.true_lon_rad, g.true_h_m)
    pointing = acq_a.scenario.gcps.pointing_error_px
    line = seen.line + pointing * rng.standard_normal(seen.line.size)
    col = seen.column + pointing * rng.standard_normal(seen.line.size)
    k = np.flatnonzero(
        seen.converged & (line > 0) & (line < SCENE - 1) & (col > 0) & (col < SCENE - 1)
    )
    return ControlPointSet(
        tuple(cp.id[i] for i in k),
        cp.lon_rad[k],
        cp.lat_rad[k],
        cp.h_m[k],
        line[k],
        col[k],
        cp.sigma_ground_m[k],
        cp.sigma_h_m[k],
        cp.sigma_px[k],
        np.full(k.size, acq_b.hrv.number, dtype=np.int64),
    )


def _checkpoints(
    a, b, models, pointing: float, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """Plan and height errors (m) of checkpoints triangulated on ``models``."""
    (acq_a, _, _), (acq_b, _, _) = a, b
    line, col = (
        x.ravel()
        for x in np.meshgrid(
            np.linspace(0.1, 0.9, 7) * (SCENE - 1),
            np.linspace(0.1, 0.9, 7) * (SCENE - 1),
            indexing="ij",
        )
    )
    lat, lon, h = WGS84.to_geodetic(Truth(acq_a, 0).ground(0, line, col))
    seen = truth_model(acq_b).ground_to_image(lat, lon, h)
    ok = seen.converged & (seen.line > 0) & (seen.line < SCENE - 1)
    ok &= (seen.column > 0) & (seen.column < SCENE - 1) & np.isfinite(h)
    k = np.flatnonzero(ok)[:25]
    noise = pointing * rng.standard_normal((4, k.size))
    plat, plon, ph, _ = triangulate_raw(
        *models,
        line[k] + noise[0],
        col[k] + noise[1],
        seen.line[k] + noise[2],
        seen.column[k] + noise[3],
    )
    north = (plat - lat[k]) * WGS84.a_m
    east = (plon - lon[k]) * WGS84.a_m * np.cos(lat[k])
    return np.hypot(east, north), ph - h[k]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--draws", type=int, default=10)
    ap.add_argument("--pointing", type=float, default=0.3, help="checkpoints' pointing, px")
    ap.add_argument("--set", action="append", default=[], metavar="SECTION.KEY=VALUE")
    args = ap.parse_args()
    changes = scenario_changes(args.set)
    opts = ProcessingOptions()
    plans, heights, biases = [], [], []
    for seed in range(args.draws):
        rng = np.random.default_rng(seed)
        a, b = _pass(seed, 0, changes), _pass(seed, 1, changes)
        ta, tb = true_tie_points(a[0], b[0], 10, TIE_SIGMA_PX, rng, 450.0)
        sa = Strip(a[1], a[2], control_points(a[0]))
        sb = Strip(b[1], b[2], _shared(a[0], b[0], rng))
        res = adjust_block([[sa], [sb]], [[ta], [tb]], opts)
        models = (res[0][0].refine(a[1], a[2][0]).model, res[1][0].refine(b[1], b[2][0]).model)
        plan, dh = _checkpoints(a, b, models, args.pointing, rng)
        plans.append(plan)
        heights.append(dh)
        biases.append(float(np.mean(dh)))
        print(
            f"draw {seed}: {len(ta.id)} tie points, {len(sb.gcps.id)} shared control points; "
            f"checkpoints plan {np.sqrt(np.mean(plan**2)):.1f} m, height "
            f"{np.sqrt(np.mean(dh**2)):.1f} m (mean {np.mean(dh):+.1f} m)",
            flush=True,
        )
    p, h = np.concatenate(plans), np.concatenate(heights)
    print(
        f"over {args.draws} draws: plan {np.sqrt(np.mean(p**2)):.1f} m, height "
        f"{np.sqrt(np.mean(h**2)):.1f} m RMS (PHOTOMOD, 5 GCPs: 8.7 / 2.9 m); the height bias "
        f"per draw {np.sqrt(np.mean(np.square(biases))):.1f} m RMS"
    )


if __name__ == "__main__":
    main()
