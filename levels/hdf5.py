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
- :func:`deflated_dataset` writes a large array as HDF5's own filter pipeline stores it
  (shuffle, deflate, Fletcher-32), its chunks compressed on every core: HDF5 compresses
  one chunk at a time on one thread, and deflating a full P image took 1.2 s of a level 3
  scene's 10. Levels 1 to 3 are deflated by ISA-L (:func:`deflate`), 4 times zlib's speed.
"""

from __future__ import annotations

import collections
import contextlib
import errno
import hashlib
import itertools
import os
import zlib
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any, Protocol

import h5py
import numba as nb
import numpy as np
from isal import isal_zlib

from levels.files import atomic_path
from levels.threads import thread_count

__all__ = [
    "ATTRS_DIGEST",
    "DEFLATE_LEVEL",
    "HDF5_FILE_OPTIONS",
    "ISAL_LEVELS",
    "all_attrs",
    "attrs_digest",
    "check_attrs_digest",
    "checksummed",
    "damage_as",
    "deflate",
    "deflated_dataset",
    "hdf5_damage",
    "new_hdf5",
    "new_hdf5_on_disk",
]

#: How every HDF5 file of the project is created: with the object-header format of HDF5
#: 1.8 and later, whose metadata carry checksums that the library verifies on read (a
#: flipped byte in a header or an attribute is an error, not a wrong value), readable by
#: HDF5 1.8 to 1.12 and so by netCDF-C, GDAL and h5netcdf.
HDF5_FILE_OPTIONS = {"libver": ("v108", "v112")}


def checksummed(data: Any) -> dict[str, object]:
    """``create_dataset`` options that store a Fletcher-32 checksum with every chunk of
    ``data`` (verified by HDF5 on each read; a scalar cannot be chunked and has none)."""
    return {"fletcher32": True} if np.ndim(data) > 0 and np.size(data) > 0 else {}


@nb.njit(cache=True, nogil=True)
def fletcher32(data: np.ndarray) -> int:
    """HDF5's Fletcher-32 checksum of a byte array (``H5_checksum_fletcher32``: 16-bit
    big-endian words, both sums folded every 360 words, an odd last byte as a high byte)."""
    n = data.size
    sum1 = np.uint32(0)
    sum2 = np.uint32(0)
    i = 0
    words = n // 2
    while words > 0:
        block = min(words, 360)
        words -= block
        for _ in range(block):
            sum1 += (np.uint32(data[i]) << np.uint32(8)) | np.uint32(data[i + 1])
            sum2 += sum1
            i += 2
        sum1 = (sum1 & np.uint32(0xFFFF)) + (sum1 >> np.uint32(16))
        sum2 = (sum2 & np.uint32(0xFFFF)) + (sum2 >> np.uint32(16))
    if n % 2:
        sum1 += np.uint32(data[i]) << np.uint32(8)
        sum2 += sum1
        sum1 = (sum1 & np.uint32(0xFFFF)) + (sum1 >> np.uint32(16))
        sum2 = (sum2 & np.uint32(0xFFFF)) + (sum2 >> np.uint32(16))
    sum1 = (sum1 & np.uint32(0xFFFF)) + (sum1 >> np.uint32(16))
    sum2 = (sum2 & np.uint32(0xFFFF)) + (sum2 >> np.uint32(16))
    return (int(sum2) << 16) | int(sum1)


#: Deflate levels compressed by ISA-L (Intel's Intelligent Storage Acceleration Library,
#: through python-isal) rather than zlib: the same zlib streams, which every inflater reads
#: (HDF5's deflate filter, GDAL, netCDF), made about 4 times faster than by zlib's fastest
#: level, and smaller: on a full P 2A image, 0.27 s and 22.2 MB at ISA-L's level 2 against
#: 0.93 s and 22.3 MB at zlib's level 1, one core (``benchmarks/bench_levels.py``).
ISAL_LEVELS = (1, 2, 3)
#: The products' deflate level by default (ISA-L's level 2: as fast as its level 1, and
#: smaller), of their image bands (``[processing] deflate_level``) and always of their masks.
DEFLATE_LEVEL = 2


def deflate(data: Any, level: int) -> bytes:
    """``data`` (any buffer) as a zlib stream: stored at level 0, ISA-L's levels 1 to 3
    (:data:`ISAL_LEVELS`), zlib's 4 to 9. Both let go of the GIL while they compress."""
    if not 0 <= level <= 9:
        raise ValueError(f"deflate level {level}: expected 0 to 9")
    if level in ISAL_LEVELS:
        return isal_zlib.compress(data, level)
    return zlib.compress(data, level)


def _chunk_payload(block: np.ndarray, shuffle: bool, level: int) -> bytes:
    """One chunk as HDF5's pipeline stores it: shuffled (bytes of each significance
    together), deflated (:func:`deflate`: zlib's format, as HDF5's deflate filter writes
    it), then its Fletcher-32, little-endian."""
    raw = np.ascontiguousarray(block)
    if shuffle and raw.dtype.itemsize > 1:
        raw = np.ascontiguousarray(raw.view(np.uint8).reshape(-1, raw.dtype.itemsize).T)
    packed = deflate(raw, level)  # the array's own buffer
    return packed + fletcher32(np.frombuffer(packed, np.uint8)).to_bytes(4, "little")


class Rows(Protocol):
    """What :func:`deflated_dataset` reads a dataset's chunks from: an array, or an array's
    stand-in that reads the slices asked from elsewhere (a front end's line store)."""

    @property
    def shape(self) -> tuple[int, ...]: ...

    @property
    def dtype(self) -> np.dtype: ...

    def __getitem__(self, key: tuple[slice, ...]) -> np.ndarray: ...


def deflated_dataset(
    group: h5py.Group,
    name: str,
    data: Rows,
    chunks: tuple[int, ...],
    shuffle: bool = False,
    level: int = DEFLATE_LEVEL,
    fillvalue: float | None = None,
) -> h5py.Dataset:
    """``group[name]``: ``data`` chunked, deflated at ``level`` (:func:`deflate`; shuffled
    first if asked) and checksummed, as ``create_dataset`` with those filters would store
    it, every chunk compressed by a pool of threads (numba's thread count) and written as
    it is; ``fillvalue``: the dataset's own (HDF5's; netCDF's ``_FillValue`` is set beside
    it by the caller)."""
    ds = group.create_dataset(
        name,
        shape=data.shape,
        dtype=data.dtype,
        chunks=chunks,
        compression="gzip",
        compression_opts=level,  # what the filter records; the chunks are written as made
        shuffle=shuffle,
        fletcher32=True,
        fillvalue=fillvalue,
    )
    starts = list(
        itertools.product(*(range(0, n, c) for n, c in zip(data.shape, chunks, strict=True)))
    )

    def payload(start: tuple[int, ...]) -> bytes:
        part = data[tuple(slice(s, s + c) for s, c in zip(start, chunks, strict=True))]
        if part.shape != chunks:  # an edge chunk is stored whole, padded with zeros
            block = np.zeros(chunks, dtype=data.dtype)
            block[tuple(slice(0, n) for n in part.shape)] = part
            part = block
        return _chunk_payload(part, shuffle, level)

    threads = thread_count()
    with ThreadPoolExecutor(threads) as pool:  # a few chunks in flight, not every one
        flight: collections.deque = collections.deque()
        for start in starts:
            flight.append((start, pool.submit(payload, start)))
            if len(flight) >= 4 * threads:
                done, packed = flight.popleft()
                ds.id.write_direct_chunk(done, packed.result())
        for done, packed in flight:
            ds.id.write_direct_chunk(done, packed.result())
    return ds


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


def all_attrs(f: h5py.File) -> dict[str, dict[str, Any]]:
    """Every object's attributes, read once: ``{"": the file's, "group/name": …}`` in the
    order :func:`attrs_digest` visits them (the plumbing's values left as ``None``)."""
    out: dict[str, dict[str, Any]] = {}

    def add(name: str, obj: Any) -> None:
        a = obj.attrs
        out[name] = {k: (None if k in _PLUMBING else a[k]) for k in a}

    add("", f)
    f.visititems(add)
    return out


def attrs_digest(f: h5py.File, attrs: dict[str, dict[str, Any]] | None = None) -> bytes:
    """SHA-256 of every attribute of the file but the digest itself (of the plumbing, its
    presence), in the order of the objects' and the attributes' names; ``attrs``: what
    :func:`all_attrs` read of ``f``, not read again."""
    h = hashlib.sha256()
    for name, values in (all_attrs(f) if attrs is None else attrs).items():
        for key in sorted(values):
            if name == "" and key == ATTRS_DIGEST:
                continue
            h.update(f"{name}/{key}=".encode())
            if key not in _PLUMBING:  # references and layout: their presence only
                h.update(_attr_bytes(values[key]))
    return h.digest()


def check_attrs_digest(
    f: h5py.File, required: bool, attrs: dict[str, dict[str, object]] | None = None
) -> None:
    """Raise ``ValueError`` if the attributes do not match their stored digest (or it is
    missing where ``required``); ``attrs`` as :func:`attrs_digest`'s."""
    stored = (f.attrs if attrs is None else attrs[""]).get(ATTRS_DIGEST)
    if stored is None:
        if required:
            raise ValueError(f"the attribute digest '{ATTRS_DIGEST}' is missing")
        return
    if np.asarray(stored, dtype=np.uint8).tobytes() != attrs_digest(f, attrs):
        raise ValueError(
            "the attributes do not match their stored digest: the file is damaged or was edited"
        )


@contextlib.contextmanager
def new_hdf5(target: str | Path) -> Iterator[h5py.File]:
    """A new HDF5 file, built in memory and written to ``target`` whole when the block ends
    (through :func:`levels.files.atomic_path`). HDF5 never writes to the disk itself: a full
    disk is one clean ``OSError`` from the final write, and the temporary file is removed;
    HDF5's own failing writes would end in a flood of errors and a crash of the library.
    The products and the L0 archive are held in memory by their readers anyway.

    Without a chunk cache (``rdcc_nbytes=0``), each chunk is placed in the file when it is
    written: with one, a small dataset's chunk was placed when its Python object happened
    to be freed, and the same product came out laid out differently (same content, other
    bytes) in one run of 24 on a Dask worker."""
    f = h5py.File(
        f"memory-{os.getpid()}-{next(_MEMORY_FILES)}.h5",
        "w",
        driver="core",
        backing_store=False,
        rdcc_nbytes=0,
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


@contextlib.contextmanager
def new_hdf5_on_disk(target: str | Path, need_bytes: int) -> Iterator[h5py.File]:
    """A new HDF5 file written straight to disk, for one too large to build in memory
    (a whole pass's L0 archive: :func:`new_hdf5`'s memory is twice the file). HDF5 itself
    writes, so the disk's room is checked first: fewer than ``need_bytes`` free (an upper
    bound of the file) is one clean ``OSError`` before any byte is written. The file is
    built beside ``target`` and renamed onto it whole (:func:`levels.files.atomic_path`);
    its bytes are :func:`new_hdf5`'s for the same calls."""
    import shutil

    from levels.files import atomic_path

    target = Path(target)
    free = shutil.disk_usage(target.parent).free
    if free < need_bytes:
        raise OSError(
            errno.ENOSPC,
            f"No space left on device ({need_bytes / 1e6:.0f} MB needed, {free / 1e6:.0f} MB free)",
            str(target),
        )
    with atomic_path(target) as tmp:
        f = h5py.File(tmp, "w", rdcc_nbytes=0, **HDF5_FILE_OPTIONS)
        try:
            yield f
            f.attrs[ATTRS_DIGEST] = np.frombuffer(attrs_digest(f), dtype=np.uint8)
        finally:
            f.close()


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
