"""The ``station`` command line. Thin: it parses, calls one function, prints.

Bad input gives one line on stderr and exit code 2, never a traceback.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from pathlib import Path

from levels.errors import LevelsError
from station.errors import StationError

__all__ = ["main"]


def _cmd_locate(args: argparse.Namespace) -> int:
    from station.locate import check_frame

    check = check_frame(args.metadata, attitude=args.attitude)
    if args.json:
        print(json.dumps(check.as_dict(), indent=2))
        return 0
    print(f"{check.scene}  (attitude: {check.attitude})")
    print(
        f"{'point':>12} {'lat °':>12} {'lon °':>12} {'pred lat °':>12} {'pred lon °':>12} "
        f"{'error m':>8} {'closure px':>10}"
    )
    labels = ["corner 1", "corner 2", "corner 3", "corner 4", "centre"]
    for i, label in enumerate(labels):
        print(
            f"{label:>12} {check.lat_deg[i]:12.7f} {check.lon_deg[i]:12.7f} "
            f"{check.predicted_lat_deg[i]:12.7f} {check.predicted_lon_deg[i]:12.7f} "
            f"{check.error_m[i]:8.3f} {check.roundtrip_px[i]:10.2e}"
        )
    print(f"max error {check.error_m.max():.3f} m")
    return 0


def _cmd_emulate(args: argparse.Namespace) -> int:
    import time

    from station.scenario import load_scenario
    from station.spacecraft.emulator import emulate
    from station.spacecraft.summary import summarize

    start = time.perf_counter()
    acq = emulate(load_scenario(args.scenario), render=not args.no_render)
    summary = summarize(acq)
    summary["elapsed_s"] = round(time.perf_counter() - start, 3)
    if args.json:
        print(json.dumps(summary, indent=2))
        return 0
    s, f = summary["strip"], summary["footprint"]
    print(f"{summary['scenario']}: HRV{s['hrv']} {s['mode']}, mirror step {s['mirror_step']}"
          f"{' (twin)' if s['twin'] else ''}, {s['lines']} lines x {s['detectors']} detectors")
    print(f"strip centre {s['centre_utc']} UTC at {f['centre_lat_lon_deg'][0]:.5f}°, "
          f"{f['centre_lat_lon_deg'][1]:.5f}° ({f['centre_height_m']:.0f} m); "
          f"satellite at {s['satellite_altitude_km']:.1f} km")
    print(f"footprint {f['width_first_line_km']:.2f} km across x "
          f"{f['length_first_column_km']:.2f} km along")
    for b in summary["bands"]:
        print(f"band {b['name']}: mean {b['mean_counts']:.1f} counts, {b['saturated']} "
              f"saturated, {b['failed_rays']} rays lost, Newton <= {b['newton_iterations_max']}")
    ps = summary["passes"]
    if ps:
        print(f"{len(ps)} passes over {acq.scenario.ground_station.name} "
              f"(median {sorted(p['duration_min'] for p in ps)[len(ps) // 2]:.1f} min):")
        for p in ps:
            print(f"  AOS {p['aos_utc']}  {p['duration_min']:6.2f} min  max el "
                  f"{p['max_elevation_deg']:5.1f}°  {'day' if p['daylight'] else 'night'}")
    h = summary["handover"]
    print(f"handed to the station: {h['gyro_samples']} gyro samples, {h['bulletin_points']} "
          f"bulletin points, {h['control_points']} control points")
    print(f"elapsed {summary['elapsed_s']:.1f} s")
    return 0


def _cmd_downlink(args: argparse.Namespace) -> int:
    import time
    from pathlib import Path

    from station.scenario import load_scenario
    from station.spacecraft.emulator import emulate
    from station.srrs.report import downlink_report
    from station.srrs.session import downlink, record

    start = time.perf_counter()
    scn = load_scenario(args.scenario)
    acq = emulate(scn)
    t_emulate = time.perf_counter() - start
    result = downlink(acq)
    out = Path(args.out) if args.out else Path(f"{scn.name}.l0.h5")
    t0 = time.perf_counter()
    record(acq, result, out)
    result.timings_s.update(emulate=t_emulate, record=time.perf_counter() - t0)
    rep = downlink_report(acq, result)
    rep["l0"] = {"path": str(out), "size_mb": round(out.stat().st_size / 1e6, 2)}
    if args.json:
        print(json.dumps(rep, indent=2))
        return 0
    link = rep["link"]
    print(f"{rep['scenario']}: HRV{rep['hrv']} {rep['mode']}, {rep['lines']} lines x "
          f"{rep['detectors']} detectors")
    print(f"link: {link['cadus_sent']} CADUs in {link['duration_s']:.2f} s at "
          f"{link['bit_rate_mbps']:g} Mbit/s; {link['bit_errors']} bit errors, "
          f"{link['bursts']} bursts, {link['fades']} fades")
    print("CADUs: " + ", ".join(f"{k} {v}" for k, v in rep["cadus"].items()))
    print(f"{'channel':>8} {'sent':>7} {'deliv.':>7} {'lost':>6} {'gaps':>5} {'dupl.':>6} "
          f"{'o-o-o':>6} {'corr.':>6} {'symbols':>8}  ends known")
    for name, c in rep["channels"].items():
        print(f"{name:>8} {c['sent']:7d} {c['delivered']:7d} {c['lost']:6d} {c['gaps']:5d} "
              f"{c['duplicates']:6d} {c['out_of_order']:6d} {c['corrected']:6d} "
              f"{c['symbols_corrected']:8d}  {'yes' if c['head_known'] else 'no'}/"
              f"{'yes' if c['tail_known'] else 'no'}")
    for b in rep["bands"]:
        print(f"band {b['name']}: {b['lines_complete']} lines complete, {b['lines_partial']} "
              f"partial, {b['lines_missing']} missing; valid pixels "
              f"{'as sent' if b['valid_pixels_as_sent'] else 'DIFFER FROM WHAT WAS SENT'}, "
              f"error vs raw counts max {b['max_error_vs_raw_counts']} rms "
              f"{b['rms_error_vs_raw_counts']:.2f}")
    tc = rep["truth_check"]
    print(f"against the truth: {tc['data_frames_lost']} data frames lost; masks "
          f"{'match' if tc['masks_match_lost_frames'] else 'DO NOT MATCH'} the segments they "
          f"touched; accounts {'balance' if tc['accounts_balance'] else 'DO NOT BALANCE'}, "
          f"frames sent {'as counted' if tc['sent_as_counted'] else 'MISCOUNTED'}")
    lc = rep["line_clock"]
    print(f"line clock: period {lc['period_s'] * 1e3:.6f} ms, time of the middle line "
          f"±{lc['uncertainty_us']:.1f} µs; max error vs truth {lc['max_error_vs_truth_us']:.1f} "
          "µs")
    t = rep["timings_s"]
    print(f"L0: {rep['l0']['path']} ({rep['l0']['size_mb']:.1f} MB); emulate {t['emulate']:.1f} "
          f"s, send {t['transmit']:.2f} s, channel {t['channel']:.2f} s, receive "
          f"{t['receive']:.2f} s ({rep['receive_speed_x_real_time']:.1f}x real time at 50 "
          f"Mbit/s), record {t['record']:.2f} s")
    return 0


def _cmd_process(args: argparse.Namespace) -> int:
    from pathlib import Path

    from station.run import approximation_max_px
    from station.scenario import load_scenario
    from station.sipc.process import process_scenario

    scn = load_scenario(args.scenario)
    out = Path(args.out) if args.out else Path(f"{scn.name}_products")
    products, l0 = process_scenario(scn, out)
    rows = [{"scene": s.index, "level": lv, "path": str(s.paths[lv]), **s.quality[lv],
             "timings_s": s.timings_s} for s in products.scenes for lv in s.paths]
    if args.json:
        print(json.dumps({"l0": str(l0), "tail_lines": products.tail_lines,
                          "timings_s": products.timings_s, "products": rows}, indent=2,
                         default=float))
        return 0
    print(f"{scn.name}: {len(products.scenes)} scene(s) from {l0}; GEO "
          f"{products.timings_s['geo']:.3f} s, all {products.timings_s['total']:.1f} s")
    print(f"{'scene':>5} {'level':>5} {'LOS rms m':>10} {'max px':>7} {'ground rms m':>13} "
          f"{'approx max px':>14}  stripes raw → 1A")
    for r in rows:
        band = next(b for b in ("P", "XS1") if f"stripe_level/{b}/raw_counts" in r
                    or f"checkpoints/{b}/line_of_sight/rms_m" in r)
        los = r.get(f"checkpoints/{band}/line_of_sight/rms_m", float("nan"))
        los_px = r.get(f"checkpoints/{band}/line_of_sight/max_px", float("nan"))
        ground = r.get(f"checkpoints/{band}/ground/rms_m", float("nan"))
        approx = approximation_max_px(r)
        approx = float("nan") if approx is None else approx
        stripes = (f"{r[f'stripe_level/{band}/raw_counts']:.2f} → "
                   f"{r[f'stripe_level/{band}/level_1a_counts']:.2f}"
                   if r["level"] == "1A" else "")
        print(f"{r['scene']:5d} {r['level']:>5} {los:10.1f} {los_px:7.2f} {ground:13.1f} "
              f"{approx:14.4f}  {stripes}")
        print(f"{'':11}{r['path']}")
    return 0


#: The scenario ``station`` and ``station run`` run when given none.
DEFAULT_SCENARIO = Path(__file__).resolve().parents[1] / "scenarios" / "quickstart.toml"


def _cmd_run(args: argparse.Namespace) -> int:
    from station.run import run_scenario, summary_table
    from station.scenario import load_scenario

    path = Path(args.scenario) if args.scenario else DEFAULT_SCENARIO
    if not args.scenario and not path.is_file():
        raise StationError(f"the default scenario {path} is not there (an install without "
                           "the repository's scenarios/); give a scenario file")
    scn = load_scenario(path)
    out = Path(args.out) if args.out else Path("runs") / scn.name
    if not args.json:
        print(f"running {path} into {out}/ ...", file=sys.stderr)
    report = run_scenario(scn, out, quicklooks=not args.no_quicklooks,
                          progress=not args.quiet and sys.stderr.isatty())
    if args.json:
        print(json.dumps(report, indent=2))
    else:
        print(summary_table(report, out))
    return 0


def _cmd_compare(args: argparse.Namespace) -> int:
    from levels.compare import compare_paths, load_tolerances

    result = compare_paths(args.a, args.b, load_tolerances(args.tolerances))
    print(json.dumps(result.as_dict(), indent=2) if args.json else result.text())
    return 0 if result.ok else 1


def _cmd_inspect(args: argparse.Namespace) -> int:
    from levels.inspect import product_summary, summary_text
    from levels.products import read_product

    summary = product_summary(read_product(args.product), args.product)
    print(json.dumps(summary, indent=2, default=str) if args.json else summary_text(summary))
    return 0


def _cmd_export(args: argparse.Namespace) -> int:
    from levels.export import write_geotiff
    from levels.products import read_product

    src = Path(args.product)
    out = Path(args.out) if args.out else src.with_suffix(".tif")
    path = write_geotiff(read_product(src), out)
    print(f"wrote {path}")
    return 0


def _cmd_capacity(args: argparse.Namespace) -> int:
    if args.scenario == "calibrate":
        from station.capacity.calibrate import calibrate, write_service_times

        if args.sweep or args.replications:
            raise StationError("capacity calibrate takes only --out FILE")
        print("measuring this code's stages on this machine ...", file=sys.stderr)
        table = calibrate()
        path = write_service_times(args.out or "service_times.json", table)
        print(f"wrote {path}: ingest {table['ingest_s_per_signal_s']:.3f} s per s of signal; "
              "per full scene, GEO " + ", ".join(
                  f"{m} {v:.3f}" for m, v in table["geo_s_per_scene"].items())
              + " s; COR " + "; ".join(
                  f"{m} " + ", ".join(f"{lv} {t:.2f}" for lv, t in lvs.items())
                  for m, lvs in table["cor_s"].items()) + " s")
        return 0
    from station.capacity.config import load_capacity
    from station.capacity.study import parse_sweep, run_study, study_table

    scn = load_capacity(args.scenario)
    sweep = parse_sweep(args.sweep) if args.sweep else None
    if args.replications is not None and args.replications < 1:
        raise StationError(f"--replications {args.replications}: expected at least 1")
    out = Path(args.out) if args.out else Path("runs") / scn.name
    summary = run_study(scn, out, sweep, args.replications, plots=not args.no_plots)
    if args.json:
        print(json.dumps(summary, indent=2, default=str))
    else:
        print(study_table(summary))
        print(f"in {out}/: summary.json, stages.csv, levels.csv, station.csv, queues.csv"
              + ("" if args.no_plots else ", queues.png, latency.png"
                 + (", sweep.png" if sweep else "")))
    return 0


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="station",
        description="Emulated SPOT direct-receiving station and processing centre.",
    )
    sub = parser.add_subparsers(dest="command")
    run = sub.add_parser(
        "run",
        help="run a scenario end to end (emulate, downlink, L0, GEO and COR, quality, "
             "quicklooks, report.json); the default scenario without one",
    )
    run.add_argument("scenario", nargs="?",
                     help="path to a scenario .toml (default: scenarios/quickstart.toml)")
    run.add_argument("--out", help="run directory (default: runs/<scenario name>)")
    run.add_argument("--json", action="store_true", help="print the report instead of a table")
    run.add_argument("--no-quicklooks", action="store_true", help="skip the quicklook PNGs")
    run.add_argument("--quiet", action="store_true", help="no progress bars")
    run.set_defaults(func=_cmd_run)
    locate = sub.add_parser(
        "locate",
        help="predict the frame of a real SPOT scene from its METADATA.DIM and compare",
    )
    locate.add_argument("metadata", help="path to a SPOT level-1A METADATA.DIM")
    locate.add_argument(
        "--attitude",
        default="auto",
        choices=["auto", "corrected", "none", "aocs", "integrated", "integrated_zeroed"],
        help="attitude model (default: auto, see levels.readers.dimap)",
    )
    locate.add_argument("--json", action="store_true", help="print JSON instead of a table")
    locate.set_defaults(func=_cmd_locate)
    emul = sub.add_parser(
        "emulate", help="run the spacecraft emulator on a scenario file and summarise it"
    )
    emul.add_argument("scenario", help="path to a scenario .toml (see scenarios/)")
    emul.add_argument("--no-render", action="store_true", help="geometry only, no image")
    emul.add_argument("--json", action="store_true", help="print JSON instead of text")
    emul.set_defaults(func=_cmd_emulate)
    down = sub.add_parser(
        "downlink",
        help="emulate a pass, send it through the channel, receive it and record the L0",
    )
    down.add_argument("scenario", help="path to a scenario .toml (see scenarios/)")
    down.add_argument("--out", help="L0 file to write (default: <scenario name>.l0.h5)")
    down.add_argument("--json", action="store_true", help="print JSON instead of text")
    down.set_defaults(func=_cmd_downlink)
    proc = sub.add_parser(
        "process",
        help="emulate and receive a pass, then make its level 1A, 1B, 2A products (GEO, COR)",
    )
    proc.add_argument("scenario", help="path to a scenario .toml (see scenarios/)")
    proc.add_argument("--out", help="directory of the products (default: <name>_products)")
    proc.add_argument("--json", action="store_true", help="print JSON instead of a table")
    proc.set_defaults(func=_cmd_process)
    comp = sub.add_parser(
        "compare",
        help="compare two products or two run directories; exit 0 within tolerances, 1 "
             "outside, 2 on bad input",
    )
    comp.add_argument("a", help="a product (.h5) or a run directory")
    comp.add_argument("b", help="the product or run directory to compare it with")
    comp.add_argument("--tolerances", help="TOML file overriding the default tolerances "
                                           "(docs/compare.md)")
    comp.add_argument("--json", action="store_true", help="print JSON instead of text")
    comp.set_defaults(func=_cmd_compare)
    insp = sub.add_parser("inspect", help="what a level product holds, at a glance")
    insp.add_argument("product", help="a level product (.h5)")
    insp.add_argument("--json", action="store_true", help="print JSON instead of text")
    insp.set_defaults(func=_cmd_inspect)
    expo = sub.add_parser("export", help="export a level 2A product as a GeoTIFF")
    expo.add_argument("product", help="a level product (.h5)")
    expo.add_argument("--geotiff", action="store_true", required=True,
                      help="GeoTIFF through GDAL (the only format so far)")
    expo.add_argument("--out", help="output file (default: the product's name with .tif)")
    expo.set_defaults(func=_cmd_export)
    cap = sub.add_parser(
        "capacity", help="capacity planning: a simpy model of the station, or `calibrate`",
        description="Simulate a station's passes, recording and processing queues over a "
                    "capacity scenario (scenarios/capacity/), with replications and what-if "
                    "sweeps; or `station capacity calibrate` to measure this code's service "
                    "times on this machine.")
    cap.add_argument("scenario", help="a capacity scenario (.toml), or 'calibrate'")
    cap.add_argument("--sweep", help="SECTION.KEY=V1,V2,... (e.g. "
                                     "resources.cor_workers=1,2,3,4)")
    cap.add_argument("--replications", type=int, help="replications (default: the scenario's)")
    cap.add_argument("--out", help="output directory (default runs/<name>/); for calibrate, "
                                   "the service-time file (default service_times.json)")
    cap.add_argument("--json", action="store_true", help="print the summary as JSON")
    cap.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    cap.set_defaults(func=_cmd_capacity)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``station`` console script; returns the exit code."""
    parser = _parser()
    args = parser.parse_args(argv)
    if args.command is None:  # `station` alone runs the default scenario
        args = parser.parse_args(["run"])
    try:
        return args.func(args)
    except (LevelsError, StationError, OSError) as exc:
        print(f"station: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
