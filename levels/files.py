"""Files written whole or not at all, and JSON of numpy values: one way, for every writer.

Every file the project writes (L0 archives, products, GeoTIFFs, quicklooks, reports, CSVs)
goes through :func:`atomic_path`: it is written under a hidden temporary name beside its
target (same directory, so the same file system) and renamed into place by ``os.replace``,
atomic on POSIX, only once complete. A reader never sees half a file; a failure (a full
disk, an exception, Ctrl-C) removes the temporary file and leaves any older target as it
was.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

__all__ = [
    "atomic_path",
    "json_default",
    "plain",
    "remove_partials",
    "writable_dir",
    "write_json",
    "write_text",
]


@contextlib.contextmanager
def atomic_path(target: str | Path) -> Iterator[Path]:
    """A temporary path to write ``target`` at; renamed onto it when the block succeeds.

    >>> with atomic_path("out/report.json") as tmp:   # doctest: +SKIP
    ...     tmp.write_text("{}")
    """
    target = Path(target)
    tmp = target.with_name(f".{target.name}.{os.getpid()}.partial")
    try:
        yield tmp
        os.replace(tmp, target)
    except OSError as exc:  # a full disk, a lost permission: say which file
        if exc.filename is not None:
            raise
        raise OSError(exc.errno, f"{exc.strerror} (writing {target})") from None
    finally:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()


def json_default(x: Any) -> Any:
    """``json.dumps(default=…)`` for what numpy and paths leave: numpy scalars as Python
    numbers, arrays as lists, paths as strings; non-finite floats as ``null`` where
    :func:`plain` is applied first."""
    if isinstance(x, np.generic):
        return x.item()
    if isinstance(x, np.ndarray):
        return x.tolist()
    if isinstance(x, Path):
        return str(x)
    raise TypeError(f"{type(x).__name__} is not JSON serialisable")


def plain(x: Any, digits: int | None = None) -> Any:
    """A number as JSON holds it: NaN and infinities as ``None``, rounded to ``digits``."""
    if isinstance(x, float | np.floating):
        v = float(x)
        if not math.isfinite(v):
            return None
        return round(v, digits) if digits is not None else v
    return x


def write_text(path: str | Path, text: str) -> Path:
    """Write a text file atomically (module docstring); returns its path."""
    target = Path(path)
    with atomic_path(target) as tmp:
        tmp.write_text(text)
    return target


def write_json(path: str | Path, data: Any) -> Path:
    """Write ``data`` as indented JSON atomically (module docstring); returns its path."""
    return write_text(path, json.dumps(data, indent=2, default=json_default) + "\n")


def writable_dir(path: str | Path) -> Path:
    """``path`` as a directory this process can write files in, created if need be: checked
    before any work starts, so that an unwritable output fails in a second, not after
    minutes. Raises ``OSError`` naming the directory."""
    d = Path(path)
    try:
        d.mkdir(parents=True, exist_ok=True)
        with atomic_path(d / ".write-check") as tmp:
            tmp.write_bytes(b"")
        (d / ".write-check").unlink()
    except OSError as exc:
        raise OSError(f"cannot write in {d}: {exc.strerror or exc}") from None
    return d


def remove_partials(directory: str | Path) -> list[Path]:
    """Remove the temporary files that writers killed mid-write left in ``directory``
    (``.<name>.<pid>.partial`` of :func:`atomic_path`, when process ``pid`` is gone)."""
    removed = []
    for p in Path(directory).glob(".*.partial"):
        pid = p.name.rsplit(".", 2)[-2]
        if pid.isdigit() and _alive(int(pid)):
            continue
        with contextlib.suppress(FileNotFoundError):
            p.unlink()
            removed.append(p)
    return removed


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True
