"""A pass's level 0 as CCSDS space packets others read (``station export L0.h5 --packets
DIR``, ``docs/l0.md``).

Every image line of every band and every auxiliary record of the archive becomes one
fixed-length source packet (CCSDS 133.0-B-2: a 6-byte primary header, version 0,
telemetry, no secondary header, unsegmented, a 14-bit sequence count), one file per
application process (APID) of the packets laid end to end:

- ``<name>_apid<N>_<band>.bin``, APID ``0x100 + k`` for band ``k``: the line counter, the
  line's time, the validity of each segment (as the archive holds it), the counts of every
  detector, and the CRC-16-CCITT of all before it;
- ``<name>_apid<N>_aux.bin``, APID ``0x010``: each auxiliary record (its time code, the line
  counter it goes with, the gyro rates, the mirror step, the status word), and its CRC.

Beside each, ``….csv`` is its packet definition as ccsdspy reads one (``name, data_type,
bit_length``; arrays as ``uint(N)``), without the primary header, which every reader
knows: ``ccsdspy.FixedLength.from_file(csv).load(bin)`` gives the archive's arrays back.
``packets.json`` lists the files, their APIDs and packet counts.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from station.telemetry.crc import crc_table

__all__ = ["APID_AUX", "APID_IMAGE", "export_packets"]

APID_IMAGE, APID_AUX = 0x100, 0x010


@dataclass(frozen=True)
class _Field:
    name: str
    dtype: str  # numpy's, big-endian
    kind: str  # ccsdspy's data_type
    count: int = 0  # an array of this many (0: a scalar)


def _layout(fields: list[_Field]) -> np.dtype:
    return np.dtype([(f.name, f.dtype, (f.count,)) if f.count else (f.name, f.dtype)
                     for f in fields])  # fmt: skip


def _definition(fields: list[_Field]) -> str:
    rows = ["name,data_type,bit_length"]
    for f in fields:
        kind = f"{f.kind}({f.count})" if f.count else f.kind
        rows.append(f"{f.name},{kind},{8 * np.dtype(f.dtype).itemsize}")
    return "\n".join(rows) + "\n"


def _crc16_rows(rows: NDArray[np.uint8]) -> NDArray[np.uint16]:
    """CRC-16-CCITT of each row of bytes, every row at once (a byte column at a time)."""
    table = crc_table().astype(np.uint32)
    reg = np.full(rows.shape[0], 0xFFFF, np.uint32)
    for i in range(rows.shape[1]):  # the row's bytes in turn, over every packet at once
        reg = ((reg << 8) & 0xFFFF) ^ table[((reg >> 8) ^ rows[:, i]) & 0xFF]
    return reg.astype(np.uint16)


def _packets(apid: int, fields: list[_Field], values: dict[str, NDArray]) -> bytes:
    """The packets of one APID: their primary headers, the fields, the CRC of the fields."""
    n = len(next(iter(values.values())))
    body = np.zeros(n, _layout(fields))
    for f in fields:
        if f.name != "crc16":
            body[f.name] = values[f.name]
    raw = body.view(np.uint8).reshape(n, -1)
    body["crc16"] = _crc16_rows(raw[:, :-2])
    head = np.zeros((n, 6), np.uint8)
    word1 = apid & 0x7FF  # version 0, telemetry, no secondary header
    seq = (0b11 << 14) | (np.arange(n) & 0x3FFF)  # unsegmented
    length = raw.shape[1] - 1
    head[:, 0], head[:, 1] = word1 >> 8, word1 & 0xFF
    head[:, 2], head[:, 3] = seq >> 8, seq & 0xFF
    head[:, 4], head[:, 5] = length >> 8, length & 0xFF
    return np.concatenate([head, body.view(np.uint8).reshape(n, -1)], axis=1).tobytes()


def export_packets(l0_path: str | Path, out_dir: str | Path) -> dict[str, object]:
    """Write the archive's lines and auxiliary records as space packets into ``out_dir``
    (module docstring); returns what ``packets.json`` lists."""
    import h5py

    from levels.readers.l0 import read_l0

    archive = read_l0(l0_path)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    name = Path(l0_path).name.removesuffix(".h5").removesuffix(".l0")
    written: list[dict[str, object]] = []
    for k, (band, b) in enumerate(archive.bands.items()):
        counts = np.asarray(b.counts, np.uint8)
        fields = [
            _Field("line_counter", ">u4", "uint"),
            _Field("line_t_s", ">f8", "float"),
            _Field("segment_valid", "u1", "uint", b.valid.shape[1]),
            _Field("counts", "u1", "uint", counts.shape[1]),
            _Field("crc16", ">u2", "uint"),
        ]
        values: dict[str, NDArray] = {
            "line_counter": archive.line_counter,
            "line_t_s": archive.line_t_s,
            "segment_valid": b.valid.astype(np.uint8).reshape(b.valid.shape[0], -1),
            "counts": counts,
        }
        written.append(_write(out, f"{name}_apid{APID_IMAGE + k}_{band}", APID_IMAGE + k,
                              fields, values))  # fmt: skip
    with h5py.File(l0_path) as f:
        aux: dict[str, NDArray] = {key: np.asarray(f["aux"][key]) for key in f["aux"]}
    fields = [
        _Field("time_ms", ">i8", "int"),
        _Field("line_time_ms", ">i8", "int"),
        _Field("line_counter", ">i8", "int"),
        _Field("t_s", ">f8", "float"),
        _Field("gyro_rates_rad_per_s", ">f8", "float", 3),
        _Field("mirror_step", ">i2", "int"),
        _Field("status", ">i4", "int"),
        _Field("crc16", ">u2", "uint"),
    ]
    written.append(_write(out, f"{name}_apid{APID_AUX}_aux", APID_AUX, fields, aux))
    listing: dict[str, object] = {"archive": Path(l0_path).name, "files": written}
    (out / "packets.json").write_text(json.dumps(listing, indent=1))
    return listing


def _write(
    out: Path, stem: str, apid: int, fields: list[_Field], values: dict[str, NDArray]
) -> dict[str, object]:
    data = _packets(apid, fields, values)
    (out / f"{stem}.bin").write_bytes(data)
    (out / f"{stem}.csv").write_text(_definition(fields))
    n = len(next(iter(values.values())))
    return {"apid": apid, "file": f"{stem}.bin", "definition": f"{stem}.csv", "packets": n}
