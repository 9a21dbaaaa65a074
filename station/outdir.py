"""Output directories a command owns: checked before any work, published whole.

``station run``, ``station process`` and ``station campaign`` each write one directory
(``--out``) and replace it whole when they finish (:func:`levels.files.staged_dir`): a
failure, a full disk or Ctrl-C leaves the previous one exactly as it was. Since the whole
directory is replaced, :func:`replaceable_dir` first makes sure it holds nothing else: it
must be absent, empty, or an earlier output of the same command (its report names it:
``report.json`` of a run of the same scenario, ``process.json``, ``campaign.json``).
Anything else (another scenario's run, the user's own files, the current directory, the
inputs of the command) is refused before any work starts.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

from station.errors import StationError

__all__ = ["replaceable_dir"]


def replaceable_dir(
    out: str | Path,
    report: str,
    owner: Callable[[dict[str, Any]], object],
    expected: object,
    what: Callable[[object], str],
    inputs: Iterable[str | Path] = (),
) -> Path:
    """``out``, which the command may replace whole (module docstring); else
    :class:`StationError` saying why, before any work.

    ``report`` is the file naming an earlier output of the command, ``owner(its JSON)``
    what it was made of (a scenario's name), to equal ``expected``; ``what(owner)`` says
    such an output in words ("a run of scenario 'x'"); none of ``inputs`` may lie in
    ``out``.
    """
    d = Path(out)
    here = Path.cwd().resolve()
    full = d.resolve()
    if full == here or full in here.parents:
        raise StationError(f"--out {out}: the current directory or above it; give a new directory")
    for i in inputs:
        if full in Path(i).resolve().parents:
            raise StationError(f"--out {out} holds the input {i}: give another directory")
    if d.exists() and not d.is_dir():
        raise StationError(f"--out {out} is a file, not a directory")
    if not d.is_dir() or not any(d.iterdir()):
        return d
    marker = d / report
    previous: object = None
    if marker.is_file():
        try:
            previous = owner(json.loads(marker.read_text(encoding="utf-8")))
        except (ValueError, KeyError, TypeError, UnicodeDecodeError, AttributeError):
            previous = None
    if previous is None:
        sample = sorted(p.name for p in d.iterdir())[:3]
        raise StationError(
            f"{d} holds files that are not {what(expected)} ({', '.join(sample)}…); the output "
            "directory is replaced whole: give a new or empty --out"
        )
    if previous != expected:
        raise StationError(
            f"{d} holds {what(previous)}, not {what(expected)}: give another --out "
            "(or remove that one)"
        )
    return d
