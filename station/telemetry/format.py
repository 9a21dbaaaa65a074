"""The telemetry format: byte layouts shared by the spacecraft's sender and the station.

Everything here is documented, with byte tables, in ``docs/telemetry.md``; the structured
dtypes below are those tables (big-endian, as CCSDS sends them), so that building or
parsing thousands of headers is one numpy view, never a loop.

Layers, outside in
    CADU (1024 B) = ASM 1ACFFC1D + code block (1020 B: RS(255,223) interleave 4, randomised)
    transfer frame (892 B) = primary header (6 B) + M_PDU header (2 B) + packet zone (882 B)
                             + frame error control (CRC-16, 2 B)
    space packet = primary header (6 B) + secondary header + data, spanning frames freely
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

__all__ = [
    "APID_AUX",
    "APID_IDLE",
    "APID_IMAGE",
    "ASM",
    "AUX_DTYPE",
    "CADU_BYTES",
    "CNES_EPOCH",
    "CODE_BLOCK_BYTES",
    "ENCODING_DPCM6",
    "ENCODING_RAW8",
    "FHP_IDLE",
    "FHP_NONE",
    "FRAME_BYTES",
    "FRAME_HEADER_DTYPE",
    "IMAGE_HEADER_DTYPE",
    "PACKET_HEADER_DTYPE",
    "SEGMENT_DETECTORS",
    "SPACECRAFT_ID",
    "STATUS_ENTRY_DTYPE",
    "STATUS_MAGIC",
    "VC_FILL",
    "VC_FRAME_COUNT_MODULUS",
    "ZONE_BYTES",
    "from_u24",
    "ms_since_cnes_epoch",
    "u24",
    "vc_of_hrv",
]

ASM = np.frombuffer(bytes.fromhex("1ACFFC1D"), np.uint8)
ASM_WORD = 0x1ACFFC1D
CADU_BYTES = 1024
CODE_BLOCK_BYTES = CADU_BYTES - 4  # 4 × 255
FRAME_BYTES = 892  # 4 × 223
FRAME_HEADER_BYTES = 8  # primary header 6 + M_PDU header 2
ZONE_BYTES = FRAME_BYTES - FRAME_HEADER_BYTES - 2  # 882, before the 2-byte CRC
VC_FRAME_COUNT_MODULUS = 1 << 24
VC_FILL = 63
SPACECRAFT_ID = 0x5A  # our stand-in for SPOT; checked by the receiver
FHP_NONE = 0x7FF  # no packet header starts in this frame
FHP_IDLE = 0x7FE  # the packet zone holds no packets (fill frames)
APID_IMAGE = 0x100  # + HRV number
APID_AUX = 0x110  # + HRV number
APID_IDLE = 0x7FF
ENCODING_RAW8 = 0
ENCODING_DPCM6 = 1
SEGMENT_DETECTORS = 1500  # detectors per image packet: one CCD's useful part in P
STATUS_MAGIC = b"SES1"
#: The day SPOT's time codes count from (CNES Julian day 0).
CNES_EPOCH = np.datetime64("1950-01-01T00:00:00", "ns")
#: The time codes the receiver takes as plausible: below 2⁴⁴ ms (557 years) after
#: :data:`CNES_EPOCH`; a pass after that is not one this telemetry can date.
TIME_CODE_LIMIT_MS = 2**44


def vc_of_hrv(hrv: int) -> int:
    """The virtual channel of an HRV's data (1 or 2)."""
    return int(hrv)


def u24(values: ArrayLike) -> np.ndarray:
    """24-bit unsigned values (…) → their 3 big-endian bytes (…, 3)."""
    v = np.asarray(values, np.int64)
    return np.stack([v >> 16, (v >> 8) & 0xFF, v & 0xFF], axis=-1).astype(np.uint8)


def from_u24(octets: np.ndarray) -> np.ndarray:
    """3 big-endian bytes (…, 3) → the 24-bit values (…) as int64."""
    b = np.asarray(octets, np.int64)
    return (b[..., 0] << 16) | (b[..., 1] << 8) | b[..., 2]


def ms_since_cnes_epoch(t0_utc: np.datetime64, t_s: np.ndarray) -> np.ndarray:
    """Time codes: whole milliseconds since 1950-01-01 (truncated, as a counter latches)."""
    base_ns = (np.asarray(t0_utc).astype("datetime64[ns]") - CNES_EPOCH).astype(np.int64)
    ns = base_ns + np.floor(np.asarray(t_s, np.float64) * 1e9).astype(np.int64)
    return ns // 1_000_000


#: Transfer frame primary header (AOS-like, CCSDS 732.0-B §4.1.2) and M_PDU header.
FRAME_HEADER_DTYPE = np.dtype(
    [
        ("id", ">u2"),  # version '01' (2 bits), spacecraft id (8), virtual channel id (6)
        ("count", "u1", (3,)),  # virtual channel frame count, 24 bits
        ("signalling", "u1"),  # replay flag, count usage flag, spares, count cycle: all 0
        ("mpdu", ">u2"),  # 5 spare bits, first header pointer (11 bits)
    ]
)

#: Space packet primary header (CCSDS 133.0-B §4.1.3).
PACKET_HEADER_DTYPE = np.dtype(
    [
        ("id", ">u2"),  # version 000, type 0, secondary header flag 1, APID (11 bits)
        ("sequence", ">u2"),  # sequence flags '11' (unsegmented), sequence count (14 bits)
        ("length", ">u2"),  # octets after the primary header, minus one
    ]
)

#: Secondary header of an image line segment packet.
IMAGE_HEADER_DTYPE = np.dtype(
    [
        ("line", ">u4"),  # line counter of the instrument
        ("band", "u1"),  # 0 for P; 0, 1, 2 for XS1, XS2, XS3
        ("encoding", "u1"),  # ENCODING_RAW8 or ENCODING_DPCM6
        ("first_detector", ">u2"),  # first column of the segment (0-based)
        ("count", ">u2"),  # detectors in the segment
    ]
)

#: Auxiliary data packet (8 Hz): time code, gyros, mirror, mode, status, the planned strip.
AUX_DTYPE = np.dtype(
    [
        ("time_ms", ">u8"),  # time code of the gyro sample, ms since 1950-01-01 (48 bits used)
        ("line", ">u4"),  # the first line starting at or after that instant
        ("line_time_ms", ">u8"),  # time code latched at that line's start
        ("gyro_counts", ">i4", (3,)),  # roll, pitch, yaw rates in units of gyro_lsb
        ("gyro_lsb_prad_per_s", ">u4"),  # one count, in 1e-12 rad/s
        ("mirror_step", "u1"),
        ("mode", "u1"),  # 0 P, 1 XS
        ("hrv", "u1"),
        ("status", "u1"),  # bit 0: imaging; bit 1: twin configuration
        ("first_line", ">u4"),  # the planned strip: first line counter …
        ("n_lines", ">u4"),  # … and its number of lines
        ("n_detectors", ">u2"),  # detectors per band line
        ("n_bands", "u1"),
        ("spare", "u1"),
    ]
)

#: One entry of the session status carried by fill frames: for each virtual channel, the
#: count of its first frame in this session and how many frames it has sent so far.
STATUS_ENTRY_DTYPE = np.dtype(
    [
        ("vc", "u1"),
        ("first_count", "u1", (3,)),
        ("sent", ">u4"),
    ]
)
