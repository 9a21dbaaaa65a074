"""The ``station`` command line. Thin: it parses, calls one function, prints.

Bad input gives one line on stderr and exit code 2, never a traceback.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence

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


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="station",
        description="Emulated SPOT direct-receiving station and processing centre.",
    )
    sub = parser.add_subparsers(dest="command")
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
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``station`` console script; returns the exit code."""
    parser = _parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help()
        return 0
    try:
        return args.func(args)
    except (LevelsError, StationError, OSError) as exc:
        print(f"station: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
