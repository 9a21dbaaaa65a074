"""``station gcps``: a pass's control points found on a reference ortho-image."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

from station.cli._options import add_json, emit

if TYPE_CHECKING:
    from station.cli._options import Subparsers

__all__ = ["register"]


def register(sub: Subparsers) -> None:
    p = sub.add_parser(
        "gcps",
        help="find a pass's control points on a reference ortho-image",
        description="Find the control points of a recorded pass (an L0 archive, or a SPOT "
        "1–4 DIMAP 1A scene) on a reference ortho-image and a DEM (levels.reference: "
        "windows of the raw image orthorectified onto the reference's grid with the "
        "current model, phase correlation, level 2's adjustment, in a loop until the mean "
        "shift is 1/20 px), and write them as a control-point file (docs/gcp.md, kind "
        "reference) for station process --gcps.",
    )
    p.add_argument("source", help="an L0 archive (.h5) or a DIMAP 1A scene (.zip, directory)")
    p.add_argument("--reference", required=True, help="the reference ortho-image (GeoTIFF)")
    p.add_argument("--dem", required=True, help="the DEM under the pass (GeoTIFF)")
    p.add_argument("--out", required=True, help="the control-point file to write (.csv)")
    p.add_argument(
        "--ce95",
        type=float,
        help="the reference's geolocation accuracy, 95 %% circular (m): the points' σ on "
        "the ground (default: its truth file's when the emulator wrote it, else exact)",
    )
    p.add_argument(
        "--options", help="a TOML file whose [processing] sets level 2's options and the cut"
    )
    p.add_argument(
        "--scenario", help="the scenario that made the archive: each point scored against its truth"
    )
    add_json(p)
    p.set_defaults(func=_gcps, levels=None)


def _gcps(args: argparse.Namespace) -> int:
    from station.loader import load_scenario
    from station.outdir import replaceable_file
    from station.processing import options_of, recorded_cut
    from station.refgcps import gcps_from_reference, points_source

    source = Path(args.source).name
    replaceable_file(args.out, points_source, source, lambda s: f"the control points found for {s}")
    scn = load_scenario(args.scenario) if args.scenario else None
    base = scn.processing if scn is not None else recorded_cut([Path(args.source)])
    options = options_of(args, base)  # --options and --dem as station process reads them
    _, summary = gcps_from_reference(
        args.source,
        args.reference,
        args.dem,
        args.out,
        options=options,
        ce95_m=args.ce95,
        scenario=scn,
    )
    emit(args, summary, _text)
    return 0


def _text(d: dict) -> str:
    from station.refgcps import KEEP_SIGMAS

    lines = [
        f"{d['points']} control points found on {d['reference']} written to {d['out']} "
        f"(reference σ {d['reference_sigma_m']:.2f} m per axis)"
    ]
    for k, loop in enumerate(d["loops"]):
        lines.append(
            f"  loop {k + 1}: {int(loop['points'])} windows, mean shift "
            f"{loop['mean_shift_px']:.3f} px (each {loop['point_shift_px']:.3f}, at most "
            f"{loop['max_shift_px']:.2f})"
        )
    adj = d.get("adjustment") or {}
    if adj:
        left = int(adj.get("points_used") or 0) - int(d["points"])
        lines.append(
            f"  level 2's adjustment: {adj.get('points_used')} used, "
            f"{adj.get('points_rejected')} rejected as blunders"
            + (
                f"; {left} used but beyond {KEEP_SIGMAS:g}σ of the fit, not written"
                if left > 0
                else ""
            )
        )
    if "truth" in d:
        t = d["truth"]
        lines.append(
            f"  against the truth: {t['rms_m']:.2f} m RMS, {t['median_m']:.2f} m median, mean "
            f"({t['mean_east_m']:+.2f}, {t['mean_north_m']:+.2f}) m east, north"
        )
    bias = d.get("truth", {})
    if "rms_of_matching_m" in bias and (
        bias["reference_bias_east_m"] or bias["reference_bias_north_m"]
    ):
        t = d["truth"]
        lines.append(
            f"  the reference's own bias ({t['reference_bias_east_m']:+.2f}, "
            f"{t['reference_bias_north_m']:+.2f}) m taken off: {t['rms_of_matching_m']:.2f} m "
            "RMS (the matching's)"
        )
    return "\n".join(lines)
