"""Files written whole or not at all, and JSON of numpy values: one way, for every writer.

Every file the project writes (L0 archives, products, GeoTIFFs, quicklooks, reports, CSVs)
goes through :func:`atomic_path`: it is written under a hidden temporary name beside its
target (same directory, so the same file system) and renamed into place by ``os.replace``,
atomic on POSIX, only once complete. A reader never sees half a file; a failure (a full
disk, an exception, Ctrl-C) removes the temporary file and leaves any older target as it
was.

A directory of outputs (a run, a reprocessing, a campaign) is published the same way, whole:
:func:`staged_dir` builds it in a hidden directory beside its target and renames it into
place only when complete; until then the previous directory stays exactly as it was.
"""

from __future__ import annotations

import contextlib
import glob
import json
import math
import os
import shutil
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

__all__ = [
    "atomic_path",
    "check_writable",
    "json_default",
    "plain",
    "remove_partials",
    "staged_dir",
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
        if exc.filename is not None and str(exc.filename) == str(tmp) and exc.strerror:
            raise OSError(exc.errno, exc.strerror, str(target)) from None  # not the partial's
        if exc.filename is not None:
            raise
        said = f"{exc.strerror or exc or type(exc).__name__} (writing {target})"
        # GDAL's errors (rasterio's) carry no errno: the message alone, no "[Errno None]"
        raise (OSError(exc.errno, said) if exc.errno is not None else OSError(said)) from None
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


def check_writable(path: str | Path) -> Path:
    """That directory ``path`` can be made and written here, without making it (nothing is
    left behind if the work is then stopped): its nearest existing ancestor is a directory
    this process can write in. Raises ``OSError`` naming it and why."""
    d = Path(path)
    if d.exists():
        return writable_dir(d)
    parent = next((p for p in d.absolute().parents if p.exists()), Path("/"))
    if not parent.is_dir():
        raise OSError(f"cannot write in {d}: {parent} is a file, not a directory")
    try:
        fd, name = tempfile.mkstemp(prefix=".write-check.", dir=parent)
        os.close(fd)
        os.unlink(name)
    except OSError as exc:
        raise OSError(f"cannot write in {parent}: {exc.strerror or exc}") from None
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


@contextlib.contextmanager
def staged_dir(target: str | Path) -> Iterator[Path]:
    """A new empty directory beside ``target`` to build it in, published as ``target`` when
    the block succeeds.

    The staging directory, ``.<name>.<pid>.staging`` in ``target``'s parent (the same file
    system), is renamed onto ``target`` once complete: the previous ``target`` is renamed
    aside (``.<name>.<pid>.previous``), the new one into place, then the previous one
    removed. A failure or an interruption in the block removes the staging directory and
    leaves ``target`` exactly as it was; the exception then carries a note saying so. A
    process killed between the two renames leaves the previous directory aside: the next
    call puts it back (:func:`_recover`). Raises ``OSError`` naming the parent when it
    cannot be written.
    """
    target = Path(target)
    if target.is_symlink():  # the directory it points to is replaced, the link stays
        target = target.resolve()
    parent = target.parent
    try:
        parent.mkdir(parents=True, exist_ok=True)
        _recover(target)
        stage = parent / f".{target.name}.{os.getpid()}.staging"
        shutil.rmtree(stage, ignore_errors=True)
        stage.mkdir()
    except OSError as exc:
        raise OSError(f"cannot write in {parent}: {exc.strerror or exc}") from None
    try:
        yield stage
        aside = parent / f".{target.name}.{os.getpid()}.previous"
        if target.exists():
            os.rename(target, aside)
            try:
                os.rename(stage, target)
            except BaseException:
                os.rename(aside, target)
                raise
            shutil.rmtree(aside, ignore_errors=True)
        else:
            os.rename(stage, target)
    except BaseException as exc:
        shutil.rmtree(stage, ignore_errors=True)
        exc.add_note(
            f"{target} left as it was" if target.exists() else f"nothing written to {target}"
        )
        raise


def _recover(target: Path) -> None:
    """What killed :func:`staged_dir` calls left beside ``target``: their staging
    directories removed, and a previous directory renamed aside put back if ``target`` is
    missing (else removed)."""
    for p in target.parent.glob(f".{glob.escape(target.name)}.*"):
        stem, pid, kind = p.name.rsplit(".", 2)
        if stem != f".{target.name}" or kind not in ("staging", "previous"):
            continue
        if not pid.isdigit() or _alive(int(pid)):
            continue
        if kind == "previous" and not target.exists():
            os.rename(p, target)
        else:
            shutil.rmtree(p, ignore_errors=True)
