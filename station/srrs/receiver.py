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

The receiver is three steps, each in its module: frame accounting
(:mod:`station.srrs.accounting`), packets and lines (:mod:`station.srrs.packets`), the line
clock (:mod:`station.srrs.clock`). Packets are cut from the delivered frames of each data
channel in frame-count order:
a run of consecutive frames is one stretch of packet zone; a packet that runs into a gap is
dropped whole, and parsing resumes at the first header pointer of the next frame after the
gap. Image packets are decoded (DPCM for P) into their place; a segment of a line is valid
only if its packet arrived complete. Nothing lost is ever presented as data.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from levels.readers.l0 import pixel_mask
from station.srrs.accounting import CORRECTED, OK, OUT_OF_ORDER, STATUS_NAMES, ChannelAccount
from station.srrs.assembler import Assembler, Found, SpooledColumn, StoredBand
from station.srrs.errors import ReceiverError
from station.srrs.frames import decode_cadus, find_cadus
from station.telemetry import format as tf

__all__ = [
    "CORRECTED",
    "OK",
    "OUT_OF_ORDER",
    "STATUS_NAMES",
    "ChannelAccount",
    "DecodedPass",
    "Found",
    "ReceiverError",
    "assemble",
    "receive",
]


@dataclass(frozen=True, eq=False)
class DecodedPass:
    """What the receiver made of a pass: per-frame log, accounting, lines and aux."""

    #: per frame found (int64, int8, int8, int64, int16): in memory, or a front end's
    #: columns read from its spool a block at a time
    frame_bit_offset: NDArray[np.int64] | SpooledColumn
    frame_status: NDArray[np.int8] | SpooledColumn
    frame_vc: NDArray[np.int8] | SpooledColumn
    frame_count: NDArray[np.int64] | SpooledColumn  # unwrapped; −1 where unknown
    frame_symbols_corrected: NDArray[np.int16] | SpooledColumn
    accounts: dict[int, ChannelAccount]
    bits_in: int
    bits_searched: int
    sync_losses: int
    hrv: int
    mode: str
    mirror_step: int
    twin: bool
    first_line_counter: int
    #: per band, (lines, detectors): in memory, or read from a front end's store
    images: tuple[NDArray[np.uint8] | StoredBand, ...]
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
        return pixel_mask(self.valid[band], self.segment_first_detector, self.images[band].shape[1])

    @property
    def status_counts(self) -> dict[str, int]:
        st = self.frame_status
        blocks = st.blocks() if isinstance(st, SpooledColumn) else [st]
        counts = sum(
            (np.bincount(b, minlength=len(STATUS_NAMES)) for b in blocks),
            np.zeros(len(STATUS_NAMES), np.int64),
        )
        return {name: int(c) for name, c in zip(STATUS_NAMES, counts, strict=True)}


def receive(
    stream: NDArray[np.uint8],
    n_bits: int | None = None,
    search_tolerance: int = 3,
    lock_tolerance: int = 8,
) -> DecodedPass:
    """Decode a recorded pass (module docstring). Raises :class:`ReceiverError` only when
    nothing usable is in it; every defect short of that is counted, not raised."""
    stream = np.ascontiguousarray(
        np.frombuffer(stream, np.uint8) if isinstance(stream, bytes | bytearray) else stream,
        np.uint8,
    )
    n_bits = stream.size * 8 if n_bits is None else int(n_bits)
    offsets, confirmed, searched, losses = find_cadus(
        stream, n_bits, search_tolerance, lock_tolerance
    )
    frames, corrected, rs_ok, crc_ok = decode_cadus(stream, offsets)
    found = Found(offsets, confirmed, frames, corrected, rs_ok, crc_ok)
    return assemble(found, n_bits, searched, losses)


def assemble(found: Found, n_bits: int, searched: int, losses: int) -> DecodedPass:
    """The frames found in a stream of ``n_bits`` (``searched`` bits scanned, the lock lost
    ``losses`` times) accounted, cut into packets and lines (module docstring): what
    :func:`receive` makes of a recorded pass, one piece of
    :class:`station.srrs.assembler.Assembler`'s."""
    assembler = Assembler()
    assembler.add(found)
    return DecodedPass(**assembler.result(n_bits, searched, losses, final=True))
