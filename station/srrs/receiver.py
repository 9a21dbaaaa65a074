"""The receiver: a recorded pass → accounted frames → packets → image lines and aux data.

Every CADU found in the stream gets exactly one status (:data:`STATUS_NAMES`):

``ok``            delivered, no symbol corrected
``corrected``     delivered after correcting n symbols (n is kept per frame)
``uncorrectable`` Reed–Solomon failed, or the CRC or the header did not check after it
``duplicate``     a frame count already delivered on that channel (tape replay overlap)
``out_of_order``  delivered, but after a later frame of its channel (put back in place)
``fill``          an idle frame of VC 63 (its session status is read)
``false_sync``    an unconfirmed marker whose block did not decode: noise, not a frame

Per virtual channel, frame counts are unwrapped (24 bits) and the frames expected are
those from the session's first count (reported by any fill frame) to the last one sent
(reported by a fill frame flagged *closed*, or else the last one received): **sent =
delivered + lost**, and the report says whether the head and the tail were known.

Packets are then cut from the delivered frames of each data channel in frame-count order:
a run of consecutive frames is one stretch of packet zone; a packet that runs into a gap is
dropped whole, and parsing resumes at the first header pointer of the next frame after the
gap. Image packets are decoded (DPCM for P) into their place; a segment of a line is valid
only if its packet arrived complete. Nothing lost is ever presented as data.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numba
import numpy as np
from numpy.lib.recfunctions import repack_fields
from numpy.typing import NDArray
from scipy.optimize import linprog

from levels.readers.l0 import pixel_mask
from station.errors import StationError
from station.srrs.frames import decode_cadus, find_cadus
from station.telemetry import dpcm
from station.telemetry import format as tf

__all__ = [
    "STATUS_NAMES",
    "ChannelAccount",
    "DecodedPass",
    "ReceiverError",
    "receive",
]

STATUS_NAMES = ("ok", "corrected", "uncorrectable", "duplicate", "out_of_order", "fill",
                "false_sync")
OK, CORRECTED, UNCORRECTABLE, DUPLICATE, OUT_OF_ORDER, FILL, FALSE_SYNC = range(7)
_HALF = tf.VC_FRAME_COUNT_MODULUS // 2
_MAX_LINES = 10**6  # sanity limits on what the aux data may announce
_MAX_DETECTORS = 12000
_MAX_BANDS = 4
_MAX_TIME_MS = 2**44  # 557 years after 1950
ZONE_BYTES = tf.ZONE_BYTES  # plain ints for the compiled kernels
ENCODING_RAW8 = tf.ENCODING_RAW8


class ReceiverError(StationError, ValueError):
    """The stream holds no usable pass (no frame, or no auxiliary data to place lines)."""


@dataclass(frozen=True)
class ChannelAccount:
    """Frame accounting of one virtual channel (counts of frames)."""

    vc: int
    sent: int
    delivered: int
    lost: int
    gaps: int
    duplicates: int
    out_of_order: int
    corrected: int
    symbols_corrected: int
    head_known: bool
    tail_known: bool
    first_count: int  # unwrapped count of the first expected frame

    def as_dict(self) -> dict:
        return dict(self.__dict__)


@dataclass(frozen=True, eq=False)
class DecodedPass:
    """What the receiver made of a pass: per-frame log, accounting, lines and aux."""

    frame_bit_offset: NDArray[np.int64]
    frame_status: NDArray[np.int64]
    frame_vc: NDArray[np.int64]
    frame_count: NDArray[np.int64]  # unwrapped; −1 where unknown
    frame_symbols_corrected: NDArray[np.int64]
    accounts: dict[int, ChannelAccount]
    bits_in: int
    bits_searched: int
    sync_losses: int
    hrv: int
    mode: str
    mirror_step: int
    twin: bool
    first_line_counter: int
    images: tuple[NDArray[np.uint8], ...]  # per band, (lines, detectors)
    valid: tuple[NDArray[np.bool_], ...]  # per band, (lines, segments)
    segment_first_detector: NDArray[np.int64]
    line_counter: NDArray[np.int64]
    aux: NDArray
    epoch_utc: np.datetime64  # 00:00 UTC of the day of the first time code
    line_t_s: NDArray[np.float64]  # fitted line times, s since epoch_utc
    line_period_s: float
    line_clock_uncertainty_s: float
    packets: dict[str, int] = field(default_factory=dict)

    @property
    def aux_t_s(self) -> NDArray[np.float64]:
        """Time codes of the aux records, s since ``epoch_utc`` (1 ms resolution)."""
        day0 = (self.epoch_utc - tf.CNES_EPOCH).astype("timedelta64[ms]").astype(np.int64)
        return (self.aux["time_ms"].astype(np.int64) - day0) / 1e3

    @property
    def gyro_rates_rad_per_s(self) -> NDArray[np.float64]:
        lsb = self.aux["gyro_lsb_prad_per_s"].astype(np.float64)[:, None] * 1e-12
        return self.aux["gyro_counts"].astype(np.float64) * lsb

    def pixel_valid(self, band: int) -> NDArray[np.bool_]:
        """The segment mask of a band expanded to every pixel (lines, detectors)."""
        return pixel_mask(self.valid[band], self.segment_first_detector,
                          self.images[band].shape[1])

    @property
    def status_counts(self) -> dict[str, int]:
        counts = np.bincount(self.frame_status, minlength=len(STATUS_NAMES))
        return {name: int(c) for name, c in zip(STATUS_NAMES, counts, strict=True)}


def _unwrap(count: NDArray[np.int64]) -> NDArray[np.int64]:
    """Unwrap 24-bit counts in arrival order (steps taken as the shortest way round)."""
    if count.size == 0:
        return count.copy()
    step = (np.diff(count) + _HALF) % tf.VC_FRAME_COUNT_MODULUS - _HALF
    return count[0] + np.concatenate([[0], np.cumsum(step)])


def _near(value: int, reference: int) -> int:
    """The unwrapped count ≡ value (mod 2²⁴) nearest to ``reference``."""
    return reference + (value - reference + _HALF) % tf.VC_FRAME_COUNT_MODULUS - _HALF


def _status_tables(frames: NDArray[np.uint8], rows: NDArray[np.int64]) -> dict[int, dict]:
    """Session status read from good fill frames: per VC, first count, most sent, closed."""
    z0 = tf.FRAME_HEADER_BYTES
    out: dict[int, dict] = {}
    magic = np.frombuffer(tf.STATUS_MAGIC, np.uint8)
    good = rows[np.all(frames[rows, z0:z0 + 4] == magic, axis=1)]
    if good.size == 0:
        return out
    most = (tf.ZONE_BYTES - 5) // tf.STATUS_ENTRY_DTYPE.itemsize
    n_entries = np.minimum(frames[good, z0 + 4].astype(np.int64), most)
    width = tf.STATUS_ENTRY_DTYPE.itemsize
    for k in range(int(n_entries.max(initial=0))):  # a handful of channels
        has = good[n_entries > k]
        raw = np.ascontiguousarray(frames[has, z0 + 5 + k * width:z0 + 5 + (k + 1) * width])
        e = raw.view(tf.STATUS_ENTRY_DTYPE).ravel()
        vc = (e["vc"] & 0x3F).astype(np.int64)
        closed = (e["vc"] & 0x80) != 0
        first = tf.from_u24(e["first_count"])
        for v in np.unique(vc):
            sel = vc == v
            out[int(v)] = {"first": int(first[sel][0]), "sent": int(e["sent"][sel].max()),
                           "closed": bool(closed[sel].any())}
    return out


def _account(vc: int, rows: NDArray[np.int64], count24: NDArray[np.int64],
             corrected: NDArray[np.int64], status: NDArray[np.int64], table: dict | None,
             unwrapped: NDArray[np.int64]) -> ChannelAccount:
    """Classify a channel's good frames in arrival order and account for its frames."""
    u = _unwrap(count24[rows])
    unwrapped[rows] = u
    uniq, first_idx = np.unique(u, return_index=True)
    is_first = np.zeros(u.size, bool)
    is_first[first_idx] = True
    status[rows[~is_first]] = DUPLICATE
    running_max = np.maximum.accumulate(np.where(is_first, u, np.iinfo(np.int64).min))
    late = is_first & (u < np.concatenate([[np.iinfo(np.int64).min], running_max[:-1]]))
    status[rows[late]] = OUT_OF_ORDER
    n_corr = corrected[rows]
    delivered = uniq.size
    head_known = tail_known = False
    lo, hi = int(uniq[0]), int(uniq[-1])
    if table is not None:
        first = _near(table["first"], lo)
        if first > lo:  # the reported first cannot be after a frame received
            first -= tf.VC_FRAME_COUNT_MODULUS
        lo, head_known = first, True
        hi = max(hi, first + table["sent"] - 1)
        tail_known = table["closed"]
    expected = hi - lo + 1
    inner_gaps = int(np.count_nonzero(np.diff(uniq) > 1))
    return ChannelAccount(
        vc=vc, sent=expected, delivered=delivered, lost=expected - delivered,
        gaps=inner_gaps + int(uniq[0] > lo) + int(uniq[-1] < hi),
        duplicates=int((~is_first).sum()), out_of_order=int(late.sum()),
        corrected=int((is_first & (n_corr > 0)).sum()),
        symbols_corrected=int(n_corr[is_first].sum()),
        head_known=head_known, tail_known=tail_known, first_count=lo,
    )


@numba.njit(cache=True, nogil=True)
def _first_break(seq: NDArray[np.int64], a: int, b: int) -> int:
    """The first frame index in (a, b] that does not follow its predecessor, or −1."""
    for g in range(a + 1, b + 1):
        if seq[g] - seq[g - 1] != 1:
            return g
    return -1


@numba.njit(cache=True, nogil=True)
def _cut_packets(zone: NDArray[np.uint8], seq: NDArray[np.int64], fhp: NDArray[np.int64],
                 starts: NDArray[np.int64], lengths: NDArray[np.int64]) -> tuple[int, int]:
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
def _place_segments(zone: NDArray[np.uint8], starts: NDArray[np.int64],
                    row: NDArray[np.int64], band: NDArray[np.int64],
                    first_det: NDArray[np.int64], count: NDArray[np.int64],
                    encoding: NDArray[np.int64], value: NDArray[np.uint8],
                    payload: int, images: NDArray[np.uint8]) -> None:
    for k in range(starts.size):
        out = images[band[k], row[k], first_det[k]:first_det[k] + count[k]]
        p = starts[k] + payload
        if encoding[k] == ENCODING_RAW8:
            out[:] = zone[p:p + count[k]]
        else:
            dpcm.decode_one(zone, p, count[k], value, out)


def _packets_of(frames: NDArray[np.uint8], rows: NDArray[np.int64],
                unwrapped: NDArray[np.int64]) -> tuple[NDArray[np.uint8], NDArray[np.int64],
                                                       NDArray[np.int64], int]:
    """Complete packets of one channel: the zone bytes, packet starts and lengths, drops."""
    u = unwrapped[rows]
    uniq, idx = np.unique(u, return_index=True)  # sorted, one copy each
    sel = rows[idx]
    h0 = tf.FRAME_HEADER_BYTES
    zone = np.ascontiguousarray(frames[sel, h0:h0 + tf.ZONE_BYTES]).ravel()
    fhp = ((frames[sel, 6].astype(np.int64) << 8) | frames[sel, 7]) & 0x7FF
    cap = zone.size // 7 + 1
    starts = np.zeros(cap, np.int64)
    lengths = np.zeros(cap, np.int64)
    n, dropped = _cut_packets(zone, uniq, fhp, starts, lengths)
    return zone, starts[:n], lengths[:n], int(dropped)


def receive(stream: NDArray[np.uint8], n_bits: int | None = None,
            search_tolerance: int = 3, lock_tolerance: int = 8) -> DecodedPass:
    """Decode a recorded pass (module docstring). Raises :class:`ReceiverError` only when
    nothing usable is in it; every defect short of that is counted, not raised."""
    stream = np.ascontiguousarray(np.frombuffer(stream, np.uint8)
                                  if isinstance(stream, bytes | bytearray) else stream, np.uint8)
    n_bits = stream.size * 8 if n_bits is None else int(n_bits)
    offsets, confirmed, searched, losses = find_cadus(stream, n_bits, search_tolerance,
                                                       lock_tolerance)
    frames, corrected, rs_ok, crc_ok = decode_cadus(stream, offsets)
    head = np.ascontiguousarray(frames[:, :6])
    word = (head[:, 0].astype(np.int64) << 8) | head[:, 1]
    version, scid, vc = word >> 14, (word >> 6) & 0xFF, word & 0x3F
    count24 = tf.from_u24(head[:, 2:5])
    good = rs_ok & crc_ok & (version == 1) & (scid == tf.SPACECRAFT_ID)
    n_corr = np.where(corrected < 0, 0, corrected).sum(axis=1)
    status = np.where(good, np.where(n_corr > 0, CORRECTED, OK), UNCORRECTABLE)
    status[~good & ~confirmed] = FALSE_SYNC
    fill = good & (vc == tf.VC_FILL)
    tables = _status_tables(frames, np.flatnonzero(fill))
    unwrapped = np.full(offsets.size, -1, np.int64)
    accounts = {}
    for v in np.unique(vc[good]):  # a few channels
        rows = np.flatnonzero(good & (vc == v))
        accounts[int(v)] = _account(int(v), rows, count24, n_corr, status,
                                    tables.get(int(v)), unwrapped)
    for v, t in tables.items():  # channels that sent frames none of which arrived
        if v not in accounts:
            accounts[v] = ChannelAccount(v, t["sent"], 0, t["sent"], 1, 0, 0, 0, 0, True,
                                         t["closed"], t["first"])
    status[fill & (status != DUPLICATE)] = FILL

    data_vcs = [v for v in accounts if v != tf.VC_FILL and np.any(good & (vc == v))]
    if not data_vcs:
        raise ReceiverError("no data frame could be decoded in the stream "
                            f"({offsets.size} markers found in {n_bits} bits)")
    data_vc = data_vcs[0]
    rows = np.flatnonzero(good & (vc == data_vc))
    zone, starts, lengths, dropped = _packets_of(frames, rows, unwrapped)
    decoded = _lines_from_packets(zone, starts, lengths)
    decoded["packets"]["dropped_at_gaps"] = dropped
    return DecodedPass(
        frame_bit_offset=offsets, frame_status=status, frame_vc=np.where(good, vc, -1),
        frame_count=unwrapped, frame_symbols_corrected=n_corr, accounts=accounts,
        bits_in=n_bits, bits_searched=searched, sync_losses=losses, **decoded,
    )


def _lines_from_packets(zone: NDArray[np.uint8], starts: NDArray[np.int64],
                        lengths: NDArray[np.int64]) -> dict:
    """Sort packets by APID, read the aux records, place the image segments."""
    pid = ((zone[starts].astype(np.int64) << 8) | zone[starts + 1]) & 0x7FF
    stats = {"complete": int(starts.size), "idle": int((pid == tf.APID_IDLE).sum())}
    aux_size = 6 + tf.AUX_DTYPE.itemsize
    is_aux = ((pid & ~0xF) == tf.APID_AUX) & (lengths == aux_size)
    if not is_aux.any():
        raise ReceiverError("no auxiliary packet was received: lines cannot be placed")
    idx = starts[is_aux][:, None] + 6 + np.arange(tf.AUX_DTYPE.itemsize)
    aux = np.ascontiguousarray(zone[idx]).view(tf.AUX_DTYPE).ravel()
    # The strip's shape is what most aux records say; a record that disagrees is rejected.
    keys = ["first_line", "n_lines", "n_detectors", "n_bands", "mode", "hrv", "mirror_step"]
    shape = repack_fields(aux[keys])
    _kinds, first, votes = np.unique(shape, return_index=True, return_counts=True)
    ref = aux[first[np.argmax(votes)]]
    agree = np.all([aux[k] == ref[k] for k in keys], axis=0) & _plausible_times(aux)
    stats["aux"] = int(agree.sum())
    stats["aux_rejected"] = int((~agree).sum())
    aux = np.sort(aux[agree], order="time_ms")
    first_line, n_lines = int(ref["first_line"]), int(ref["n_lines"])
    n_det, n_bands, hrv = int(ref["n_detectors"]), int(ref["n_bands"]), int(ref["hrv"])
    seg_first = np.arange(0, n_det, tf.SEGMENT_DETECTORS)

    if not (1 <= n_lines <= _MAX_LINES and 1 <= n_det <= _MAX_DETECTORS
            and 1 <= n_bands <= _MAX_BANDS):
        raise ReceiverError(f"the auxiliary data describe an impossible strip: {n_lines} lines "
                            f"of {n_bands} bands × {n_det} detectors")
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
    sane = ((row >= 0) & (row < n_lines) & (band < n_bands) & (count >= 1)
            & (first_det % tf.SEGMENT_DETECTORS == 0) & (first_det + count <= n_det)
            & (count == np.minimum(tf.SEGMENT_DETECTORS, n_det - first_det))
            & ((enc == tf.ENCODING_RAW8) | (enc == tf.ENCODING_DPCM6))
            & (lengths[is_img] == 6 + hdr_size + need))
    stats["image"] = int(sane.sum())
    stats["image_rejected"] = int((~sane).sum())
    images = np.zeros((n_bands, n_lines, n_det), np.uint8)
    valid = np.zeros((n_bands, n_lines, seg_first.size), bool)
    _code, value = dpcm.reconstruction_table()
    _place_segments(zone, starts[is_img][sane], row[sane], band[sane], first_det[sane],
                    count[sane], enc[sane], value, 6 + hdr_size, images)
    valid[band[sane], row[sane], seg[sane]] = True
    stats["other"] = int(starts.size - stats["idle"] - is_aux.sum() - is_img.sum())
    epoch_utc, line_t, period, rms = _line_times(aux, first_line, n_lines)
    return {
        "epoch_utc": epoch_utc, "line_t_s": line_t, "line_period_s": period,
        "line_clock_uncertainty_s": rms,
        "hrv": hrv, "mode": "P" if int(ref["mode"]) == 0 else "XS",
        "mirror_step": int(ref["mirror_step"]), "twin": bool(int(ref["status"]) & 2),
        "first_line_counter": first_line, "images": tuple(images), "valid": tuple(valid),
        "segment_first_detector": seg_first,
        "line_counter": first_line + np.arange(n_lines), "aux": aux, "packets": stats,
    }


def _plausible_times(aux: NDArray) -> NDArray[np.bool_]:
    """Time codes within the counter's range (after 1950, before ~2400) and a line time
    within a minute of its record's time: anything else is a damaged record."""
    t = aux["time_ms"].astype(np.uint64)
    lt = aux["line_time_ms"].astype(np.uint64)
    ok = (t < _MAX_TIME_MS) & (lt < _MAX_TIME_MS)
    gap = np.abs(t.astype(np.float64) - lt.astype(np.float64))
    return ok & (gap <= 60_000.0)


def _on_the_clock(aux: NDArray, first_line: int) -> NDArray[np.bool_]:
    """Records consistent with one line clock: a robust line (median of the slopes between
    records half the span apart, then median intercept) and a 2 ms tolerance around it
    (twice the truncation), so that a record damaged on board cannot drag the fit."""
    x = aux["line"].astype(np.float64) - first_line
    y = aux["line_time_ms"].astype(np.float64)
    y = y - y.min()
    order = np.argsort(x, kind="stable")
    half = max(aux.size // 2, 1)  # pair each record with one half the span away
    dx = x[order][half:] - x[order][:-half]
    dy = y[order][half:] - y[order][:-half]
    if np.count_nonzero(dx > 0) == 0:
        return np.ones(aux.size, bool)
    slope = np.median(dy[dx > 0] / dx[dx > 0])
    icept = np.median(y - slope * x)
    return np.abs(y - icept - slope * x) <= 2.0


def _line_times(aux: NDArray, first_line: int, n_lines: int) -> tuple[
        np.datetime64, NDArray[np.float64], float, float]:
    """Line times from the (line counter, time code) pairs of the aux records.

    A time code is latched, truncated to the millisecond, at the start of its line: the
    true start t = a + P·x (x the line counter from the strip's first line) satisfies
    T ≤ t < T + 1 ms for every record. Those constraints bound (a, P) to a small polygon;
    its extent in a and in P is found by four linear programmes, and the clock is the
    middle of it (Westin's sub-millisecond recovery). A least-squares line through the
    codes + 0.5 ms would be biased by the deterministic pattern of the truncation (the
    codes sample t mod 1 ms on a coarse lattice): up to 0.1 ms on a full scene. If the
    constraints cannot all hold (a record damaged on board), the least-squares line is
    used. Returns the epoch, the line times, the period and half the feasible range of the
    time of the middle line (the clock's uncertainty, s), or the least-squares residual
    RMS when it fell back.
    """
    aux = aux[_on_the_clock(aux, first_line)]
    ms = aux["line_time_ms"].astype(np.int64)
    day_ms = 86_400_000
    day0 = int(aux["time_ms"].astype(np.int64).min()) // day_ms * day_ms
    epoch_utc = tf.CNES_EPOCH + np.timedelta64(day0, "ms")
    x = aux["line"].astype(np.float64) - first_line
    if np.unique(x).size < 2:
        raise ReceiverError("fewer than two auxiliary records: the line clock is unknown")
    x_mid = (n_lines - 1) / 2.0
    xc = x - x_mid
    y_ms = (ms - ms.min()).astype(np.float64)
    slope, icept = np.polyfit(xc, y_ms + 0.5, 1)
    a_ms, p_ms, spread = icept, slope, float(np.sqrt(np.mean(
        (y_ms + 0.5 - icept - slope * xc) ** 2))) * 1e-3
    # T <= a + P x < T + 1  as  A z <= b, z = (a, P)
    a_ub = np.concatenate([np.stack([-np.ones_like(xc), -xc], 1),
                           np.stack([np.ones_like(xc), xc], 1)])
    b_ub = np.concatenate([-y_ms, y_ms + 1.0 - 1e-9])
    ext = []
    for c in ([1, 0], [-1, 0], [0, 1], [0, -1]):
        r = linprog(c, A_ub=a_ub, b_ub=b_ub, bounds=[(None, None), (None, None)],
                    method="highs")
        if r.status != 0:
            break
        ext.append(r.x)
    if len(ext) == 4:
        a_ms = (ext[0][0] + ext[1][0]) / 2
        p_ms = (ext[2][1] + ext[3][1]) / 2
        spread = (ext[1][0] - ext[0][0]) / 2 * 1e-3
    t0_s = (ms.min() - day0) / 1e3 + a_ms * 1e-3
    t = t0_s + p_ms * 1e-3 * (np.arange(n_lines) - x_mid)
    return epoch_utc, t, float(p_ms * 1e-3), spread
