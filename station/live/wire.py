"""What travels between the sender and the front end (``docs/live.md``).

A pass is **announced** on a connection of its own: the 8 bytes ``SPOTPASS``, a 4-byte
big-endian length and a JSON document: the pass's name, its provenance and scene cut, and
per channel (one per HRV: SPOT 1–4's two X-band image channels) its tag, HRV, bit rate and
what a station is handed besides telemetry (the orbit bulletins, the nominal look-angle and
calibration tables). Arrays travel as their bytes (base64), so the archive the front end
writes is the file route's, bit for bit.

Each **channel** is a connection: the 8 bytes ``SPOTCHAN``, a length and a JSON header
(the pass and the channel's tag), then the demodulator's bytes in pieces (a 4-byte length
and the bytes), ended by a piece of length 0 and the stream's exact length in bits (8
bytes: a demodulator's last byte may be part filled). A connection that closes before that
end is a stream cut where it stopped: a gap in the accounting, not an error.

Both channels of a pass may share one connection instead (``[downlink] one_connection``,
``station transmit --one-connection``): the 8 bytes ``SPOTMUXC``, a length and a JSON
header (the pass and its channels' tags, in order), then each channel's pieces as they
come, interleaved, each led by its channel's index (1 byte); a channel ends as it does on
its own connection (its index, a length 0, its length in bits), the connection when every
channel has ended. A connection that closes before a channel's end cuts that channel.

A connection whose first bytes are none of these is a **raw** CADU stream (another tool's, a
recorded ``.cadu`` file replayed): every byte is the stream's, to the connection's close.
"""

from __future__ import annotations

import base64
import json
import socket
import struct
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from levels.geometry.ephemeris import Ephemeris
from levels.geometry.sensor import LookAngleTable
from station.srrs.recorder import BandAncillary

__all__ = [
    "CHANNEL",
    "MULTIPLEX",
    "PASS",
    "Announcement",
    "ChannelInfo",
    "WireError",
    "pack_header",
    "read_exact",
    "read_header",
]

PASS, CHANNEL, MULTIPLEX = b"SPOTPASS", b"SPOTCHAN", b"SPOTMUXC"
#: A header longer than this is not one (a raw stream that happens to start so).
MAX_HEADER_BYTES = 64 << 20
_LENGTH = struct.Struct(">I")
_BITS = struct.Struct(">Q")


class WireError(Exception):
    """A connection that does not speak the protocol it started with."""


def _array(a: NDArray) -> dict[str, object]:
    a = np.ascontiguousarray(a)
    return {
        "dtype": a.dtype.str,
        "shape": list(a.shape),
        "b64": base64.b64encode(a.tobytes()).decode(),
    }


def _unarray(d: dict) -> NDArray:
    raw = base64.b64decode(d["b64"])
    return np.frombuffer(raw, np.dtype(d["dtype"])).reshape(d["shape"]).copy()


@dataclass(frozen=True, eq=False)
class ChannelInfo:
    """One channel of an announced pass: its archive's tag, its HRV and bit rate, and what
    the station is handed for it besides telemetry."""

    tag: str
    hrv: int
    bit_rate_bit_per_s: float
    bulletins: Ephemeris
    bulletin_epoch_utc: np.datetime64
    ancillary: tuple[BandAncillary, ...]

    def as_json(self) -> dict[str, object]:
        e = self.bulletins
        return {
            "tag": self.tag,
            "hrv": self.hrv,
            "bit_rate_bit_per_s": self.bit_rate_bit_per_s,
            "bulletin_epoch_utc": str(np.asarray(self.bulletin_epoch_utc).astype("datetime64[ns]")),
            "bulletins": {
                "t_s": _array(e.t_s),
                "r_ecef_m": _array(e.r_ecef_m),
                "v_ecef_m_per_s": _array(e.v_ecef_m_per_s),
                "n_points": e.n_points,
                "reference_velocity": e.reference_velocity,
            },
            "ancillary": [
                {
                    "name": a.name,
                    "column": _array(a.look.column),
                    "psi_x_rad": _array(a.look.psi_x_rad),
                    "psi_y_rad": _array(a.look.psi_y_rad),
                    "n_columns": a.look.n_columns,
                    "gain": _array(a.gain),
                    "offset_counts": _array(a.offset_counts),
                }
                for a in self.ancillary
            ],
        }

    @classmethod
    def of_json(cls, d: dict) -> ChannelInfo:
        b = d["bulletins"]
        eph = Ephemeris(
            _unarray(b["t_s"]),
            _unarray(b["r_ecef_m"]),
            _unarray(b["v_ecef_m_per_s"]),
            int(b["n_points"]),
            b["reference_velocity"],
        )
        bands = tuple(
            BandAncillary(
                a["name"],
                LookAngleTable(
                    _unarray(a["column"]),
                    _unarray(a["psi_x_rad"]),
                    _unarray(a["psi_y_rad"]),
                    int(a["n_columns"]),
                ),
                _unarray(a["gain"]),
                _unarray(a["offset_counts"]),
            )
            for a in d["ancillary"]
        )
        epoch = np.datetime64(d["bulletin_epoch_utc"], "ns")
        return cls(str(d["tag"]), int(d["hrv"]), float(d["bit_rate_bit_per_s"]), eph, epoch, bands)


@dataclass(frozen=True, eq=False)
class Announcement:
    """A pass the sender is about to send (module docstring)."""

    name: str
    channels: tuple[ChannelInfo, ...]
    provenance: dict[str, object] = field(default_factory=dict)
    scene_cut: dict[str, int] = field(default_factory=dict)

    def message(self) -> bytes:
        body = {
            "name": self.name,
            "provenance": self.provenance,
            "scene_cut": self.scene_cut,
            "channels": [c.as_json() for c in self.channels],
        }
        return pack_header(PASS, body)

    @classmethod
    def of_json(cls, d: dict) -> Announcement:
        try:
            return cls(
                str(d["name"]),
                tuple(ChannelInfo.of_json(c) for c in d["channels"]),
                dict(d.get("provenance", {})),
                {k: int(v) for k, v in d.get("scene_cut", {}).items()},
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise WireError(f"a pass announcement that does not read: {exc}") from None


def pack_header(magic: bytes, body: Mapping[str, object]) -> bytes:
    """A header: its magic, its length and its JSON."""
    raw = json.dumps(body, sort_keys=True).encode()
    return magic + _LENGTH.pack(len(raw)) + raw


def piece(data: bytes) -> bytes:
    """A piece of a channel's stream, framed."""
    return _LENGTH.pack(len(data)) + data


def end_of_stream(n_bits: int) -> bytes:
    """A channel's end: a piece of length 0 and the stream's length in bits."""
    return _LENGTH.pack(0) + _BITS.pack(n_bits)


def read_exact(sock: socket.socket, n: int) -> bytes:
    """``n`` bytes, or fewer if the peer closes first."""
    chunks, got = [], 0
    while got < n:
        b = sock.recv(min(n - got, 1 << 20))
        if not b:
            break
        chunks.append(b)
        got += len(b)
    return b"".join(chunks)


def read_header(sock: socket.socket) -> tuple[bytes, dict | None, bytes]:
    """What a connection starts with: ``(PASS | CHANNEL | MULTIPLEX, its JSON, b"")``, or ``(b"",
    None, the first bytes)`` for a raw stream."""
    head = read_exact(sock, 8)
    if head not in (PASS, CHANNEL, MULTIPLEX):
        return b"", None, head
    raw = read_exact(sock, 4)
    if len(raw) < 4:
        raise WireError(f"a {head.decode()} header cut short")
    (n,) = _LENGTH.unpack(raw)
    if n > MAX_HEADER_BYTES:
        raise WireError(f"a {head.decode()} header of {n} bytes: not one")
    body = read_exact(sock, n)
    if len(body) < n:
        raise WireError(f"a {head.decode()} header cut short ({len(body)} of {n} bytes)")
    try:
        return head, json.loads(body), b""
    except json.JSONDecodeError as exc:
        raise WireError(f"a {head.decode()} header that is not JSON: {exc}") from None


def read_piece(sock: socket.socket) -> tuple[bytes | None, int | None]:
    """The next piece of a framed channel: ``(bytes, None)``; at its end ``(None, n_bits)``;
    ``(None, None)`` when the connection closed before the end (a cut stream)."""
    raw = read_exact(sock, 4)
    if len(raw) < 4:
        return None, None
    (n,) = _LENGTH.unpack(raw)
    if n == 0:
        bits = read_exact(sock, 8)
        return (None, _BITS.unpack(bits)[0]) if len(bits) == 8 else (None, None)
    data = read_exact(sock, n)
    return (data, None) if data else (None, None)


def read_channel_piece(sock: socket.socket) -> tuple[int | None, bytes | None, int | None]:
    """The next piece of a multiplexed connection: ``(channel, bytes, None)``; at a
    channel's end ``(channel, None, n_bits)``; ``(None, None, None)`` when the connection
    closed (the channels not ended are cut there)."""
    index = read_exact(sock, 1)
    if not index:
        return None, None, None
    data, n_bits = read_piece(sock)
    if data is None and n_bits is None:
        return None, None, None
    return index[0], data, n_bits
