"""Files from outside read within bounds: a size cap on every file and zip member read
whole, and GDAL kept from reading what lies beside an image.

A reader of outside files trusts no size it has not checked: a 2 MB zip whose
``METADATA.DIM`` inflates to 2 GiB must be refused in a second, not parsed for a minute
until the machine runs out of memory. Every metadata document and every member of a zip
read whole goes through :func:`read_capped` or :func:`read_member`, which refuse, naming the
file, what is larger than the cap before reading it (the size a zip declares, then the
bytes actually inflated, which a forged header cannot raise).

GDAL, opening an image, lists its folder and parses the metadata it finds beside it (its
TIFF driver reads a sibling ``METADATA.DIM`` through its SPOT metadata reader: a huge one
took 4.8 s and several GB, and crashed GDAL when larger). The project has read and checked
that metadata itself; :func:`gdal_image_alone` opens images with
``GDAL_DISABLE_READDIR_ON_OPEN=EMPTY_DIR``, so GDAL sees the image and nothing else.
"""

from __future__ import annotations

import contextlib
import zipfile
import zlib
from collections.abc import Iterator
from pathlib import Path

from levels.errors import LevelsError

__all__ = [
    "MAX_METADATA_BYTES",
    "MAX_TABLE_BYTES",
    "begins_with",
    "gdal_image_alone",
    "looks_like_zip",
    "read_capped",
    "read_member",
    "refuse_broken_zip",
]

#: The largest metadata document read (a DIMAP ``METADATA.DIM``, a ``DIM_*.XML``, an RPC or
#: OSSIM keyword list): 13× the largest real one here (SPOT 5's 2.5 MB, its look angles of
#: 12 000 detectors).
MAX_METADATA_BYTES = 32 * 2**20
#: The largest control-point table read (bytes): about 2.5 million points of 100 bytes,
#: far beyond any scene's.
MAX_TABLE_BYTES = 256 * 2**20


def _too_large(where: str, size: int, limit: int, what: str, error: type[LevelsError]) -> None:
    raise error(
        f"{where}: {size / 2**20:.1f} MiB, more than the {limit / 2**20:.0f} MiB any {what} "
        "takes: damaged, or not one"
    )


def read_capped(path: Path, limit: int, what: str, error: type[LevelsError] = LevelsError) -> bytes:
    """The bytes of ``path``, refused by ``error`` when it holds more than ``limit``."""
    size = path.stat().st_size
    if size > limit:
        _too_large(str(path), size, limit, what, error)
    with open(path, "rb") as f:
        data = f.read(limit + 1)
    if len(data) > limit:  # grown since the stat
        _too_large(str(path), len(data), limit, what, error)
    return data


def read_member(
    zip_path: Path, member: str, limit: int, what: str, error: type[LevelsError] = LevelsError
) -> bytes:
    """The inflated bytes of ``member`` of the zip ``zip_path``, refused by ``error`` when
    it declares or inflates to more than ``limit``, or is damaged."""
    where = f"{zip_path}/{member}"
    try:
        with zipfile.ZipFile(zip_path) as z:
            info = z.getinfo(member)
            if info.file_size > limit:
                _too_large(where, info.file_size, limit, what, error)
            with z.open(info) as f:
                data = f.read(limit + 1)
    except (zipfile.BadZipFile, zlib.error, EOFError, NotImplementedError) as exc:
        raise error(f"{where}: a damaged zip member ({exc})") from None
    if len(data) > limit:
        _too_large(where, len(data), limit, what, error)
    return data


def begins_with(path: str | Path, magic: bytes) -> bool:
    """Whether the file ``path`` begins with ``magic`` (False if it cannot be read): how a
    reader says a file is of its format before it reads it."""
    try:
        with open(path, "rb") as f:
            return f.read(len(magic)) == magic
    except OSError:
        return False


def looks_like_zip(path: Path) -> bool:
    """Whether ``path`` is meant as a zip: named ``.zip``, or opening as one (``PK\\3\\4``),
    readable or not."""
    return path.suffix.lower() == ".zip" or begins_with(path, b"PK\x03\x04")


def refuse_broken_zip(path: Path, error: type[LevelsError] = LevelsError) -> None:
    """Refuse a file meant as a zip that ``zipfile`` cannot open (empty, truncated, junk
    named ``.zip``), saying so, instead of reading it as something else."""
    if path.is_file() and looks_like_zip(path) and not zipfile.is_zipfile(path):
        size = path.stat().st_size
        raise error(
            f"{path}: not a readable zip ({size} bytes, no zip directory at its end): "
            "empty, truncated or damaged"
        )


@contextlib.contextmanager
def gdal_image_alone() -> Iterator[None]:
    """GDAL opening images without listing their folder (module docstring)."""
    import rasterio

    with rasterio.Env(GDAL_DISABLE_READDIR_ON_OPEN="EMPTY_DIR"):
        yield
