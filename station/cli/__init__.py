"""The ``station`` command line, one module per command family (rasterio's ``rio/`` is the
model): each registers its subcommands, parses, calls one function and prints.

Bad input gives one line on stderr and exit code 2, never a traceback; ``station compare``
keeps exit 1 for "outside the tolerances".
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from levels.errors import LevelsError
from station import __version__
from station.cli import capacity, locate, process, products, run, spacecraft
from station.errors import StationError

__all__ = ["main"]

#: Command families, in the order ``station --help`` lists them.
_FAMILIES = (run, process, products, spacecraft, locate, capacity)


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="station",
        description="Emulated SPOT direct-receiving station and processing centre. Without "
        "a command, runs the default scenario end to end (station run).",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for family in _FAMILIES:
        family.register(sub)
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
