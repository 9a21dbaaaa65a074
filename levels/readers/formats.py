"""The readers as a registry: every format the processing centre reads says whether it can
open a path and opens it, as xarray's backends do (``guess_can_open``, ``open_dataset``).

A :class:`Format` names what it reads (a pass's archive, :attr:`levels.kinds.Unit.SCENE`'s
input; a SAR frame, :attr:`levels.kinds.Unit.FRAME`'s), ``can_open(path)`` and
``open(path)``. :func:`format_of` finds the first that can open a path, in the order of
:data:`FORMATS` (the sure tests first: a file's own bytes before its name);
:func:`open_frame` and :func:`open_archive` open one. A new format is one entry here: no
caller names a reader.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from levels.errors import DimapError, ProductError
from levels.kinds import Unit
from levels.readers.bounded import refuse_broken_zip
from levels.readers.envisat import is_envisat, read_envisat
from levels.readers.l0 import L0Archive, read_l0
from levels.readers.sar import SarFrame, is_sar_frame, read_sar_frame
from levels.readers.scene1a import is_dimap_scene, read_scene_1a

__all__ = ["FORMATS", "Format", "format_of", "is_frame_file", "open_archive", "open_frame"]


@dataclass(frozen=True)
class Format:
    """A format the processing centre reads (module docstring)."""

    name: str
    reads: Unit
    can_open: Callable[[Path], bool]
    open: Callable[[Path], Any]


def _house_frame(path: Path) -> bool:
    return path.suffix == ".h5" and is_sar_frame(path)


def _l0(path: Path) -> L0Archive:
    return read_l0(path, lazy=True)  # a scene's counts are read by its task


#: Every format, in the order :func:`format_of` asks them.
FORMATS: tuple[Format, ...] = (
    Format("SAR-FRAME", Unit.FRAME, _house_frame, read_sar_frame),
    Format("ENVISAT", Unit.FRAME, is_envisat, read_envisat),
    Format("DIMAP", Unit.SCENE, is_dimap_scene, read_scene_1a),
    Format("L0", Unit.SCENE, lambda p: True, _l0),  # the archive's reader says what it is not
)


def format_of(path: str | Path, reads: Unit | None = None) -> Format | None:
    """The first format that can open ``path`` (of inputs of ``reads``, if given)."""
    p = Path(path)
    for f in FORMATS:
        if (reads is None or f.reads is reads) and f.can_open(p):
            return f
    return None


def is_frame_file(path: str | Path) -> bool:
    """Whether ``path`` is a SAR frame :func:`open_frame` reads."""
    return format_of(path, Unit.FRAME) is not None


def open_frame(path: str | Path) -> SarFrame:
    """The SAR frame in ``path`` (the house file, ESA's ENVISAT format…)."""
    f = format_of(path, Unit.FRAME)
    if f is None:
        raise ProductError(f"{path}: not a SAR frame this processing centre reads")
    frame: SarFrame = f.open(Path(path))
    return frame


def open_archive(path: str | Path) -> L0Archive:
    """What the processing centre reads a pass from: an L0 archive (read lazily) or a DIMAP
    level-1A scene."""
    refuse_broken_zip(Path(path), DimapError)  # not "not a readable HDF5 file"
    f = format_of(path, Unit.SCENE)
    assert f is not None  # the L0 reader takes every path, and says what it is not
    archive: L0Archive = f.open(Path(path))
    return archive
