"""Level 2 at full size: the figures of issue 18, measured against the emulated truth.

Geometry only (no image is rendered): full P scenes (6000 detectors, 6000 lines), the
emulator's default errors (ephemeris bias and drift, attitude offsets, Westin's drift,
jitter, gyro noise; control points with 8 m map, 5 m height and 0.3 px pointing errors),
GEO as the station runs it, :func:`levels.adjust.adjust`, and each refined scene's model
against the truth's line of sight at an 11 × 11 lattice on the reference surface. A lost
stretch of the pass (an outage) removes its scenes and its attitude records.

    python tools/level2.py            # every figure, 20 passes each (about 4 min)
    python tools/level2.py --passes 5 # quicker, rougher
    python tools/level2.py --plot docs/figures/level2_gap.png

Printed: RMS per axis (east, north) and horizontal, in m and P pixels (10 m), beside the
adjustment's predicted σ.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np

from levels.adjust import Strip, adjust, adjust_strips
from levels.geometry.attitude import westin_variogram_rad2
from levels.options import ProcessingOptions
from levels.spot import MODES, ORBIT_ALTITUDE_M
from station.chain.gcps import control_points
from station.fixtures import emulated_pass
from station.scenario import scenario_from_dict
from station.spacecraft.emulator import emulate, emulate_pass
from station.truth.optical import Truth

SCENE = 6000  # lines and detectors of a full P scene
LINE_S = MODES["P"].line_period_s
PIXEL_M = 10.0


def run_case(
    seed: int,
    n_scenes: int,
    gcps: dict[str, Any],
    *,
    lost: tuple[int, ...] = (),
    mirror_step: int = 48,
    options: ProcessingOptions | None = None,
) -> dict[str, Any]:
    """One emulated pass of ``n_scenes`` full P scenes, the scenes ``lost`` taken away with
    their attitude records; returns per-scene errors, predictions and the adjustment."""
    scn = scenario_from_dict(
        {
            "name": "level2",
            "seed": seed,
            "instrument": {"n_lines": SCENE * n_scenes, "mirror_step": mirror_step},
            "gcps": gcps,
        }
    )
    acq = emulate(scn, render=False)
    pg, scenes = emulated_pass(acq, SCENE, lost=lost)
    opts = options or ProcessingOptions()
    adj = adjust(pg, scenes, control_points(acq), opts)
    truth = Truth(acq, 0)
    errors = [truth.model_error_en(adj.refine(pg, s)) for s in scenes]
    return {
        "scenes": [s.cut.index for s in scenes],
        "error_en": errors,
        "predicted": adj.predicted_sigma_m,
        "adjustment": adj,
        "blunder": acq.gcps.blunder,
    }


def rms(values: list[np.ndarray]) -> float:
    v = np.concatenate([np.ravel(x) for x in values])
    return float(np.sqrt(np.mean(v**2)))


def figure(label: str, east: list, north: list, predicted: list[float]) -> None:
    e, n = rms(east), rms(north)
    h = float(np.hypot(e, n))
    p = float(np.sqrt(np.mean(np.square(predicted))))
    print(
        f"  {label:<44} east {e:5.1f} m  north {n:5.1f} m  horizontal {h:5.1f} m "
        f"({h / PIXEL_M:4.2f} px)  predicted {p:5.1f} m  measured/predicted {h / p:4.2f}"
    )


def single_scene(passes: int) -> None:
    print("one full P scene, default errors:")
    for mirror, angle in ((48, "nadir"), (75, "27°")):
        for count in (12, 1):
            e, n, p = [], [], []
            for seed in range(passes):
                r = run_case(seed, 1, {"count": count}, mirror_step=mirror)
                e.append(r["error_en"][0][0])
                n.append(r["error_en"][0][1])
                p.append(r["predicted"][0, 2])
            figure(f"{count} control point(s), {angle}, {passes} passes", e, n, p)


def westin(passes: int) -> None:
    print("Westin's Table I: 2 points in scene 0, scenes 1-4 lost, scene 5 without points:")
    gcps = {"count": 2, "line_ranges": [0.01, 0.16]}
    for lost, label in (((1, 2, 3, 4), "with the outage"), ((), "attitude records throughout")):
        e, n, p = [], [], []
        for seed in range(passes):
            r = run_case(seed, 6, gcps, lost=lost)
            k = r["scenes"].index(5)
            e.append(r["error_en"][k][0].mean())  # the scene's bias, as Westin's Table I
            n.append(r["error_en"][k][1].mean())
            p.append(r["predicted"][k, 2])
        figure(f"scene 5 bias, {label}", e, n, p)
    gap_s = 4 * SCENE * LINE_S
    for axis, name, direction in ((0, "roll", "across"), (1, "pitch", "along")):
        sig = float(np.sqrt(westin_variogram_rad2(axis, gap_s)))
        print(
            f"  variogram 1σ of the {name} drift over the {gap_s:.0f} s gap: "
            f"{np.degrees(sig) * 1e3:.2f} mdeg, {sig * ORBIT_ALTITUDE_M:.1f} m {direction} track"
        )
    print("  Westin's Table I, scene 61-229: x 8.9 m, y 6.6 m RMS (bias -8.2, 5.6 m)")


def gap_sweep(passes: int, plot: str | None) -> None:
    print("error of the scene beyond a gap, against the gap's length (2 points before it):")
    lengths, measured, predicted = [], [], []
    for k in range(0, 7):
        n_scenes = k + 2
        gcps = {"count": 2, "line_ranges": [0.06 / n_scenes, 0.9 / n_scenes]}  # first scene
        e, n, p = [], [], []
        for seed in range(passes):
            r = run_case(seed, n_scenes, gcps, lost=tuple(range(1, k + 1)))
            e.append(r["error_en"][-1][0])
            n.append(r["error_en"][-1][1])
            p.append(r["predicted"][-1, 2])
        gap = k * SCENE * LINE_S
        lengths.append(gap)
        measured.append(float(np.hypot(rms(e), rms(n))))
        predicted.append(float(np.sqrt(np.mean(np.square(p)))))
        print(
            f"  gap {gap:5.1f} s: measured {measured[-1]:5.1f} m, predicted {predicted[-1]:5.1f} m"
        )
    if plot:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(6, 3.6))
        ax.plot(lengths, measured, "o-", label=f"measured RMS ({passes} passes)")
        ax.plot(lengths, predicted, "s--", label="predicted σ (adjustment)")
        ax.set_xlabel("attitude records lost before the scene (s)")
        ax.set_ylabel("horizontal error (m)")
        ax.set_title("Level 2 beyond a gap: 2 control points before it (full P)")
        ax.grid(alpha=0.3)
        ax.legend()
        fig.tight_layout()
        Path(plot).parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(plot, dpi=110)
        print(f"  plot: {plot}")


def ends(passes: int) -> None:
    print("points at both ends of a 10-scene pass (12 + 12), none between:")
    per_scene = [[] for _ in range(10)]
    pred = [[] for _ in range(10)]
    for seed in range(passes):
        r = run_case(seed, 10, {"count": 24, "line_ranges": [0.0, 0.1, 0.9, 1.0]})
        for k in range(10):
            per_scene[k].append(np.hypot(*r["error_en"][k]))
            pred[k].append(r["predicted"][k, 2])
    worst = max(range(10), key=lambda k: rms(per_scene[k]))
    print(
        f"  worst scene {worst}: {rms(per_scene[worst]):.1f} m "
        f"({rms(per_scene[worst]) / PIXEL_M:.2f} px), predicted "
        f"{np.sqrt(np.mean(np.square(pred[worst]))):.1f} m; middle scenes "
        + ", ".join(f"{rms(per_scene[k]):.1f}" for k in range(1, 9))
        + " m"
    )


def twin(passes: int, n_scenes: int = 3) -> None:
    print(f"twin pass, both HRVs in P ({n_scenes} scenes each), 12 points per scene in HRV1 only:")
    per_hrv: dict[int, list] = {1: [], 2: []}
    pred: dict[int, list] = {1: [], 2: []}
    alone = []
    for seed in range(passes):
        scn = scenario_from_dict(
            {
                "name": "level2_twin",
                "seed": seed,
                "instrument": [
                    {"hrv": h, "twin": True, "n_lines": SCENE * n_scenes} for h in (1, 2)
                ],
                "gcps": {"count": 12 * n_scenes, "hrvs": [1]},
            }
        )
        acqs = emulate_pass(scn, render=False)
        geo = [emulated_pass(a, SCENE) for a in acqs]
        strips = [
            Strip(pg, scenes, control_points(a)) for a, (pg, scenes) in zip(acqs, geo, strict=True)
        ]
        opts = ProcessingOptions()
        for a, (pg, scenes), adj in zip(acqs, geo, adjust_strips(strips, opts), strict=True):
            truth = Truth(a, 0)
            h = a.hrv.number
            per_hrv[h] += [np.hypot(*truth.model_error_en(adj.refine(pg, s))) for s in scenes]
            pred[h] += list(adj.predicted_sigma_m[:, 2])
        pg2, scenes2 = geo[1]
        solo = adjust(pg2, scenes2, control_points(acqs[1]), opts)
        alone += [np.hypot(*Truth(acqs[1], 0).model_error_en(solo.refine(pg2, s))) for s in scenes2]
    for h in (1, 2):
        m = rms(per_hrv[h])
        p = float(np.sqrt(np.mean(np.square(pred[h]))))
        print(
            f"  HRV{h}, adjusted together: {m:5.1f} m ({m / PIXEL_M:4.2f} px), "
            f"predicted {p:5.1f} m, measured/predicted {m / p:4.2f}"
        )
    print(f"  HRV2 alone (no point of its own: the a priori budget): {rms(alone):6.1f} m")


def blunders(passes: int) -> None:
    print("10 % of 20 points with 100 m blunders, one scene:")
    clean, dirty, planted, caught, false = [], [], 0, 0, 0
    for seed in range(passes):
        c = run_case(seed, 1, {"count": 20})
        d = run_case(seed, 1, {"count": 20, "blunder_fraction": 0.1, "blunder_m": 100.0})
        clean.append(np.hypot(*c["error_en"][0]))
        dirty.append(np.hypot(*d["error_en"][0]))
        rejected = np.array(d["adjustment"].point_status) == "rejected"
        planted += int(d["blunder"].sum())
        caught += int(np.sum(d["blunder"] & rejected))
        false += int(np.sum(~d["blunder"] & rejected))
    print(
        f"  blunders rejected {caught}/{planted}, good points rejected {false}; RMS "
        f"{rms(dirty):.1f} m with blunders, {rms(clean):.1f} m without "
        f"(ratio {rms(dirty) / rms(clean):.3f})"
    )


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--passes", type=int, default=20, help="emulated passes per figure")
    ap.add_argument("--plot", help="write the gap-length plot here (PNG)")
    ap.add_argument(
        "--only", choices=("scene", "westin", "gap", "ends", "blunders", "twin"), help="one figure"
    )
    args = ap.parse_args(argv)
    commit = subprocess.run(
        ["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True, check=False
    ).stdout.strip()
    print(f"level 2 figures, commit {commit or '?'}, {args.passes} passes each")
    todo = {
        "scene": lambda: single_scene(args.passes),
        "westin": lambda: westin(args.passes),
        "gap": lambda: gap_sweep(max(args.passes // 2, 3), args.plot),
        "ends": lambda: ends(max(args.passes // 2, 3)),
        "blunders": lambda: blunders(args.passes),
        "twin": lambda: twin(max(args.passes // 2, 3)),
    }
    for name, fn in todo.items():
        if args.only in (None, name):
            fn()
    sys.stdout.flush()


if __name__ == "__main__":
    main()
