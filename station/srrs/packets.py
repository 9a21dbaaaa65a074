"""Packets from the delivered frames of a channel, and image lines from the packets.

Packets are cut in frame-count order: a run of consecutive frames is one stretch of packet
zone; a packet that runs into a gap is dropped whole, and parsing resumes at the first
header pointer of the next frame after the gap. Image packets are decoded (DPCM for P) into
their place; a segment of a line is valid only if its packet arrived complete. The aux
records give the strip's shape and, through :mod:`station.srrs.clock`, the line times.
"""

from __future__ import annotations

import numba
import numpy as np
from numpy.lib.recfunctions import repack_fields
from numpy.typing import NDArray

from station.srrs.clock import line_clock, plausible_times
from station.srrs.errors import ReceiverError
from station.telemetry import dpcm
from station.telemetry import format as tf

__all__ = ["lines_from_packets", "packets_of"]

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
) -> tuple[int, int]:
    """Find the complete packets in the packet zones of a channel's frames, laid end to end
    in frame-count order (``seq`` strictly increasing, possibly with gaps).

    A packet is complete when every frame from the one holding the end of the previous
    packet (or, after a resync, the one whose first header pointer led to it) to the one
    holding its own last byte is present. Returns (packets found, packets dropped).
    """
    zb = ZONE_BYTES
    n = seq.size
    found = 0
    dropped = 0
    pos = -1  # next header position in the laid-out zones; −1: resync
    anchor = 0  # frame from which contiguity must hold
    f = 0
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
    return found, dropped


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


def packets_of(
    frames: NDArray[np.uint8], rows: NDArray[np.int64], unwrapped: NDArray[np.int64]
) -> tuple[NDArray[np.uint8], NDArray[np.int64], NDArray[np.int64], int]:
    """Complete packets of one channel: the zone bytes, packet starts and lengths, drops."""
    u = unwrapped[rows]
    uniq, idx = np.unique(u, return_index=True)  # sorted, one copy each
    sel = rows[idx]
    h0 = tf.FRAME_HEADER_BYTES
    zone = np.ascontiguousarray(frames[sel, h0 : h0 + tf.ZONE_BYTES]).ravel()
    fhp = ((frames[sel, 6].astype(np.int64) << 8) | frames[sel, 7]) & 0x7FF
    cap = zone.size // 7 + 1
    starts = np.zeros(cap, np.int64)
    lengths = np.zeros(cap, np.int64)
    n, dropped = _cut_packets(zone, uniq, fhp, starts, lengths)
    return zone, starts[:n], lengths[:n], int(dropped)


def _aux_records(
    zone: NDArray[np.uint8],
    starts: NDArray[np.int64],
    lengths: NDArray[np.int64],
    pid: NDArray[np.int64],
    stats: dict[str, int],
) -> tuple[NDArray, NDArray, NDArray[np.bool_]]:
    """The auxiliary records that agree on the strip's shape (what most of them say; a
    record that disagrees, or whose time is implausible, is rejected), by time; the
    reference record and which packets are auxiliary. Counts into ``stats``."""
    aux_size = 6 + tf.AUX_DTYPE.itemsize
    is_aux = ((pid & ~0xF) == tf.APID_AUX) & (lengths == aux_size)
    if not is_aux.any():
        raise ReceiverError("no auxiliary packet was received: lines cannot be placed")
    idx = starts[is_aux][:, None] + 6 + np.arange(tf.AUX_DTYPE.itemsize)
    aux = np.ascontiguousarray(zone[idx]).view(tf.AUX_DTYPE).ravel()
    keys = ["first_line", "n_lines", "n_detectors", "n_bands", "mode", "hrv", "mirror_step"]
    shape = repack_fields(aux[keys])
    _kinds, first, votes = np.unique(shape, return_index=True, return_counts=True)
    ref = aux[first[np.argmax(votes)]]
    agree = np.all([aux[k] == ref[k] for k in keys], axis=0) & plausible_times(aux)
    stats["aux"] = int(agree.sum())
    stats["aux_rejected"] = int((~agree).sum())
    aux = np.sort(aux[agree], order="time_ms")
    return aux, ref, is_aux


def lines_from_packets(
    zone: NDArray[np.uint8], starts: NDArray[np.int64], lengths: NDArray[np.int64]
) -> dict:
    """Sort packets by APID, read the aux records, place the image segments."""
    pid = ((zone[starts].astype(np.int64) << 8) | zone[starts + 1]) & 0x7FF
    stats = {"complete": int(starts.size), "idle": int((pid == tf.APID_IDLE).sum())}
    aux, ref, is_aux = _aux_records(zone, starts, lengths, pid, stats)
    first_line, n_lines = int(ref["first_line"]), int(ref["n_lines"])
    n_det, n_bands, hrv = int(ref["n_detectors"]), int(ref["n_bands"]), int(ref["hrv"])
    seg_first = np.arange(0, n_det, tf.SEGMENT_DETECTORS)

    if not (
        1 <= n_lines <= _MAX_LINES and 1 <= n_det <= _MAX_DETECTORS and 1 <= n_bands <= _MAX_BANDS
    ):
        raise ReceiverError(
            f"the auxiliary data describe an impossible strip: {n_lines} lines "
            f"of {n_bands} bands × {n_det} detectors"
        )
    hdr_size = tf.IMAGE_HEADER_DTYPE.itemsize
    is_img = (pid == tf.APID_IMAGE + hrv) & (lengths >= 6 + hdr_size + 1)
    idx = starts[is_img][:, None] + 6 + np.arange(hdr_size)
    hdr = np.ascontiguousarray(zone[idx]).view(tf.IMAGE_HEADER_DTYPE).ravel()
    row = hdr["line"].astype(np.int64) - first_line
    first_det = hdr["first_detector"].astype(np.int64)
    count = hdr["count"].astype(np.int64)
    enc = hdr["encoding"].astype(np.int64)
    band = hdr["band"].astype(np.int64)
    need = np.where(enc == tf.ENCODING_DPCM6, dpcm.payload_bytes(count), count)
    seg = first_det // tf.SEGMENT_DETECTORS
    sane = (
        (row >= 0)
        & (row < n_lines)
        & (band < n_bands)
        & (count >= 1)
        & (first_det % tf.SEGMENT_DETECTORS == 0)
        & (first_det + count <= n_det)
        & (count == np.minimum(tf.SEGMENT_DETECTORS, n_det - first_det))
        & ((enc == tf.ENCODING_RAW8) | (enc == tf.ENCODING_DPCM6))
        & (lengths[is_img] == 6 + hdr_size + need)
    )
    stats["image"] = int(sane.sum())
    stats["image_rejected"] = int((~sane).sum())
    images = np.zeros((n_bands, n_lines, n_det), np.uint8)
    valid = np.zeros((n_bands, n_lines, seg_first.size), bool)
    _code, value = dpcm.reconstruction_table()
    _place_segments(
        zone,
        starts[is_img][sane],
        row[sane],
        band[sane],
        first_det[sane],
        count[sane],
        enc[sane],
        value,
        6 + hdr_size,
        images,
    )
    valid[band[sane], row[sane], seg[sane]] = True
    stats["other"] = int(starts.size - stats["idle"] - is_aux.sum() - is_img.sum())
    epoch_utc, line_t, period, rms = line_clock(aux, first_line, n_lines)
    return {
        "epoch_utc": epoch_utc,
        "line_t_s": line_t,
        "line_period_s": period,
        "line_clock_uncertainty_s": rms,
        "hrv": hrv,
        "mode": "P" if int(ref["mode"]) == 0 else "XS",
        "mirror_step": int(ref["mirror_step"]),
        "twin": bool(int(ref["status"]) & 2),
        "first_line_counter": first_line,
        "images": tuple(images),
        "valid": tuple(valid),
        "segment_first_detector": seg_first,
        "line_counter": first_line + np.arange(n_lines),
        "aux": aux,
        "packets": stats,
    }
