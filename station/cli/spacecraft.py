"""``station emulate`` and ``station downlink``: the spacecraft emulator, and a pass sent
through the X-band channel into the receiving station's L0 archive."""

from __future__ import annotations

import argparse
import time
from typing import TYPE_CHECKING, Any

from station.cli._options import add_json, add_out, emit

if TYPE_CHECKING:
    from station.cli._options import Subparsers

__all__ = ["register"]


def register(sub: Subparsers) -> None:
    emul = sub.add_parser(
        "emulate",
        help="run the spacecraft emulator on a scenario file and summarise it",
        description="Emulate a scenario's pass (orbit, attitude, HRV imaging of the world) "
        "and summarise the strip, its footprint and the station's passes.",
    )
    emul.add_argument("scenario", help="path to a scenario .toml (see scenarios/)")
    emul.add_argument("--no-render", action="store_true", help="geometry only, no image")
    add_json(emul)
    emul.set_defaults(func=_emulate)
    down = sub.add_parser(
        "downlink",
        help="emulate a pass, send it through the channel, receive it and record the L0",
        description="Emulate a pass, pack it into packets and CADUs, send it through the "
        "X-band channel, decode it at the station and record the L0 archive; "
        "the decoding is checked against what was sent.",
    )
    down.add_argument("scenario", help="path to a scenario .toml (see scenarios/)")
    add_out(down, "L0 file to write (default: <scenario name>.l0.h5)")
    add_json(down)
    down.set_defaults(func=_downlink)


def _emulate(args: argparse.Namespace) -> int:
    from station.loader import load_scenario
    from station.spacecraft.emulator import emulate
    from station.spacecraft.summary import summarize

    start = time.perf_counter()
    scn = load_scenario(args.scenario)
    acq = emulate(scn, render=not args.no_render)
    summary = summarize(acq)
    summary["elapsed_s"] = round(time.perf_counter() - start, 3)
    summary.setdefault("station", scn.ground_station.name)
    emit(args, summary, _emulate_text)
    return 0


def _emulate_text(summary: dict[str, Any]) -> str:
    lines: list[str] = []
    s, f = summary["strip"], summary["footprint"]
    lines.append(
        f"{summary['scenario']}: HRV{s['hrv']} {s['mode']}, mirror step {s['mirror_step']}"
        f"{' (twin)' if s['twin'] else ''}, {s['lines']} lines x {s['detectors']} detectors"
    )
    lines.append(
        f"strip centre {s['centre_utc']} UTC at {f['centre_lat_lon_deg'][0]:.5f}°, "
        f"{f['centre_lat_lon_deg'][1]:.5f}° ({f['centre_height_m']:.0f} m); "
        f"satellite at {s['satellite_altitude_km']:.1f} km"
    )
    lines.append(
        f"footprint {f['width_first_line_km']:.2f} km across x "
        f"{f['length_first_column_km']:.2f} km along"
    )
    for b in summary["bands"]:
        lines.append(
            f"band {b['name']}: mean {b['mean_counts']:.1f} counts, {b['saturated']} "
            f"saturated, {b['failed_rays']} rays lost, Newton <= {b['newton_iterations_max']}"
        )
    ps = summary["passes"]
    if ps:
        lines.append(
            f"{len(ps)} passes over {summary['station']} "
            f"(median {sorted(p['duration_min'] for p in ps)[len(ps) // 2]:.1f} min):"
        )
        for p in ps:
            lines.append(
                f"  AOS {p['aos_utc']}  {p['duration_min']:6.2f} min  max el "
                f"{p['max_elevation_deg']:5.1f}°  {'day' if p['daylight'] else 'night'}"
            )
    h = summary["handover"]
    lines.append(
        f"handed to the station: {h['gyro_samples']} gyro samples, {h['bulletin_points']} "
        f"bulletin points, {h['control_points']} control points"
    )
    lines.append(f"elapsed {summary['elapsed_s']:.1f} s")
    return "\n".join(lines)


def _downlink(args: argparse.Namespace) -> int:
    from station.chain.report import downlink_scenario

    emit(args, downlink_scenario(args.scenario, args.out), _downlink_text)
    return 0


def _downlink_text(rep: dict[str, Any]) -> str:
    lines: list[str] = []
    link = rep["link"]
    lines.append(
        f"{rep['scenario']}: HRV{rep['hrv']} {rep['mode']}, {rep['lines']} lines x "
        f"{rep['detectors']} detectors"
    )
    lines.append(
        f"link: {link['cadus_sent']} CADUs in {link['duration_s']:.2f} s at "
        f"{link['bit_rate_mbps']:g} Mbit/s; {link['bit_errors']} bit errors, "
        f"{link['bursts']} bursts, {link['fades']} fades"
    )
    lines.append("CADUs: " + ", ".join(f"{k} {v}" for k, v in rep["cadus"].items()))
    lines.append(
        f"{'channel':>8} {'sent':>7} {'deliv.':>7} {'lost':>6} {'gaps':>5} {'dupl.':>6} "
        f"{'o-o-o':>6} {'corr.':>6} {'symbols':>8}  ends known"
    )
    for name, c in rep["channels"].items():
        lines.append(
            f"{name:>8} {c['sent']:7d} {c['delivered']:7d} {c['lost']:6d} {c['gaps']:5d} "
            f"{c['duplicates']:6d} {c['out_of_order']:6d} {c['corrected']:6d} "
            f"{c['symbols_corrected']:8d}  {'yes' if c['head_known'] else 'no'}/"
            f"{'yes' if c['tail_known'] else 'no'}"
        )
    for b in rep["bands"]:
        lines.append(
            f"band {b['name']}: {b['lines_complete']} lines complete, {b['lines_partial']} "
            f"partial, {b['lines_missing']} missing; valid pixels "
            f"{'as sent' if b['valid_pixels_as_sent'] else 'DIFFER FROM WHAT WAS SENT'}, "
            f"error vs raw counts max {b['max_error_vs_raw_counts']} rms "
            f"{b['rms_error_vs_raw_counts']:.2f}"
        )
    tc = rep["truth_check"]
    lines.append(
        f"against the truth: {tc['data_frames_lost']} data frames lost; masks "
        f"{'match' if tc['masks_match_lost_frames'] else 'DO NOT MATCH'} the segments they "
        f"touched; accounts {'balance' if tc['accounts_balance'] else 'DO NOT BALANCE'}, "
        f"frames sent {'as counted' if tc['sent_as_counted'] else 'MISCOUNTED'}"
    )
    lc = rep["line_clock"]
    lines.append(
        f"line clock: period {lc['period_s'] * 1e3:.6f} ms, time of the middle line "
        f"±{lc['uncertainty_us']:.1f} µs; max error vs truth {lc['max_error_vs_truth_us']:.1f} "
        "µs"
    )
    t = rep["timings_s"]
    lines.append(
        f"L0: {rep['l0']['path']} ({rep['l0']['size_mb']:.1f} MB); emulate {t['emulate']:.1f} "
        f"s, send {t['transmit']:.2f} s, channel {t['channel']:.2f} s, receive "
        f"{t['receive']:.2f} s ({rep['receive_speed_x_real_time']:.1f}x real time at 50 "
        f"Mbit/s), record {t['record']:.2f} s"
    )
    return "\n".join(lines)
