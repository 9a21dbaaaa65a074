"""The stereo pair at full size: the figures of issue 37, measured against the emulated truth.

``scenarios/stereo/stereo_pair.toml`` at full P size (6000 detectors × 6000 lines, 10 m):
two passes three days apart, the mirror at −22.8° and +27° (B/H 1.09), five control points
each measured in both images, 400 m of fractal relief. The run (every pass, their tie
points, the block, the pair's DEM, level 3 over it) is made once by ``station run`` into
``DIR/run`` (about ten minutes) and kept; then printed:

* the disparity against the exact one; the checkpoints (PHOTOMOD's Table 1: 8.7 m plan,
  2.9 m height with 5 GCPs); the DEM against the terrain, NMAD and LE90 by slope class,
  the same NMAD by xdem (the peer: its ``nmad`` and its slope, on the DEM's GeoTIFF and the
  true terrain written beside it); the plane the error leans on (the control points'
  absolute orientation) and the error without it, beside xdem's own deramping; coverage;
  the predicted precision against the measured;
* level 3 over the pair's DEM: its ground error against what the DEM's error predicts
  (``σh · tan θ`` along each view's tilt, added to level 2's own error).

    python tools/stereo.py [DIR]          # DIR default: runs/stereo_full
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SCENARIO = ROOT / "scenarios" / "stereo" / "stereo_pair.toml"
#: The reduced scenario's sizes, and the full size's.
FULL = {
    "n_detectors = 600": "n_detectors = 6000",
    "n_lines = 600": "n_lines = 6000",
    "bit_rate_mbps = 2.0": "bit_rate_mbps = 50.0",
}


def run_full(where: Path, full: bool = True) -> Path:
    """The full-size run in ``where/run`` (made once); the shipped reduced one without
    ``full`` (the benchmarks' smoke mode)."""
    from station.cli import main

    run = where / "run"
    if (run / "report.json").is_file():
        return run
    where.mkdir(parents=True, exist_ok=True)
    text = SCENARIO.read_text()
    for a, b in FULL.items() if full else ():
        if a not in text:
            raise SystemExit(f"{SCENARIO} no longer holds {a!r}: update tools/stereo.py")
        text = text.replace(a, b)
    scenario = where / "stereo_pair.toml"
    scenario.write_text(text)
    if main(["run", str(scenario), "--out", str(run), "--no-quicklooks"]) != 0:
        raise SystemExit("the full-size run failed")
    return run


def pair_and_truth(where: Path, full: bool = True) -> tuple[Any, Any, tuple[float, float]]:
    """The full run's epipolar pair, its truth and its tie points' disparity range (the
    reduced run's without ``full``)."""
    from levels.products import read_product
    from levels.readers.gcp import read_gcps
    from levels.readers.l0 import read_l0
    from levels.stereo import StereoView, disparity_range, epipolar_pair
    from station.loader import load_block
    from station.truth.optical import truth_for
    from station.truth.stereo import StereoTruth

    run = run_full(where, full)
    scns = list(load_block(where / "stereo_pair.toml").passes)
    views = [
        StereoView.of_products(
            read_product(run / "block" / f"{s.name}_s000_2.nc"),
            read_product(run / s.name / f"{s.name}_s000_1A.h5"),
        )
        for s in scns
    ]
    pair = epipolar_pair(*views)
    truth = StereoTruth(
        *(truth_for(s, read_l0(run / s.name / f"{s.name}.l0.h5", lazy=True)) for s in scns)
    )
    ties = [read_gcps(run / "ties" / f"{s.name}.tie.csv") for s in scns]
    return pair, truth, disparity_range(pair, *ties)


def _xdem_nmad(run: Path, dem_file: str, truth: Any) -> dict[str, float] | None:
    """xdem's NMAD of the DEM minus the true terrain, by xdem's slope of the terrain."""
    try:
        import xdem
    except ImportError:
        return None
    import rasterio

    from levels.products import read_product
    from station.truth.stereo import SLOPE_CLASSES_DEG, true_heights

    product = read_product(run / dem_file)

    class _Dem:  # what true_heights reads of a StereoDem
        grid = product.map_grid

    h_true, _ = true_heights(_Dem, truth.a.acq.world)  # type: ignore[arg-type]
    true_tif = run / "stereo" / "true_terrain.tif"
    with rasterio.open(run / "stereo" / Path(dem_file).name.replace(".nc", ".tif")) as ds:
        profile = ds.profile
    with rasterio.open(true_tif, "w", **profile) as ds:
        ds.write(h_true.astype(np.float32), 1)
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # xdem's numpy on masked and NaN cells
        dem = xdem.DEM(str(run / "stereo" / Path(dem_file).name.replace(".nc", ".tif")))
        ref = xdem.DEM(str(true_tif))
        diff = (dem - ref).data.filled(np.nan)
        slope = np.asarray(xdem.terrain.slope(ref).data.filled(np.nan))
        out = {"all": float(xdem.spatialstats.nmad(diff[np.isfinite(diff)]))}
        for lo, hi in SLOPE_CLASSES_DEG:
            k = np.isfinite(diff) & (slope >= lo) & (slope < hi)
            if k.sum() > 100:
                out[f"{lo:g}-{hi:g}deg"] = float(xdem.spatialstats.nmad(diff[k]))
        # xdem's own coregistration of the DEM onto the terrain, bias and tilt (Deramp of
        # order 1): what is left against ours without the plane
        deramp = xdem.coreg.Deramp(poly_order=1)
        deramp.fit(ref, dem)
        left = (deramp.apply(dem) - ref).data.filled(np.nan)
        out["deramped_rmse"] = float(np.sqrt(np.nanmean(left**2)))
    return out


def main(argv: list[str]) -> int:
    where = Path(argv[0]) if argv else ROOT / "runs" / "stereo_full"
    run = run_full(where)
    report = json.loads((run / "report.json").read_text())
    (entry,) = report["stereo"]["dems"]
    q = entry["quality"]
    d, h, c = q["disparity"], q["heights"], q["checkpoints"]
    print(f"full P pair, {run}:")
    print(
        f"  disparity against the exact: RMS {d['rms_px']:.3f} px, NMAD {d['nmad_px']:.3f} px,"
        f" beyond 1 px {d['beyond_1px_fraction']:.2%}, kept {d['valid_fraction']:.1%}"
        f" (target RMS ≤ 0.2 px); v-parallax RMS {d['v_parallax_rms_px']:.3f} px"
    )
    print(
        f"  checkpoints ({c['points']}, {c['pointing_px']} px pointing): plan "
        f"{c['plan_rms_m']:.1f} m, height {c['height_rms_m']:.1f} m (mean "
        f"{c['height_mean_m']:+.1f}) (PHOTOMOD: 8.7 / 2.9 m)"
    )
    print(
        f"  DEM − terrain: RMSE {h['rmse']:.2f} m (mean {h['mean']:+.2f}), NMAD {h['nmad']:.2f}"
        f" m, LE90 {h['le90']:.2f} m (target RMSE ≤ 3 m); coverage of the cells both images "
        f"see {h['coverage_of_seen']:.1%} (≥ 95 %)"
    )
    for k, s in h["by_slope"].items():
        print(
            f"    slope {k:9s} {s['count']:9d} cells: NMAD {s['nmad']:.2f} m, LE90 "
            f"{s['le90']:.2f} m, mean {s['mean']:+.2f} m"
        )
    datum, rest = h["datum"], h["datum_removed"]
    print(
        f"  the plane it leans on (the control points' absolute orientation): bias "
        f"{datum['bias_m']:+.2f} m, tilt {datum['tilt_east_m_per_km']:+.3f} m/km east, "
        f"{datum['tilt_north_m_per_km']:+.3f} m/km north; without it: RMSE {rest['rmse']:.2f}"
        f" m, NMAD {rest['nmad']:.2f} m, LE90 {rest['le90']:.2f} m (target RMSE ≤ 3 m)"
    )
    print(
        f"  predicted σ (median) {h['predicted_median_m']:.2f} m, measured NMAD "
        f"{h['nmad']:.2f} m: measured / predicted {h['measured_over_predicted']:.2f}, the "
        f"plane taken out {rest['measured_over_predicted']:.2f} (target [0.7, 1.5])"
    )
    _, truth, _ = pair_and_truth(where)
    peer = _xdem_nmad(run, entry["file"], truth)
    if peer is None:
        print("  xdem not installed (pip install xdem): no peer figures")
    else:
        ours = {
            "all": h["nmad"],
            **{k: s["nmad"] for k, s in h["by_slope"].items()},
            "deramped_rmse": rest["rmse"],
        }
        for k, v in peer.items():
            print(f"    xdem {k:13s} {v:.3f} m, ours {ours.get(k, float('nan')):.3f} m")
    _level3(report, run / entry["file"], h)
    return 0


def _level3(report: dict, dem_file: Path, h: dict) -> None:
    """Level 3 of each view over the pair's DEM against what the DEM's error predicts: the
    view's level 2 error plus the DEM's height error carried along its tilt, the systematic
    parts as vectors (the DEM's bias moves every pixel of a view the same way, −Δh·a, the
    tilt ``a`` pointing away from the satellite: ``−tanθ_a·e`` and ``+tanθ_b·e``, ``e`` the
    epipolar direction) and the random parts in quadrature."""
    from levels.products import read_product

    stereo = read_product(dem_file, images=False).geometry["stereo"]
    tan, ex = stereo["tan_incidence"], np.asarray(stereo["epipolar_direction"], dtype=float)
    level2 = {p["pass"]: p["quality"] for p in report["block"]["products"] if p["level"] == "2"}
    for p in report["block"]["products"]:
        if p["level"] != "3":
            continue
        q, l2 = p["quality"], level2[p["pass"]]
        k = list(level2).index(p["pass"])
        los_mean = np.array([l2[f"checkpoints/P/line_of_sight/mean_{i}_m"] for i in (1, 2)])
        los_rms = l2["checkpoints/P/line_of_sight/rms_m"]
        dh_mean, dh_rms = h["mean"], q["checkpoints/P/dem_error/rms_m"]
        mean = los_mean + (1.0 if k == 0 else -1.0) * dh_mean * tan[k] * ex
        random2 = max(los_rms**2 - los_mean @ los_mean, 0.0)
        random2 += max(dh_rms**2 - dh_mean**2, 0.0) * tan[k] ** 2
        predicted = float(np.sqrt(mean @ mean + random2))
        ground = q["checkpoints/P/ground/rms_m"]
        got = np.array([q[f"checkpoints/P/ground/mean_{i}_m"] for i in (1, 2)])
        print(
            f"  level 3 {p['pass']} over the pair's DEM: on the terrain {ground:.1f} m RMS, "
            f"mean ({got[0]:+.1f}, {got[1]:+.1f}) m; predicted {predicted:.1f} m, mean "
            f"({mean[0]:+.1f}, {mean[1]:+.1f}) m (level 2's ({los_mean[0]:+.1f}, "
            f"{los_mean[1]:+.1f}) m, {los_rms:.1f} m RMS, and Δh {dh_mean:+.1f} m × tanθ "
            f"{tan[k]:.3f} along its tilt): ratio {ground / predicted:.2f} (target within 20 %)"
        )


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
