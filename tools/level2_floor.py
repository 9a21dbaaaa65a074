"""What level 2 can reach with perfect control points: the error no point can take off.

A full P scene over the SRTM tile (``tools/reference_draws.py --full``'s pass) refined on
``--points`` exact control points (their map and image errors 1 mm and 0.001 px, as if
measured perfectly): level 2's checkpoints against the truth, along and across the track,
beside what its adjustment predicts. What is left is the attitude between the gyro
records, which Westin's drift moves (pitch: 0.83 µrad RMS between records 0.125 s apart,
:func:`levels.geometry.attitude.interpolation_sigma_rad`) and the jitter, which no model of
the records and no number of points can follow; it bounds level 2, and the co-registration
of two passes (``tools/coregistration.py``), from below.

    python tools/level2_floor.py [--mirror-step 48] [--points 400] [--set SECTION.KEY=VALUE]

``--set attitude.drift_scale=0 --set attitude.jitter_amplitude_urad=[0,0,0]`` takes the
drift and the jitter out of the truth: what is left is the rest of the chain.
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

from overrides import scenario_changes  # tools/overrides.py
from reference_draws import FULL  # tools/reference_draws.py

from levels.choices import Level
from levels.geometry.attitude import interpolation_sigma_rad
from station.run import run_scenario
from station.scenario import scenario_from_dict


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--mirror-step", type=int, default=48)
    ap.add_argument("--points", type=int, default=400)
    ap.add_argument("--seed", type=int, default=100)
    ap.add_argument("--set", action="append", default=[], metavar="SECTION.KEY=VALUE")
    args = ap.parse_args()
    data = json.loads(json.dumps(FULL))
    data.pop("reference")
    data["gcps"] = {
        "count": args.points,
        "horizontal_error_m": 0.001,
        "vertical_error_m": 0.001,
        "pointing_error_px": 0.001,
    }
    data["instrument"] = {"mirror_step": args.mirror_step}
    data["processing"]["levels"] = ["2"]
    for section, values in scenario_changes(args.set).items():
        data.setdefault(section, {}).update(values)
    scn = scenario_from_dict({"name": "floor", "seed": args.seed, **data})
    with tempfile.TemporaryDirectory() as tmp:
        report = run_scenario(scn, Path(tmp) / "run", quicklooks=False)
    adj = report["hrvs"][0]["adjustment"]
    floor = interpolation_sigma_rad(0.125) * 1e6
    print(
        f"{args.points} exact control points, mirror step {args.mirror_step}: "
        f"{adj['points_used']} used, residual {adj['residual_rms_px']:.3f} px RMS, "
        f"σ0 {adj['sigma0']:.2f}; the attitude between gyro records "
        f"(roll, pitch, yaw) {floor[0]:.2f}, {floor[1]:.2f}, {floor[2]:.2f} µrad"
    )
    for row in (r for r in report["products"] if r["level"] == Level.L2):
        q = row["quality"]
        key = "checkpoints/P/line_of_sight"
        print(
            f"scene {row['scene']}: level 2 against the truth {q[f'{key}/rms_m']:.2f} m "
            f"({q[f'{key}/rms_px']:.3f} px RMS), predicted "
            f"{q['predicted_sigma_m/horizontal']:.2f} m"
        )


if __name__ == "__main__":
    main()
