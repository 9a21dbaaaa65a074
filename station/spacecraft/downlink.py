"""The sender on board: raw lines and auxiliary data → packets → transfer frames → CADUs.

What is sent (byte tables in ``docs/telemetry.md``)
    * one image packet per band, line and segment of up to 1500 detectors: raw 8-bit counts
      in XS, closed-loop DPCM at 6 bits per pixel in P (:mod:`station.telemetry.dpcm`);
    * one auxiliary packet per gyro sample (8 Hz): the time code to 1 ms, the line counter
      of the line starting next with the time code latched at its start, gyro counts,
      mirror step, mode, status and the planned strip;
    * packets are laid end to end in the packet zones of the HRV's virtual channel, in the
      order they become available (a line's packets when the line is complete); a frame
      leaves as soon as it is full and a slot is free on the 25 Mbit/s link; slots with no
      full frame carry a fill frame on VC 63, whose data field reports, for every virtual
      channel, the count of its first frame of the session and how many it has sent
      (so that the station can count frames lost before its first or after its last).

The line counter runs continuously; line ``i`` of the strip carries
``first_line_counter + i``. The truth kept beside the bytes (:class:`Transmission`) says
which frames each image packet occupies, and what the ground should decode.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from station.scenario import DownlinkConfig
from station.spacecraft.emulator import Acquisition
from station.telemetry import dpcm
from station.telemetry import format as tf
from station.telemetry.crc import crc16_rows
from station.telemetry.randomiser import pn_sequence
from station.telemetry.rs import encode_block

__all__ = ["Transmission", "frames_to_cadus", "transmit"]

_IDLE_MIN_BYTES = 7  # an idle packet: its 6-byte header and at least one byte


@dataclass(frozen=True, eq=False)
class Transmission:
    """The CADUs of one session, in the order sent, and the truth about them.

    Per slot (n,): ``slot_t_s`` (start of the CADU on the link, s since the acquisition's
    epoch), ``vc``, ``count`` (24-bit frame count). Per image packet (m,): ``packet_row``
    (line of the strip), ``packet_band``, ``packet_segment``, ``packet_first_frame`` and
    ``packet_last_frame`` (indices among the data channel's frames, 0-based in the
    session). ``ground_bands`` are the images as the ground must decode them (the DPCM
    reconstruction in P, the raw counts in XS). ``data_vc`` is the HRV's channel;
    ``first_count`` and ``sent`` per VC give the accounting truth.
    """

    cadus: NDArray[np.uint8]
    slot_t_s: NDArray[np.float64]
    vc: NDArray[np.int64]
    count: NDArray[np.int64]
    data_vc: int
    first_count: dict[int, int]
    sent: dict[int, int]
    first_line_counter: int
    segment_first_detector: NDArray[np.int64]
    packet_row: NDArray[np.int64]
    packet_band: NDArray[np.int64]
    packet_segment: NDArray[np.int64]
    packet_first_frame: NDArray[np.int64]
    packet_last_frame: NDArray[np.int64]
    ground_bands: tuple[NDArray[np.uint8], ...]
    aux: NDArray
    bit_rate_bit_per_s: float

    @property
    def n_bytes(self) -> int:
        return int(self.cadus.size)


def _segments(n_columns: int) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    first = np.arange(0, n_columns, tf.SEGMENT_DETECTORS)
    return first, np.minimum(tf.SEGMENT_DETECTORS, n_columns - first)


def _packets(apid: int, secondary: NDArray, payload: NDArray[np.uint8]) -> NDArray[np.uint8]:
    """Whole packets (m, 6 + s + p) from secondary headers (m,) and payloads (m, p);
    sequence counts are filled in later, in sending order."""
    m = payload.shape[0]
    sec = secondary.view(np.uint8).reshape(m, -1)
    head = np.zeros(m, tf.PACKET_HEADER_DTYPE)
    head["id"] = 0x0800 | apid  # version 0, type 0, secondary header flag 1
    head["length"] = sec.shape[1] + payload.shape[1] - 1
    return np.concatenate([head.view(np.uint8).reshape(m, 6), sec, payload], axis=1)


def _image_packets(acq: Acquisition, first_line: int) -> tuple[list, tuple, NDArray]:
    """Packet groups (bytes, time, row, band, segment) of every band, line and segment."""
    hrv = acq.hrv
    n_lines = acq.line_times_s.size
    seg_first, seg_count = _segments(hrv.n_columns)
    ready_t = acq.line_times_s + hrv.line_period_s  # a line leaves once complete
    groups, ground = [], []
    for b, band in enumerate(acq.bands):
        counts = band.counts
        decoded = np.empty_like(counts)
        for s, (c0, nc) in enumerate(zip(seg_first, seg_count, strict=True)):
            seg = np.ascontiguousarray(counts[:, c0 : c0 + nc])
            if hrv.mode == "P":
                payload, recon = dpcm.encode_segments(seg)
                encoding = tf.ENCODING_DPCM6
            else:
                payload, recon, encoding = seg, seg, tf.ENCODING_RAW8
            decoded[:, c0 : c0 + nc] = recon
            sec = np.zeros(n_lines, tf.IMAGE_HEADER_DTYPE)
            sec["line"] = first_line + np.arange(n_lines)
            sec["band"] = b
            sec["encoding"] = encoding
            sec["first_detector"] = c0
            sec["count"] = nc
            rows = np.arange(n_lines)
            groups.append(
                (
                    _packets(tf.APID_IMAGE + hrv.number, sec, payload),
                    ready_t,
                    rows,
                    np.full(n_lines, b),
                    np.full(n_lines, s),
                )
            )
        ground.append(decoded)
    return groups, tuple(ground), seg_first


def _aux_records(acq: Acquisition, first_line: int) -> NDArray:
    hrv, gyros = acq.hrv, acq.gyros
    t0, period = float(acq.line_times_s[0]), hrv.line_period_s
    t = gyros.t_s
    k = np.ceil((t - t0) / period - 1e-9).astype(np.int64)  # the next line to start
    lsb = acq.scenario.attitude.gyro_lsb_rad_per_s or 1e-9  # unquantised: 1 nrad/s counts
    rec = np.zeros(t.size, tf.AUX_DTYPE)
    epoch = acq.epoch.t0_utc
    rec["time_ms"] = tf.ms_since_cnes_epoch(epoch, t)
    rec["line"] = first_line + k
    rec["line_time_ms"] = tf.ms_since_cnes_epoch(epoch, t0 + k * period)
    rec["gyro_counts"] = np.round(gyros.rates_rad_per_s / lsb).astype(np.int64)
    rec["gyro_lsb_prad_per_s"] = round(lsb * 1e12)
    rec["mirror_step"] = hrv.mirror_step
    rec["mode"] = 0 if hrv.mode == "P" else 1
    rec["hrv"] = hrv.number
    imaging = (k >= 0) & (k < acq.line_times_s.size)
    rec["status"] = imaging.astype(np.uint8) | (np.uint8(2) if hrv.twin else np.uint8(0))
    rec["first_line"] = first_line
    rec["n_lines"] = acq.line_times_s.size
    rec["n_detectors"] = hrv.n_columns
    rec["n_bands"] = len(acq.bands)
    return rec


def _zone_stream(
    groups: list,
) -> tuple[NDArray[np.uint8], NDArray[np.int64], NDArray[np.float64], NDArray[np.int64], int]:
    """Lay the packets of all groups end to end in the order they become available.

    Returns the packet zone bytes (padded to whole frames with an idle packet), each
    packet's start offset and time, the sending order, and where the idle packet starts.
    """
    sizes = np.concatenate([np.full(g[1].size, g[0].shape[1]) for g in groups])
    times = np.concatenate([g[1] for g in groups])
    gid = np.concatenate([np.full(g[1].size, i) for i, g in enumerate(groups)])
    order = np.lexsort((gid, times))  # by time, then group (stable within a group)
    start = np.zeros(sizes.size, np.int64)
    start[order] = np.concatenate([[0], np.cumsum(sizes[order])[:-1]])
    total = int(sizes.sum())
    pad = (-(total + _IDLE_MIN_BYTES)) % tf.ZONE_BYTES + _IDLE_MIN_BYTES
    zone = np.zeros(total + pad, np.uint8)
    offset = 0
    for g in groups:
        data = g[0]
        m, size = data.shape
        idx = start[offset : offset + m, None] + np.arange(size)
        zone[idx] = data
        offset += m
    idle = np.zeros(1, tf.PACKET_HEADER_DTYPE)
    idle["id"] = tf.APID_IDLE
    idle["sequence"] = 0xC000
    idle["length"] = pad - 7
    zone[total : total + 6] = idle.view(np.uint8)
    return zone, start, times, order, total


def _sequence_counts(
    zone: NDArray[np.uint8], start: NDArray[np.int64], order: NDArray[np.int64]
) -> None:
    """Fill each packet's 14-bit sequence count, per APID, in sending order."""
    s = start[order]
    apid = ((zone[s].astype(np.int64) << 8) | zone[s + 1]) & 0x7FF
    seq = np.zeros(s.size, np.int64)
    for a in np.unique(apid):
        sel = apid == a
        seq[sel] = np.arange(np.count_nonzero(sel)) % (1 << 14)
    word = 0xC000 | seq
    zone[s + 2] = word >> 8
    zone[s + 3] = word & 0xFF


def frames_to_cadus(frames: NDArray[np.uint8]) -> NDArray[np.uint8]:
    """Transfer frames (n, 892) whose CRC is filled → CADUs (n, 1024): RS encoding with
    interleave 4, randomisation of the code block, ASM in front."""
    blocks = encode_block(frames) ^ pn_sequence(tf.CODE_BLOCK_BYTES)
    asm = np.broadcast_to(tf.ASM, (frames.shape[0], 4))
    return np.concatenate([asm, blocks], axis=1)


def _frame_headers(
    frames: NDArray[np.uint8],
    vc: NDArray[np.int64],
    count: NDArray[np.int64],
    fhp: NDArray[np.int64],
) -> None:
    head = np.zeros(vc.size, tf.FRAME_HEADER_DTYPE)
    head["id"] = (1 << 14) | (tf.SPACECRAFT_ID << 6) | vc
    head["count"] = tf.u24(count)
    head["mpdu"] = fhp
    frames[:, : tf.FRAME_HEADER_BYTES] = head.view(np.uint8).reshape(-1, tf.FRAME_HEADER_BYTES)


def _first_header_pointers(
    n_data: int, sorted_start: NDArray[np.int64], idle_at: int
) -> NDArray[np.int64]:
    """Each data frame's first header pointer: where the first packet header in its zone
    starts (packets laid out in sending order, ``sorted_start`` their first bytes in the
    zone stream, the idle packet's at ``idle_at``), else ``FHP_NONE``."""
    frame_start = np.arange(n_data) * tf.ZONE_BYTES
    headers = np.append(sorted_start, idle_at)  # every packet header, the idle one last
    nxt = headers[np.minimum(np.searchsorted(headers, frame_start), headers.size - 1)]
    return np.where(
        (nxt >= frame_start) & (nxt < frame_start + tf.ZONE_BYTES), nxt - frame_start, tf.FHP_NONE
    )


def _slots(
    t_sorted: NDArray[np.float64],
    sorted_start: NDArray[np.int64],
    n_data: int,
    times: NDArray[np.float64],
    cfg: DownlinkConfig,
) -> tuple[NDArray[np.int64], float, float]:
    """The slot of each data frame: the first after the frame is full (the time of the
    packet holding its last byte), never before the frame before it; the session's start
    (the first packet's time less the preamble) and the slot's duration."""
    last_byte = np.arange(n_data) * tf.ZONE_BYTES + tf.ZONE_BYTES - 1
    holder = np.searchsorted(sorted_start, last_byte, side="right") - 1
    ready = t_sorted[holder]
    slot_s = 8.0 * tf.CADU_BYTES / cfg.bit_rate_bit_per_s
    t_session = float(times.min()) - cfg.preamble_s
    earliest = np.ceil((ready - t_session) / slot_s).astype(np.int64)
    slot_of_frame = np.arange(n_data) + np.maximum.accumulate(earliest - np.arange(n_data))
    return slot_of_frame, t_session, slot_s


def transmit(acq: Acquisition, cfg: DownlinkConfig, rng: np.random.Generator) -> Transmission:
    """Packetise, frame and schedule an acquisition's data (module docstring)."""
    if not acq.bands:
        raise ValueError("the acquisition was emulated without rendering: nothing to send")
    first_line = (
        cfg.first_line_counter if cfg.first_line_counter >= 0 else int(rng.integers(10**5, 10**9))
    )
    first_count = (
        cfg.first_frame_count
        if cfg.first_frame_count >= 0
        else int(rng.integers(0, tf.VC_FRAME_COUNT_MODULUS))
    )
    fill_first = int(rng.integers(0, tf.VC_FRAME_COUNT_MODULUS))
    hrv = acq.hrv
    data_vc = tf.vc_of_hrv(hrv.number)

    groups, ground, seg_first = _image_packets(acq, first_line)
    aux = _aux_records(acq, first_line)
    no_payload = np.zeros((aux.size, 0), np.uint8)  # the record is the secondary header
    groups.append(
        (
            _packets(tf.APID_AUX + hrv.number, aux, no_payload),
            acq.gyros.t_s,
            np.full(aux.size, -1),
            np.full(aux.size, -1),
            np.full(aux.size, -1),
        )
    )
    zone, start, times, order, idle_at = _zone_stream(groups)
    _sequence_counts(zone, start, order)

    n_data = zone.size // tf.ZONE_BYTES
    fhp = _first_header_pointers(n_data, start[order], idle_at)
    slot_of_frame, t_session, slot_s = _slots(times[order], start[order], n_data, times, cfg)
    n_slots = int(slot_of_frame[-1]) + 1 + int(np.ceil(cfg.postamble_s / slot_s))
    vc = np.full(n_slots, tf.VC_FILL, np.int64)
    vc[slot_of_frame] = data_vc
    is_fill = vc == tf.VC_FILL
    fill_index = np.cumsum(is_fill) - 1
    data_sent = np.cumsum(~is_fill)  # data frames sent up to and including each slot
    count = np.where(is_fill, fill_first + fill_index, first_count + data_sent - 1)
    count %= tf.VC_FRAME_COUNT_MODULUS

    frames = np.zeros((n_slots, tf.FRAME_BYTES), np.uint8)
    frames[slot_of_frame, tf.FRAME_HEADER_BYTES : tf.FRAME_HEADER_BYTES + tf.ZONE_BYTES] = (
        zone.reshape(n_data, tf.ZONE_BYTES)
    )
    slot_fhp = np.full(n_slots, tf.FHP_IDLE, np.int64)
    slot_fhp[slot_of_frame] = fhp
    _frame_headers(frames, vc, count, slot_fhp)
    _status_records(
        frames, is_fill, data_vc, first_count, data_sent, fill_first, fill_index, n_data
    )
    crc = crc16_rows(frames, tf.FRAME_BYTES - 2)
    frames[:, -2] = crc >> 8
    frames[:, -1] = crc & 0xFF

    row, band, segment = (np.concatenate([g[k] for g in groups]) for k in (2, 3, 4))
    img = row >= 0  # image packets (aux packets carry −1)
    p_start = start[img]
    p_size = np.concatenate([np.full(g[1].size, g[0].shape[1]) for g in groups])[img]
    return Transmission(
        cadus=frames_to_cadus(frames),
        slot_t_s=np.asarray(t_session + slot_s * np.arange(n_slots), dtype=np.float64),
        vc=vc,
        count=count,
        data_vc=data_vc,
        first_count={data_vc: first_count, tf.VC_FILL: fill_first},
        sent={data_vc: n_data, tf.VC_FILL: int(is_fill.sum())},
        first_line_counter=first_line,
        segment_first_detector=seg_first,
        packet_row=row[img],
        packet_band=band[img],
        packet_segment=segment[img],
        packet_first_frame=p_start // tf.ZONE_BYTES,
        packet_last_frame=(p_start + p_size - 1) // tf.ZONE_BYTES,
        ground_bands=ground,
        aux=aux,
        bit_rate_bit_per_s=cfg.bit_rate_bit_per_s,
    )


def _status_records(
    frames: NDArray[np.uint8],
    is_fill: NDArray[np.bool_],
    data_vc: int,
    first_count: int,
    data_sent: NDArray[np.int64],
    fill_first: int,
    fill_index: NDArray[np.int64],
    n_data: int,
) -> None:
    """The session status in every fill frame's data field (docs/telemetry.md)."""
    rows = np.flatnonzero(is_fill)
    n_fill = rows.size
    entries = np.zeros((n_fill, 2), tf.STATUS_ENTRY_DTYPE)
    closed_data = data_sent[rows] >= n_data
    entries[:, 0]["vc"] = data_vc | np.where(closed_data, 0x80, 0)
    entries[:, 0]["first_count"] = tf.u24(first_count)
    entries[:, 0]["sent"] = data_sent[rows]
    last_fill = fill_index[rows] == n_fill - 1
    entries[:, 1]["vc"] = tf.VC_FILL | np.where(last_fill, 0x80, 0)
    entries[:, 1]["first_count"] = tf.u24(fill_first)
    entries[:, 1]["sent"] = fill_index[rows] + 1
    z0 = tf.FRAME_HEADER_BYTES
    magic = np.frombuffer(tf.STATUS_MAGIC, np.uint8)
    frames[rows, z0 : z0 + 4] = magic
    frames[rows, z0 + 4] = 2
    body = entries.view(np.uint8).reshape(n_fill, -1)
    frames[rows, z0 + 5 : z0 + 5 + body.shape[1]] = body
