"""Large arrays written with their chunks compressed on every core are what HDF5's own
filter pipeline would have stored (byte for byte at zlib's levels 4 to 9; at ISA-L's, and
stored, the same filters and chunks, each inflating to HDF5's own), and HDF5 checks them on read."""

from __future__ import annotations

import zlib

import h5py
import numpy as np
import pytest

from levels.hdf5 import ISAL_LEVELS, deflate, deflated_dataset, fletcher32


@pytest.mark.parametrize(
    ("shape", "dtype", "chunks", "shuffle"),
    [
        ((700, 913), np.uint8, (512, 512), False),  # an image: edge chunks part empty
        ((231, 309), np.float32, (128, 128), True),  # a DEM window
        ((4, 19, 24), np.float64, (1, 19, 24), True),  # a grid per segment
        ((5001,), np.int16, (1024,), True),
    ],
)
@pytest.mark.parametrize("level", [0, 2, 6])
def test_chunks_are_hdf5s_own(tmp_path, shape, dtype, chunks, shuffle, level) -> None:
    rng = np.random.default_rng(2)
    data = (rng.normal(100.0, 30.0, shape)).astype(dtype)
    ours, theirs = tmp_path / "ours.h5", tmp_path / "theirs.h5"
    with h5py.File(ours, "w") as f:
        deflated_dataset(f, "x", data, chunks, shuffle, level)
    with h5py.File(theirs, "w") as f:
        f.create_dataset(
            "x",
            data=data,
            chunks=chunks,
            compression="gzip",
            compression_opts=level,
            shuffle=shuffle,
            fletcher32=True,
        )
    with h5py.File(ours) as a, h5py.File(theirs) as b:
        assert a["x"].compression == "gzip" and a["x"].fletcher32
        assert a["x"].shuffle == shuffle and a["x"].chunks == chunks
        assert np.array_equal(a["x"][()], data)
        n = b["x"].id.get_num_chunks()
        assert a["x"].id.get_num_chunks() == n
        for k in range(n):
            offset = b["x"].id.get_chunk_info(k).chunk_offset
            (mask_a, mine), (mask_b, hdf5s) = (
                a["x"].id.read_direct_chunk(offset),
                b["x"].id.read_direct_chunk(offset),
            )
            assert mask_a == mask_b
            if level < 4:  # ISA-L, or stored blocks cut elsewhere: the same once inflated
                assert (
                    fletcher32(np.frombuffer(mine[:-4], np.uint8)).to_bytes(4, "little")
                    == (mine[-4:])
                )
                assert zlib.decompress(mine[:-4]) == zlib.decompress(hdf5s[:-4])
            else:
                assert mine == hdf5s


def test_deflate_levels() -> None:
    """Every level makes a zlib stream zlib inflates; ISA-L's levels 1 to 3 compress an
    8-bit image about as well as zlib's level 1; a level outside 0 to 9 is refused."""
    rng = np.random.default_rng(3)
    image = np.clip(rng.normal(120.0, 20.0, (256, 512)), 0, 255).astype(np.uint8)
    sizes = {}
    for level in range(10):
        packed = deflate(image, level)
        assert zlib.decompress(packed) == image.tobytes()
        sizes[level] = len(packed)
    assert sizes[0] > image.nbytes  # stored, with its framing
    # ISA-L compresses noise-like counts as well as zlib's fastest level, give or take 2 %
    # (measured: 2 % smaller here, and on full P images)
    zlib_1 = len(zlib.compress(image, 1))
    assert all(sizes[lv] < 1.02 * zlib_1 for lv in ISAL_LEVELS)
    with pytest.raises(ValueError, match="deflate level 10"):
        deflate(image, 10)


def test_fletcher32_is_hdf5s_and_catches_a_flipped_byte(tmp_path) -> None:
    # the checksum HDF5 itself appends to its chunks, of odd and even lengths
    rng = np.random.default_rng(4)
    with h5py.File(tmp_path / "h.h5", "w") as f:
        ds = f.create_dataset(
            "x",
            data=rng.integers(0, 40, (64, 640), dtype=np.uint8),
            chunks=(64, 16),
            compression="gzip",
            fletcher32=True,
        )
        payloads = [
            ds.id.read_direct_chunk(ds.id.get_chunk_info(k).chunk_offset)[1]
            for k in range(ds.id.get_num_chunks())
        ]
    assert {len(p) % 2 for p in payloads} == {0, 1}
    for p in payloads:
        assert fletcher32(np.frombuffer(p[:-4], np.uint8)).to_bytes(4, "little") == p[-4:]
    path = tmp_path / "x.h5"
    data = np.arange(600 * 400, dtype=np.uint16).reshape(600, 400)
    with h5py.File(path, "w") as f:
        deflated_dataset(f, "x", data, (256, 256))
        address = f["x"].id.get_chunk_info(0).byte_offset
    raw = bytearray(path.read_bytes())
    raw[address + 40] ^= 0x10
    path.write_bytes(bytes(raw))
    with h5py.File(path) as f, pytest.raises(OSError):
        f["x"][:256, :256]


def test_a_file_s_bytes_do_not_depend_on_when_its_datasets_are_freed(tmp_path) -> None:
    """A chunk held in HDF5's chunk cache was placed when its dataset object was freed:
    a Dask worker that freed one later wrote the same product with other bytes. Without
    the cache, the bytes follow the writes alone."""
    from levels.hdf5 import new_hdf5

    def write(path, hold: bool) -> bytes:
        held = []
        with new_hdf5(path) as f:
            for k in range(4):
                ds = f.create_dataset(
                    f"a{k}", data=np.arange(300.0) * k, chunks=(300,), fletcher32=True
                )
                if hold:
                    held.append(ds)
            f.create_group("g").attrs["x"] = 1
        return path.read_bytes()

    assert write(tmp_path / "a.h5", hold=False) == write(tmp_path / "b.h5", hold=True)


def test_a_file_written_on_disk_checks_the_room_first(tmp_path, monkeypatch) -> None:
    """``new_hdf5_on_disk``: too little room is one clean ENOSPC before a byte is
    written; otherwise the file is whole, digested, and the same for the same writes."""
    import errno
    import shutil
    from collections import namedtuple

    from levels.hdf5 import ATTRS_DIGEST, new_hdf5_on_disk

    def write(path) -> bytes:
        with new_hdf5_on_disk(path, 1 << 20) as f:
            f.create_dataset("a", data=np.arange(5000.0), chunks=(1000,), fletcher32=True)
            f.attrs["x"] = 1
        return path.read_bytes()

    assert write(tmp_path / "a.h5") == write(tmp_path / "b.h5")
    with h5py.File(tmp_path / "a.h5") as f:
        assert ATTRS_DIGEST in f.attrs and f["a"][-1] == 4999.0
    usage = namedtuple("usage", "total used free")
    monkeypatch.setattr(shutil, "disk_usage", lambda _p: usage(10, 10, 1000))
    with pytest.raises(OSError) as raised:
        write(tmp_path / "c.h5")
    assert raised.value.errno == errno.ENOSPC and "1 MB needed" in str(raised.value)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.h5", "b.h5"]  # nothing left
