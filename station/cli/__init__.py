"""The ``station`` command line, one module per command family (rasterio's ``rio/`` is the
model): each registers its subcommands, parses, calls one function and prints.

Exit codes, the same for every command (``docs/compare.md``):

- 0: done: the products asked for were made (``compare``: within the tolerances);
- 1: ``compare`` only: differences found, each named;
- 2: bad input or environment (a missing or damaged file, a bad scenario, absurd control
  points, a DEM without a CRS, a run too large for the machine's memory or disk, a full
  disk, an unwritable directory), or a run that made no product (every scene skipped):
  one line on stderr, never a traceback; a closed stdout (``| head``) is not an error;
- 3: an internal error (a bug): one line naming it, and the traceback with
  ``STATION_DEBUG=1``; never disguised as 1;
- 130: interrupted (Ctrl-C): one line, nothing half-written left (every file is written
  whole or not at all, ``levels.files``).
"""

from __future__ import annotations

import argparse
import contextlib
import io
import logging
import os
import sys
import traceback
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

from levels.errors import LevelsError
from station import __version__
from station.cli import (
    capacity,
    catalogue,
    day,
    gcps,
    live,
    locate,
    process,
    products,
    run,
    spacecraft,
)
from station.errors import StationError

if TYPE_CHECKING:
    from station.cli._options import Subparsers

__all__ = [
    "EXIT_BAD_INPUT",
    "EXIT_DIFFERENT",
    "EXIT_INTERNAL",
    "EXIT_INTERRUPTED",
    "EXIT_OK",
    "main",
]

EXIT_OK, EXIT_DIFFERENT, EXIT_BAD_INPUT, EXIT_INTERNAL, EXIT_INTERRUPTED = 0, 1, 2, 3, 130

#: Command families, in the order ``station --help`` lists them.
_FAMILIES = (run, process, products, spacecraft, live, locate, gcps, capacity, catalogue, day)


def _add_verbosity(parser: argparse.ArgumentParser, default: object) -> None:
    parser.add_argument(
        "-v",
        "--verbose",
        action="count",
        default=default,
        help="say each stage as it runs (-vv: and each scene's timings)",
    )
    parser.add_argument(
        "-q",
        "--quiet",
        action="store_true",
        default=default if default is argparse.SUPPRESS else False,
        help="nothing but errors: no progress, no table (the exit code says how it went; "
        "--json still prints what it asks for)",
    )


class _Commands:
    """The subparsers, each given ``-v`` and ``-q`` (after the command as before it)."""

    def __init__(self, sub: Subparsers) -> None:
        self._sub = sub

    def add_parser(self, name: str, **kwargs: Any) -> argparse.ArgumentParser:
        parser: argparse.ArgumentParser = self._sub.add_parser(name, **kwargs)
        _add_verbosity(parser, argparse.SUPPRESS)  # the top level's value stands if absent
        return parser


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="station",
        description="Emulated SPOT direct-receiving station and processing centre. Without "
        "a command, runs the default scenario end to end (station run).",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    _add_verbosity(parser, 0)
    sub = _Commands(parser.add_subparsers(dest="command", metavar="COMMAND"))
    for family in _FAMILIES:
        family.register(sub)
    return parser


def _configure_logging(verbose: int, quiet: bool) -> None:
    """The library's messages (``levels``, ``station``) on stderr: warnings by default,
    stages with ``-v``, timings with ``-vv``, errors only with ``-q``."""
    level = (
        logging.ERROR
        if quiet
        else {0: logging.WARNING, 1: logging.INFO}.get(verbose, logging.DEBUG)
    )
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(logging.Formatter("station: %(message)s"))
    for name in ("levels", "station"):
        log = logging.getLogger(name)
        log.handlers[:] = [handler]
        log.setLevel(level)
        log.propagate = False


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``station`` console script; returns the exit code."""
    parser = _parser()
    args = parser.parse_args(argv)
    if args.command is None:  # `station` alone runs the default scenario
        given = list(argv) if argv is not None else sys.argv[1:]
        args = parser.parse_args([*given, "run"])
    _configure_logging(args.verbose, args.quiet)
    try:
        if args.quiet and not getattr(args, "json", False):
            with contextlib.redirect_stdout(io.StringIO()):  # -q: nothing but errors
                return int(args.func(args))
        return int(args.func(args))
    except BrokenPipeError:  # `station compare … | head`: the reader had enough
        _quiet_broken_pipe()
        return EXIT_OK
    except (LevelsError, StationError, OSError) as exc:
        print(f"station: error: {_one_line(exc)}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except MemoryError as exc:  # what was asked does not fit this machine: not a bug
        print(
            f"station: error: out of memory ({_one_line(exc)}): the run is too large for "
            "this machine; reduce its sizes (lines, detectors, scene_lines) or its --workers",
            file=sys.stderr,
        )
        return EXIT_BAD_INPUT
    except KeyboardInterrupt as exc:
        notes = "; ".join(getattr(exc, "__notes__", ())) or "files being written were discarded"
        print(f"station: interrupted; {notes}", file=sys.stderr)
        return EXIT_INTERRUPTED
    except Exception as exc:  # a bug: said as such, with its traceback on request
        if os.environ.get("STATION_DEBUG"):
            traceback.print_exc()
        print(
            f"station: internal error: {type(exc).__name__}: {_one_line(exc)} (a bug; "
            "STATION_DEBUG=1 shows where)",
            file=sys.stderr,
        )
        return EXIT_INTERNAL


def _quiet_broken_pipe() -> None:
    """Stdout's reader is gone: point stdout at /dev/null so that the interpreter's final
    flush does not fail again (the ``signal.SIG_DFL`` alternative kills with 141)."""
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, sys.stdout.fileno())


def _one_line(exc: BaseException) -> str:
    """The error and its notes (``BaseException.add_note``: what was left as it was); the
    operating system's as "file: reason" (never Python's "[Errno 30] …: 'file'")."""
    said = " ".join(str(exc).split()) or type(exc).__name__
    if isinstance(exc, OSError) and exc.strerror and exc.filename is not None:
        what = f"{exc.filename} → {exc.filename2}" if exc.filename2 is not None else exc.filename
        said = f"{what}: {exc.strerror}"
    return "; ".join([said, *getattr(exc, "__notes__", ())])
