"""Packets from the delivered frames of a channel, and image lines from the packets.

Packets are cut in frame-count order: a run of consecutive frames is one stretch of packet
zone; a packet that runs into a gap is dropped whole, and parsing resumes at the first
header pointer of the next frame after the gap. Image packets are decoded (DPCM for P) into
their place; a segment of a line is valid only if its packet arrived complete. The aux
records give the strip's shape and, through :mod:`station.srrs.clock`, the line times.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np
from numpy.lib.recfunctions import repack_fields
from numpy.typing import NDArray

from station.srrs.clock import line_clock, plausible_times
from station.srrs.errors import ReceiverError
from station.telemetry import dpcm
from station.telemetry import format as tf

__all__ = [
    "Segments",
    "Strip",
    "aux_records",
    "cut_packets",
    "image_segments",
    "is_image_candidate",
    "packet_ids",
    "place_segments",
    "strip_facts",
]

_MAX_LINES = 10**6  # sanity limits on what the aux data may announce
_MAX_DETECTORS = 12000
_MAX_BANDS = 4
ZONE_BYTES = tf.ZONE_BYTES  # plain ints for the compiled kernels
ENCODING_RAW8 = tf.ENCODING_RAW8


@numba.njit(cache=True, nogil=True)
def _first_break(seq: NDArray[np.int64], a: int, b: int) -> int:
    """The first frame index in (a, b] that does not follow its predecessor, or −1."""
    for g in range(a + 1, b + 1):
        if seq[g] - seq[g - 1] != 1:
            return g
    return -1


@numba.njit(cache=True, nogil=True)
def _cut_packets(
    zone: NDArray[np.uint8],
    seq: NDArray[np.int64],
    fhp: NDArray[np.int64],
    starts: NDArray[np.int64],
    lengths: NDArray[np.int64],
    pos: int = -1,
    anchor: int = 0,
    f: int = 0,
    final: bool = True,
) -> tuple[int, int, int, int, int]:
    """Find the complete packets in the packet zones of a channel's frames, laid end to end
    in frame-count order (``seq`` strictly increasing, possibly with gaps).

    A packet is complete when every frame from the one holding the end of the previous
    packet (or, after a resync, the one whose first header pointer led to it) to the one
    holding its own last byte is present. The search starts from its state (``pos``: the
    next header's position in the laid-out zones, −1 to resync at frame ``f``; ``anchor``:
    the frame from which contiguity must hold) and, unless ``final``, stops without a
    verdict at a packet that runs past the last frame given (more frames may come).
    Returns (packets found, packets dropped, and the state where it stopped).
    """
    zb = ZONE_BYTES
    n = seq.size
    found = 0
    dropped = 0
    while True:
        if pos < 0:
            while f < n and fhp[f] >= zb:
                f += 1
            if f >= n:
                break
            pos = f * zb + fhp[f]
            anchor = f
        if pos + 6 > n * zb:
            break  # the last header is cut by the end of what was received
        fh = (pos + 5) // zb
        g = _first_break(seq, anchor, fh)
        if g < 0:
            length = ((np.int64(zone[pos + 4]) << 8) | zone[pos + 5]) + 7
            fe = (pos + length - 1) // zb
            if fe >= n:
                if final:
                    dropped += 1  # runs past the last frame received
                break
            g = _first_break(seq, anchor, fe)
            if g < 0:
                starts[found] = pos
                lengths[found] = length
                found += 1
                pos += length
                anchor = (pos - 1) // zb
                continue
        dropped += 1  # a frame inside the packet (or before it) is missing
        pos = -1
        f = g
    return found, dropped, pos, anchor, f


@numba.njit(cache=True, nogil=True)
def _place_segments(
    zone: NDArray[np.uint8],
    starts: NDArray[np.int64],
    row: NDArray[np.int64],
    band: NDArray[np.int64],
    first_det: NDArray[np.int64],
    count: NDArray[np.int64],
    encoding: NDArray[np.int64],
    value: NDArray[np.uint8],
    payload: int,
    images: NDArray[np.uint8],
) -> None:
    for k in range(starts.size):
        out = images[band[k], row[k], first_det[k] : first_det[k] + count[k]]
        p = starts[k] + payload
        if encoding[k] == ENCODING_RAW8:
            for j in range(count[k]):  # a loop, not a slice copy (telemetry/rs.py's note)
                out[j] = zone[p + j]
        else:
            dpcm.decode_one(zone, p, count[k], value, out)


#: An aux packet's bytes: its header and the record.
AUX_PACKET_BYTES = 6 + tf.AUX_DTYPE.itemsize
IMAGE_HEADER_BYTES = tf.IMAGE_HEADER_DTYPE.itemsize
_SHAPE_KEYS = ["first_line", "n_lines", "n_detectors", "n_bands", "mode", "hrv", "mirror_step"]


def cut_packets(
    zone: NDArray[np.uint8],
    seq: NDArray[np.int64],
    fhp: NDArray[np.int64],
    state: tuple[int, int, int] = (-1, 0, 0),
    final: bool = True,
) -> tuple[NDArray[np.int64], NDArray[np.int64], int, tuple[int, int, int]]:
    """The complete packets of a channel's packet zones laid end to end in frame-count
    order (module docstring): their starts and lengths in ``zone``, the packets dropped,
    and the search's state where it stopped (``pos, anchor, frame``: what a next piece of
    the same channel resumes from; :class:`station.srrs.assembler.Assembler`)."""
    cap = zone.size // 7 + 1
    starts = np.zeros(cap, np.int64)
    lengths = np.zeros(cap, np.int64)
    n, dropped, pos, anchor, f = _cut_packets(zone, seq, fhp, starts, lengths, *state, final)
    return starts[:n], lengths[:n], int(dropped), (int(pos), int(anchor), int(f))


def packet_ids(zone: NDArray[np.uint8], starts: NDArray[np.int64]) -> NDArray[np.int64]:
    return ((zone[starts].astype(np.int64) << 8) | zone[starts + 1]) & 0x7FF


def aux_records(
    zone: NDArray[np.uint8], starts: NDArray[np.int64], lengths: NDArray[np.int64], pid: NDArray
) -> tuple[NDArray, NDArray[np.bool_]]:
    """The auxiliary records of these packets (as received), and which packets they are."""
    is_aux = ((pid & ~0xF) == tf.APID_AUX) & (lengths == AUX_PACKET_BYTES)
    idx = starts[is_aux][:, None] + 6 + np.arange(tf.AUX_DTYPE.itemsize)
    return np.ascontiguousarray(zone[idx]).view(tf.AUX_DTYPE).ravel(), is_aux


def is_image_candidate(pid: NDArray[np.int64], lengths: NDArray[np.int64]) -> NDArray[np.bool_]:
    """Packets that may be image segments of some HRV (which one the strip says)."""
    return ((pid & ~0xF) == tf.APID_IMAGE) & (lengths >= 6 + IMAGE_HEADER_BYTES + 1)


@dataclass(frozen=True, eq=False)
class Strip:
    """The strip's shape, as most auxiliary records say it (their reference record)."""

    ref: np.void

    @classmethod
    def of(cls, aux: NDArray) -> Strip:
        """The shape most records agree on (a record that disagrees is outvoted)."""
        if aux.size == 0:
            raise ReceiverError("no auxiliary packet was received: lines cannot be placed")
        shape = repack_fields(aux[_SHAPE_KEYS])
        _kinds, first, votes = np.unique(shape, return_index=True, return_counts=True)
        strip = cls(aux[first[np.argmax(votes)]])
        if not (
            1 <= strip.n_lines <= _MAX_LINES
            and 1 <= strip.n_detectors <= _MAX_DETECTORS
            and 1 <= strip.n_bands <= _MAX_BANDS
        ):
            raise ReceiverError(
                f"the auxiliary data describe an impossible strip: {strip.n_lines} lines "
                f"of {strip.n_bands} bands × {strip.n_detectors} detectors"
            )
        return strip

    def same(self, other: Strip) -> bool:
        return all(self.ref[k] == other.ref[k] for k in _SHAPE_KEYS)

    @property
    def first_line(self) -> int:
        return int(self.ref["first_line"])

    @property
    def n_lines(self) -> int:
        return int(self.ref["n_lines"])

    @property
    def n_detectors(self) -> int:
        return int(self.ref["n_detectors"])

    @property
    def n_bands(self) -> int:
        return int(self.ref["n_bands"])

    @property
    def hrv(self) -> int:
        return int(self.ref["hrv"])

    @property
    def segment_first_detector(self) -> NDArray[np.int64]:
        return np.arange(0, self.n_detectors, tf.SEGMENT_DETECTORS)

    def agreeing(self, aux: NDArray) -> NDArray[np.bool_]:
        """Records that agree with the shape and whose times are plausible."""
        ref = self.ref
        return np.all([aux[k] == ref[k] for k in _SHAPE_KEYS], axis=0) & plausible_times(aux)


@dataclass(frozen=True, eq=False)
class Segments:
    """The sane image segments of some packets (where each goes), and how many of the
    packets were the strip's image packets."""

    starts: NDArray[np.int64]
    row: NDArray[np.int64]
    band: NDArray[np.int64]
    first_detector: NDArray[np.int64]
    count: NDArray[np.int64]
    encoding: NDArray[np.int64]
    n_image: int

    @property
    def segment(self) -> NDArray[np.int64]:
        return self.first_detector // tf.SEGMENT_DETECTORS


def image_segments(
    zone: NDArray[np.uint8],
    starts: NDArray[np.int64],
    lengths: NDArray[np.int64],
    pid: NDArray[np.int64],
    strip: Strip,
) -> Segments:
    """The image packets of the strip's HRV among these, and the sane ones among them (a
    line and detectors inside the strip, a whole segment, a known encoding, the length
    that encoding needs)."""
    is_img = (pid == tf.APID_IMAGE + strip.hrv) & (lengths >= 6 + IMAGE_HEADER_BYTES + 1)
    idx = starts[is_img][:, None] + 6 + np.arange(IMAGE_HEADER_BYTES)
    hdr = np.ascontiguousarray(zone[idx]).view(tf.IMAGE_HEADER_DTYPE).ravel()
    row = hdr["line"].astype(np.int64) - strip.first_line
    first_det = hdr["first_detector"].astype(np.int64)
    count = hdr["count"].astype(np.int64)
    enc = hdr["encoding"].astype(np.int64)
    band = hdr["band"].astype(np.int64)
    need = np.where(enc == tf.ENCODING_DPCM6, dpcm.payload_bytes(count), count)
    n_det = strip.n_detectors
    sane = (
        (row >= 0)
        & (row < strip.n_lines)
        & (band < strip.n_bands)
        & (count >= 1)
        & (first_det % tf.SEGMENT_DETECTORS == 0)
        & (first_det + count <= n_det)
        & (count == np.minimum(tf.SEGMENT_DETECTORS, n_det - first_det))
        & ((enc == tf.ENCODING_RAW8) | (enc == tf.ENCODING_DPCM6))
        & (lengths[is_img] == 6 + IMAGE_HEADER_BYTES + need)
    )
    return Segments(
        starts[is_img][sane], row[sane], band[sane], first_det[sane], count[sane], enc[sane],
        int(is_img.sum()),
    )  # fmt: skip


def place_segments(
    zone: NDArray[np.uint8], seg: Segments, images: NDArray[np.uint8], row0: int = 0
) -> None:
    """Decode the segments into ``images`` (bands, lines from ``row0``, detectors)."""
    _code, value = dpcm.reconstruction_table()
    _place_segments(
        zone, seg.starts, seg.row - row0, seg.band, seg.first_detector, seg.count,
        seg.encoding, value, 6 + IMAGE_HEADER_BYTES, images,
    )  # fmt: skip


def strip_facts(strip: Strip, aux: NDArray) -> dict[str, object]:
    """What the agreeing aux records (by time) say of the strip: its line clock, mode,
    mirror step and status."""
    ref = strip.ref
    epoch_utc, line_t, period, rms = line_clock(aux, strip.first_line, strip.n_lines)
    return {
        "epoch_utc": epoch_utc,
        "line_t_s": line_t,
        "line_period_s": period,
        "line_clock_uncertainty_s": rms,
        "hrv": strip.hrv,
        "mode": "P" if int(ref["mode"]) == 0 else "XS",
        "mirror_step": int(ref["mirror_step"]),
        "twin": bool(int(ref["status"]) & 2),
        "first_line_counter": strip.first_line,
        "segment_first_detector": strip.segment_first_detector,
        "line_counter": strip.first_line + np.arange(strip.n_lines),
        "aux": aux,
    }
