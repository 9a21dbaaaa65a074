"""Options and printing shared by the command families."""

from __future__ import annotations

import argparse
import contextlib
import sys
from collections.abc import Callable, Iterator
from typing import Any, TypeAlias

__all__ = ["add_json", "add_out", "add_runner", "emit", "exit_made", "runner_of"]


def add_json(parser: argparse.ArgumentParser, what: str = "JSON instead of text") -> None:
    """``--json``: machine-readable output."""
    parser.add_argument("--json", action="store_true", help=f"print {what}")


def add_out(parser: argparse.ArgumentParser, help_text: str) -> None:
    """``--out``: where the command writes."""
    parser.add_argument("--out", help=help_text)


def emit(args: argparse.Namespace, data: Any, text: Callable[[Any], str]) -> None:
    """Print ``data`` as JSON with ``--json``, else as ``text(data)``."""
    from station.reports import json_text

    print(json_text(data) if args.json else text(data))


def add_runner(parser: argparse.ArgumentParser, what: str = "scenes") -> None:
    """``--workers N`` and ``--scheduler ADDRESS``: where the tasks run (levels.tasks)."""
    g = parser.add_argument_group(
        "where the work runs",
        f"The {what} are tasks: in this process by default (every core for each), on a "
        "local Dask cluster of N worker processes (--workers), or on a running Dask "
        "cluster (--scheduler, or $DASK_SCHEDULER_ADDRESS). Products are the same bit for "
        "bit. Dask is the optional extra: pip install 'spot-station[distributed]'.",
    )
    g.add_argument(
        "--workers",
        type=int,
        default=None,
        metavar="N",
        help="start a local Dask cluster of N worker processes, one task each at a time",
    )
    g.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help="the Dask scheduler of a running cluster (e.g. tcp://10.0.0.5:8786)",
    )


@contextlib.contextmanager
def runner_of(args: argparse.Namespace) -> Iterator[Any]:
    """The runner :func:`add_runner`'s options ask for (:func:`station.flow.runner_for`)."""
    from station.flow import runner_for

    with runner_for(args.workers, args.scheduler) as runner:
        yield runner


def exit_made(n_products: int, what: str) -> int:
    """The exit code of a command that makes products: 0 when it made some; 2 with one
    line when it made none (every scene skipped), which is not a success."""
    if n_products:
        return 0
    print(
        f"station: error: {what} made no product (every scene skipped: see above)", file=sys.stderr
    )
    return 2


#: What a command module's ``register(sub)`` adds its parsers to.
Subparsers: TypeAlias = "argparse._SubParsersAction[argparse.ArgumentParser]"
