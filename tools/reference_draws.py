"""Level 2 on control points found on a reference ortho-image, over draws (issue 51): is
the accuracy its adjustment predicts the accuracy it has?

Each draw is a run of a reduced pass (600 × 600 detectors and lines at 27°, 100 m pixels,
300 m of relief; ``[reference]`` exact at 100 m unless ``--set`` says otherwise; ``[gcps]
source = "reference"``) with its own seed: the pass, its errors, the world and the
reference change. ``--full``: the full P scene (6000 × 6000, 10 m) over the SRTM tile
N00E010 (``../shared/refdata``, as ``scenarios/tilt27_rugged.toml``) with an exact 10 m
reference, at the mirror step given (48 nadir, 93 the +27° of the issue). Printed per
draw: the points, level 2's checkpoint RMS against the truth (m, px), the adjustment's
predicted horizontal σ, their ratio; then the ratio's mean and range (the issue asks
[0.7, 1.5]); and each draw's reference bias (its truth) and how far level 2 is from
carrying exactly it: the issue's "within the reference's own error plus 0.1 px".

    python tools/reference_draws.py [--draws 10] [--set reference.error_ce95_m=8]
    python tools/reference_draws.py --full --mirror-step 93 --draws 10
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
import time
from pathlib import Path

import numpy as np
from overrides import scenario_changes  # tools/overrides.py

from levels.choices import Level
from station.run import run_scenario
from station.scenario import scenario_from_dict

BASE = {
    "instrument": {"mirror_step": 70, "n_detectors": 600, "n_lines": 600},
    "world": {"base_height_m": 500.0, "relief_m": 300.0},
    "dem": {"spacing_arcsec": 3.0},
    "reference": {"pixel_size_m": 100.0},
    "gcps": {"source": "reference"},
    "downlink": {"bit_rate_mbps": 0.6, "preamble_s": 0.1, "postamble_s": 0.1},
    "processing": {"reference_height_m": 500.0, "levels": ["2A", "2"]},
}


ROOT = Path(__file__).resolve().parents[1]
REFDATA = Path(os.environ.get("SPOT_REFDATA", ROOT.parent / "shared" / "refdata"))
SRTM = REFDATA / "dem" / "N00E010.hgt"
#: The full P scene over the SRTM tile (Gabon; the station in Libreville, as tilt27_rugged).
FULL = {
    "pass": {"target_lat_deg": 0.5, "target_lon_deg": 10.5, "ground_pass_days": 0.0},
    "ground_station": {"name": "Libreville", "lat_deg": 0.39, "lon_deg": 9.45, "height_m": 10.0},
    "world": {"kind": "dem", "dem_path": str(SRTM)},
    "dem": {"spacing_arcsec": 3.0},
    "reference": {"pixel_size_m": 10.0},
    "gcps": {"source": "reference"},
    "downlink": {"preamble_s": 0.1, "postamble_s": 0.1},
    "processing": {"reference_height_m": 400.0, "levels": ["2A", "2"]},
}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--draws", type=int, default=10)
    ap.add_argument("--set", action="append", default=[], metavar="SECTION.KEY=VALUE")
    ap.add_argument("--full", action="store_true", help="the full P scene over the SRTM tile")
    ap.add_argument("--mirror-step", type=int, default=None, help="48 nadir, 93 +27°")
    ap.add_argument("--first-seed", type=int, default=0)
    args = ap.parse_args()
    ratios, budget, within = [], [], []
    for seed in range(args.first_seed, args.first_seed + args.draws):
        data = json.loads(json.dumps(FULL if args.full else BASE))
        if args.mirror_step is not None:
            data.setdefault("instrument", {})["mirror_step"] = args.mirror_step
        for section, values in scenario_changes(args.set).items():
            data.setdefault(section, {}).update(values)
        scn = scenario_from_dict({"name": f"draw{seed}", "seed": 100 + seed, **data})
        t = time.perf_counter()
        with tempfile.TemporaryDirectory() as tmp:
            report = run_scenario(scn, Path(tmp) / "run", quicklooks=False)
            points = sum(1 for _ in open(Path(tmp) / "run" / f"draw{seed}.gcp.csv")) - 2
            truth = json.loads((Path(tmp) / "run" / f"draw{seed}.reference.json").read_text())
        bias = np.array([truth["bias_east_m"], truth["bias_north_m"]])
        for row in (r for r in report["products"] if r["level"] == Level.L2):
            q = row["quality"]
            key = "checkpoints/P/line_of_sight"
            rms_m = q[f"{key}/rms_m"]
            px_m = rms_m / q[f"{key}/rms_px"]
            predicted = q["predicted_sigma_m/horizontal"]
            ratios.append(rms_m / predicted)
            # level 2 puts a pixel at its true ground less the reference's bias (the bias
            # carried, as it must be): what is left beside it is the registration's own error
            mean = np.array([q[f"{key}/mean_1_m"], q[f"{key}/mean_2_m"]])
            scatter2 = max(rms_m**2 - float(mean @ mean), 0.0)
            off_px = float(np.sqrt(scatter2 + np.sum((mean + bias) ** 2))) / px_m
            budget.append(off_px)
            rss = rms_m / float(np.hypot(np.hypot(*bias), 0.1 * px_m))
            within.append(rss)
            print(
                f"draw {seed}: {points} points; level 2 {rms_m:.2f} m "
                f"({q[f'{key}/rms_px']:.3f} px) against {predicted:.2f} m "
                f"predicted: {ratios[-1]:.2f}; the reference's own bias "
                f"{float(np.hypot(*bias)):.2f} m, level 2 {off_px:.3f} px from it, "
                f"{rss:.2f} of (bias ⊕ 0.1 px)  [{time.perf_counter() - t:.0f} s]",
                flush=True,
            )
    r, b = np.array(ratios), np.array(budget)
    print(
        f"over {r.size} scenes: measured / predicted {r.mean():.2f} on average, "
        f"{r.min():.2f}–{r.max():.2f} (the issue asks [0.7, 1.5]); level 2 from the "
        f"reference's own bias {b.mean():.3f} px on average, at most {b.max():.3f} px "
        f"(within 0.1 px in {int(np.sum(b <= 0.1))} of {b.size}); level 2 within the "
        f"reference's bias ⊕ 0.1 px (RSS) in {int(np.sum(np.array(within) <= 1.0))} of "
        f"{b.size}"
    )


if __name__ == "__main__":
    main()
