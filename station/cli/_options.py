"""Options and printing shared by the command families."""

from __future__ import annotations

import argparse
import json
from collections.abc import Callable
from typing import Any

from levels.files import json_default

__all__ = ["add_json", "add_out", "emit"]


def add_json(parser: argparse.ArgumentParser, what: str = "JSON instead of text") -> None:
    """``--json``: machine-readable output."""
    parser.add_argument("--json", action="store_true", help=f"print {what}")


def add_out(parser: argparse.ArgumentParser, help_text: str) -> None:
    """``--out``: where the command writes."""
    parser.add_argument("--out", help=help_text)


def emit(args: argparse.Namespace, data: Any, text: Callable[[Any], str]) -> None:
    """Print ``data`` as JSON with ``--json``, else as ``text(data)``."""
    print(json.dumps(data, indent=2, default=json_default) if args.json else text(data))
