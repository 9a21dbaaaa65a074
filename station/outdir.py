"""Outputs a command owns, directories and single files: checked before any work, and a
directory published whole.

``station run``, ``station process`` and ``station campaign`` each write one directory
(``--out``) and replace it whole when they finish (:func:`levels.files.staged_dir`): a
failure, a full disk or Ctrl-C leaves the previous one exactly as it was. Since the whole
directory is replaced, :func:`replaceable_dir` first makes sure it holds nothing else: it
must be absent, empty, or an earlier output of the same command (its report names it:
``report.json`` of a run of the same scenario, ``process.json``, ``campaign.json``).
Anything else (another scenario's run, the user's own files, the current directory, the
inputs of the command) is refused before any work starts.

Each output knows its own files: :func:`published_dir` writes their list
(:data:`MANIFEST`) as it publishes the directory, and a later run into it refuses, naming
them, the files the station did not write there (a note, an analysis, an export): it never
deletes what is not its own. GDAL's sidecars of its files (``<file>.aux.xml``) and what a
killed writer left (``.<file>.<pid>.partial``) are its.

A command that writes one file (``station downlink``, ``export --geotiff``, ``gcps``,
``capacity calibrate``) follows one rule, :func:`replaceable_file`: the file must be absent,
or the same command's earlier output of the same thing (an L0 archive of the same
scenario, an export of the same product, the points of the same pass); anything else (a
user's file, a run's own L0 of another pass) is refused before any work, naming it. Its
directory is checked writable then too, not after minutes of work.
"""

from __future__ import annotations

import contextlib
import json
import logging
import shutil
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path

from levels.files import staged_dir, writable_dir, write_text
from station.errors import StationError

_log = logging.getLogger(__name__)

__all__ = ["MANIFEST", "published_dir", "replaceable_dir", "replaceable_file"]

#: The list of the files an output directory holds as the station wrote it.
MANIFEST = ".station-files"
#: Files GDAL writes beside a file it read (statistics, masks): the file's own.
_SIDECARS = (".aux.xml",)


def _files(d: Path) -> list[str]:
    return sorted(str(p.relative_to(d)) for p in d.rglob("*") if p.is_file() or p.is_symlink())


@contextlib.contextmanager
def published_dir(target: str | Path) -> Iterator[Path]:
    """:func:`levels.files.staged_dir` that lists the files it publishes (:data:`MANIFEST`)
    as the directory's own, and keeps what GDAL wrote beside them (:func:`_keep_caches`)."""
    with staged_dir(target) as stage:
        yield stage
        own = _files(stage)
        _keep_caches(Path(target), stage)
        write_text(stage / MANIFEST, "".join(f + "\n" for f in [*own, MANIFEST]))


def _keep_caches(old: Path, stage: Path) -> None:
    """GDAL's sidecars in the previous output that the station did not write (``gdalinfo
    -stats`` caches a file's statistics in ``<file>.aux.xml``): carried into the new output
    where their file is byte for byte the same (a rerun), else dropped, said in one line
    (statistics of another image would mislead)."""
    listed = old / MANIFEST
    if not listed.is_file():
        return
    own = set(listed.read_text(encoding="utf-8").splitlines())
    for f in _files(old):
        base = next((f[: -len(s)] for s in _SIDECARS if f.endswith(s)), None)
        if f in own or base is None or base not in own:
            continue
        new_base, new_sidecar = stage / base, stage / f
        if new_sidecar.exists():
            continue  # the station writes this sidecar itself now
        if new_base.is_file() and _same_bytes(old / base, new_base):
            shutil.copy2(old / f, new_sidecar)
        else:
            _log.warning("%s: dropped, GDAL's cache of %s, which changed", old / f, base)


def _same_bytes(a: Path, b: Path) -> bool:
    if a.stat().st_size != b.stat().st_size:
        return False
    with open(a, "rb") as fa, open(b, "rb") as fb:
        while True:
            x, y = fa.read(1 << 20), fb.read(1 << 20)
            if x != y:
                return False
            if not x:
                return True


def not_own(d: Path) -> list[str]:
    """The files in output directory ``d`` that the station did not write (its
    :data:`MANIFEST` does not list them, nor are they GDAL's sidecars of those); none
    known for an output written before the manifest."""
    listed = d / MANIFEST
    if not listed.is_file():
        return []
    own = set(listed.read_text(encoding="utf-8").splitlines())
    return [
        f
        for f in _files(d)
        if f not in own
        and not any(f.endswith(s) and f[: -len(s)] in own for s in _SIDECARS)
        and not (Path(f).name.startswith(".") and f.endswith(".partial"))  # a killed writer's
    ]


def replaceable_dir(
    out: str | Path,
    report: str,
    owner: Callable[[dict[str, object]], object],
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
    foreign = not_own(d)
    if foreign:
        more = f" and {len(foreign) - 3} more" if len(foreign) > 3 else ""
        raise StationError(
            f"{d} holds {what(expected)} and files it did not write "
            f"({', '.join(foreign[:3])}{more}); the output directory is replaced whole: move "
            "them, or give another --out"
        )
    return d


def replaceable_file(
    out: str | Path,
    owner: Callable[[Path], object],
    expected: object,
    what: Callable[[object], str],
) -> Path:
    """``out``, one file the command may write (module docstring): absent, or what
    ``owner(out)`` says it is equals ``expected`` (``owner`` returns None, or raises, for a
    file the command did not write); else :class:`StationError`, before any work. Its
    directory is created and checked writable now (``OSError`` naming it)."""
    p = Path(out)
    if p.is_dir():
        raise StationError(f"--out {out} is a directory: give the file's name")
    if p.exists() or p.is_symlink():
        try:
            previous = owner(p)
        except (OSError, ValueError, KeyError, TypeError, AttributeError):
            previous = None  # a file that cannot be read as one: not the command's
        if previous != expected:
            said = "not a file this command wrote" if previous is None else what(previous)
            raise StationError(
                f"{p} exists and is {said}, not {what(expected)}: not replaced (remove it, or "
                "give another name)"
            )
    writable_dir(p.parent)
    return p
