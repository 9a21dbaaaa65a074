"""HDF5 files of the project, products and L0 archives alike: built in memory and written
whole, checksummed, and read back with any damage turned into one error.

- :func:`new_hdf5` builds a file in memory (HDF5's core driver) and writes it whole through
  :func:`levels.files.atomic_path`: HDF5 never writes to the disk itself, so a full disk is
  one clean ``OSError``, never HDF5's own failing writes (a flood of errors and a crash).
- Checksums: every dataset's chunks carry Fletcher-32 (:func:`checksummed`), the object
  headers HDF5's metadata checksums (:data:`HDF5_FILE_OPTIONS`), and the root attribute
  :data:`ATTRS_DIGEST` the SHA-256 of every other attribute, whose strings (in the global
  heap) HDF5 does not checksum (:func:`attrs_digest`, :func:`check_attrs_digest`).
- :func:`damage_as` turns what a damaged file makes h5py or a parser raise into the
  reader's own error, in words (:func:`hdf5_damage`).
"""

from __future__ import annotations

import contextlib
import hashlib
import itertools
import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from levels.files import atomic_path

__all__ = [
    "ATTRS_DIGEST",
    "HDF5_FILE_OPTIONS",
    "attrs_digest",
    "check_attrs_digest",
    "checksummed",
    "damage_as",
    "hdf5_damage",
    "new_hdf5",
]

#: How every HDF5 file of the project is created: with the object-header format of HDF5
#: 1.8 and later, whose metadata carry checksums that the library verifies on read (a
#: flipped byte in a header or an attribute is an error, not a wrong value), readable by
#: HDF5 1.8 to 1.12 and so by netCDF-C, GDAL and h5netcdf.
HDF5_FILE_OPTIONS = {"libver": ("v108", "v112")}


def checksummed(data: Any) -> dict[str, Any]:
    """``create_dataset`` options that store a Fletcher-32 checksum with every chunk of
    ``data`` (verified by HDF5 on each read; a scalar cannot be chunked and has none)."""
    return {"fletcher32": True} if np.ndim(data) > 0 and np.size(data) > 0 else {}


#: Root attribute holding the SHA-256 of every other attribute of the file (32 bytes, in
#: the checksummed object header): HDF5 checksums the datasets' chunks (Fletcher-32) and
#: the object headers, but not the strings of the global heap, where the JSON attributes
#: live.
ATTRS_DIGEST = "attributes_sha256"
#: Dimension-scale plumbing whose values are object references (file addresses): only
#: their presence enters the digest.
_PLUMBING = ("DIMENSION_LIST", "REFERENCE_LIST")

#: What h5py and the readers' own parsing raise on a damaged file: turned into the
#: package's error by :func:`damage_as`.
_READ_ERRORS = (OSError, RuntimeError, KeyError, ValueError, TypeError, IndexError, AttributeError)

_MEMORY_FILES = itertools.count()


def _attr_bytes(value: Any) -> bytes:
    if isinstance(value, bytes):
        return b"b" + value
    if isinstance(value, str):
        return b"s" + value.encode("utf-8")
    a = np.asarray(value)
    if a.dtype.kind == "O":
        return b"o" + "\x1f".join(str(x) for x in a.ravel()).encode("utf-8")
    return f"{a.dtype.str}{a.shape}".encode() + a.tobytes()


def attrs_digest(f: h5py.File) -> bytes:
    """SHA-256 of every attribute of the file but the digest itself (of the plumbing, its
    presence), in the order of the objects' and the attributes' names."""
    h = hashlib.sha256()

    def add(name: str, obj: Any) -> None:
        for key in sorted(obj.attrs):
            if name == "" and key == ATTRS_DIGEST:
                continue
            h.update(f"{name}/{key}=".encode())
            if key not in _PLUMBING:  # references and layout: their presence only
                h.update(_attr_bytes(obj.attrs[key]))

    add("", f)
    f.visititems(add)
    return h.digest()


def check_attrs_digest(f: h5py.File, required: bool) -> None:
    """Raise ``ValueError`` if the attributes do not match their stored digest (or it is
    missing where ``required``)."""
    stored = f.attrs.get(ATTRS_DIGEST)
    if stored is None:
        if required:
            raise ValueError(f"the attribute digest '{ATTRS_DIGEST}' is missing")
        return
    if np.asarray(stored, dtype=np.uint8).tobytes() != attrs_digest(f):
        raise ValueError(
            "the attributes do not match their stored digest: the file is damaged or was edited"
        )


@contextlib.contextmanager
def new_hdf5(target: str | Path) -> Iterator[h5py.File]:
    """A new HDF5 file, built in memory and written to ``target`` whole when the block ends
    (through :func:`levels.files.atomic_path`). HDF5 never writes to the disk itself: a full
    disk is one clean ``OSError`` from the final write, and the temporary file is removed;
    HDF5's own failing writes would end in a flood of errors and a crash of the library.
    The products and the L0 archive are held in memory by their readers anyway."""
    f = h5py.File(
        f"memory-{os.getpid()}-{next(_MEMORY_FILES)}.h5",
        "w",
        driver="core",
        backing_store=False,
        **HDF5_FILE_OPTIONS,
    )
    try:
        yield f
        f.attrs[ATTRS_DIGEST] = np.frombuffer(attrs_digest(f), dtype=np.uint8)
        f.flush()
        image = f.id.get_file_image()
    finally:
        f.close()
    with atomic_path(target) as tmp:
        tmp.write_bytes(image)


def hdf5_damage(exc: BaseException) -> str:
    """What an HDF5 read error says of the file, in words: a checksum that does not match
    (:func:`checksummed`, :data:`HDF5_FILE_OPTIONS`) or another damage."""
    text = " ".join(str(exc).split())
    if "filter returned failure" in text or "checksum" in text.lower():
        return f"a stored checksum does not match: the file is damaged ({text})"
    return f"the file is damaged or truncated ({text})"


@contextlib.contextmanager
def damage_as(error: type[Exception], where: Path) -> Iterator[None]:
    """Inside the block, what a damaged file makes h5py or a parser raise becomes one
    ``error`` naming the file and the damage (:func:`hdf5_damage`); ``error`` itself, a
    reader's own precise message, passes through."""
    try:
        yield
    except error:
        raise
    except _READ_ERRORS as exc:
        raise error(f"{where}: {hdf5_damage(exc)}") from None
