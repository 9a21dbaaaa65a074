"""``station locate``: a real SPOT scene's frame predicted from its DIMAP metadata."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING, Any

import numpy as np

from station.cli._options import add_json, emit
from station.errors import StationError

if TYPE_CHECKING:
    from station.cli._options import Subparsers

__all__ = ["register"]


def register(sub: Subparsers) -> None:
    p = sub.add_parser(
        "locate",
        help="predict the frame of a real SPOT scene from its METADATA.DIM",
        description="Predict the frame corners and centre of a real SPOT 1–5 level-1A scene "
        "from its DIMAP metadata (ephemeris, attitude, look angles) and compare "
        "them with the producer's Dataset_Frame; of a SPOT 6/7 (or Pléiades) DIMAP v2 "
        "scene from its producer's RPC (RPC_*.XML), against its Dataset_Extent; the "
        "geolocation grid of an ERS SAR frame of ESA's format from its state vectors.",
    )
    p.add_argument(
        "metadata",
        help="path to a SPOT level-1A METADATA.DIM (its scene directory, or SWH's zip), a "
        "SPOT 6/7 DIMAP v2 DIM_*.XML, an ERS frame of ESA's format (.E1, .E2: its "
        "geolocation grid against the range–Doppler model), or, with --rpc, OSSIM's .geom "
        "keyword list of a SPOT 5 scene",
    )
    p.add_argument(
        "--attitude",
        default="auto",
        choices=["auto", "corrected", "none", "aocs", "integrated", "integrated_zeroed"],
        help="attitude model (default: auto, see levels.readers.dimap)",
    )
    p.add_argument(
        "--gcps",
        help="a control-point file of the scene (docs/gcp.md): how far the DIMAP model "
        "misses each point",
    )
    p.add_argument(
        "--model",
        default="rigorous",
        choices=["rigorous", "rpc"],
        help="with --gcps: predict the points through the rigorous model (default) or "
        "through RPCs fitted to it, and say how far the two land apart",
    )
    p.add_argument(
        "--rpc",
        metavar="OUT",
        help="fit RPCs (RPC00B) to the DIMAP model and write them as the sidecar GDAL reads "
        "next to an image: IMAGE_RPC.TXT beside IMAGE.tif (or IMAGE.RPB)",
    )
    p.add_argument(
        "--heights",
        default="0,3000",
        metavar="LO,HI",
        help="height range of the RPC fit, metres above the ellipsoid (default 0,3000: "
        "cover the scene's terrain)",
    )
    add_json(p)
    p.set_defaults(func=_locate)


def _locate(args: argparse.Namespace) -> int:
    from station.products import check_frame, check_gcps, parse_heights, write_rpc

    if args.rpc:
        lo, hi = parse_heights(args.heights)
        emit(args, write_rpc(args.metadata, args.rpc, (lo, hi), args.attitude), _rpc_text)
        return 0
    if args.metadata.lower().endswith(".geom"):
        raise StationError(
            f"{args.metadata}: an OSSIM keyword list has no producer's frame to check; "
            "use --rpc OUT to fit its RPCs"
        )
    if args.gcps:
        gc = check_gcps(args.metadata, args.gcps, attitude=args.attitude, model=args.model)
        emit(args, gc.as_dict(), _gcp_text)
        return 0
    check = check_frame(args.metadata, attitude=args.attitude)
    if not np.isfinite(check.error_m).any():
        raise StationError(
            f"{args.metadata}: none of its {check.error_m.size} frame points locates through "
            "its model (its orbit, timing or look angles are out of reach): nothing to check"
        )
    emit(args, check.as_dict() if args.json else check, _text)
    return 0


def _rpc_text(d: dict) -> str:
    e = d["fit_error_px"]
    if not e:  # a DIMAP v2 scene's own RPC, converted
        return f"{d['scene']}: {d['attitude']} written to {d['path']} as it is (no fit)"
    return (
        f"{d['scene']}  (attitude: {d['attitude']}): RPC00B written to {d['path']}\n"
        f"fitted over the image and heights {e['height_min_m']:.0f}–{e['height_max_m']:.0f} m; "
        f"against the rigorous model at {e['n_points']} check points: RMS "
        f"{e['rms_px']:.4f} px, max {e['max_px']:.4f} px (line {e['line_max_px']:.4f}, "
        f"sample {e['sample_max_px']:.4f})"
    )


def _gcp_text(d: dict) -> str:
    lines = [
        f"{d['scene']}  (attitude: {d['attitude']}): the DIMAP model against "
        f"{len(d['points'])} control points",
        f"{'id':>12} {'line':>10} {'column':>10} {'pred line':>10} {'pred col':>10} "
        f"{'miss px':>8} {'ground m':>9}",
    ]
    for p in d["points"]:
        lines.append(
            f"{p['id']:>12} {p['line']:10.2f} {p['column']:10.2f} "
            f"{p['predicted_line']:10.2f} {p['predicted_column']:10.2f} "
            f"{p['miss_px']:8.2f} {p['ground_miss_m']:9.2f}"
            + ("" if p["within_reach"] else "  out of the model's reach: not counted")
        )
    lines.append(
        f"RMS {d['rms_px']:.2f} px, {d['rms_ground_m']:.2f} m on the ground; max "
        f"{d['max_ground_m']:.2f} m (over {d['points_within_reach']} point(s))"
    )
    if d["model"] == "rpc":
        e = d["rpc_fit_error_px"]
        lines.append(
            f"predicted through RPCs (fit RMS {e['rms_px']:.4f} px, max {e['max_px']:.4f} px "
            f"over {e['height_min_m']:.0f}–{e['height_max_m']:.0f} m): at most "
            f"{d['rpc_vs_rigorous_px']:.4f} px from the rigorous model's predictions"
        )
    return "\n".join(lines)


def _text(check: Any) -> str:
    lines = [
        f"{check.scene}  (attitude: {check.attitude})",
        f"{'point':>12} {'lat °':>12} {'lon °':>12} {'pred lat °':>12} "
        f"{'pred lon °':>12} {'error m':>8} {'closure px':>10}",
    ]
    if check.row.size == 5:
        shown = list(enumerate(["corner 1", "corner 2", "corner 3", "corner 4", "centre"]))
    else:  # a SAR frame's geolocation grid: its first and last lines' tie points
        n = check.row.size
        keep = [*range(min(11, n)), *range(max(11, n - 11), n)]
        shown = [(i, f"r{check.row[i]} c{check.col[i]}") for i in keep]
    for i, label in shown:
        lines.append(
            f"{label:>12} {check.lat_deg[i]:12.7f} {check.lon_deg[i]:12.7f} "
            f"{check.predicted_lat_deg[i]:12.7f} {check.predicted_lon_deg[i]:12.7f} "
            f"{check.error_m[i]:8.3f} {check.roundtrip_px[i]:10.2e}"
        )
    located = np.isfinite(check.error_m)
    e = check.error_m[located]
    if check.row.size != 5:
        rms = float(np.sqrt(np.mean(e**2)))
        lines.append(f"{int(located.sum())} tie points: RMS {rms:.3f} m")
    lines.append(f"max error {e.max():.3f} m")
    if not located.all():  # said, never a "nan" to read as a figure
        lines.append(
            f"{int((~located).sum())} of {located.size} points not located through the model "
            "(beyond its orbit or timing): not counted"
        )
    return "\n".join(lines)
