"""The ``station`` command line. Thin: it parses, calls one function, prints.

Bad input gives one line on stderr and exit code 2, never a traceback.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence

from levels.errors import LevelsError

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
    except (LevelsError, OSError) as exc:
        print(f"station: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
