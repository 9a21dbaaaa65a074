"""Frame accounting of a received pass, per virtual channel: every CADU gets one status, and
per channel **sent = delivered + lost** (``station.srrs.receiver`` says how).

Frame counts are 24 bits: they are unwrapped in arrival order (steps the shortest way
round), duplicates and frames arriving after a later one are marked, and the frames
expected are those from the session's first count (reported by any fill frame's status
table) to the last one sent (reported by a fill frame flagged *closed*, or else the last one
received).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from station.telemetry import format as tf

__all__ = [
    "CORRECTED",
    "DUPLICATE",
    "FALSE_SYNC",
    "FILL",
    "OK",
    "OUT_OF_ORDER",
    "STATUS_NAMES",
    "UNCORRECTABLE",
    "ChannelAccount",
    "account",
    "status_tables",
]

STATUS_NAMES = (
    "ok",
    "corrected",
    "uncorrectable",
    "duplicate",
    "out_of_order",
    "fill",
    "false_sync",
)
OK, CORRECTED, UNCORRECTABLE, DUPLICATE, OUT_OF_ORDER, FILL, FALSE_SYNC = range(7)
_HALF = tf.VC_FRAME_COUNT_MODULUS // 2


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


def _unwrap(count: NDArray[np.int64]) -> NDArray[np.int64]:
    """Unwrap 24-bit counts in arrival order (steps taken as the shortest way round)."""
    if count.size == 0:
        return count.copy()
    step = (np.diff(count) + _HALF) % tf.VC_FRAME_COUNT_MODULUS - _HALF
    return count[0] + np.concatenate([[0], np.cumsum(step)])


def _near(value: int, reference: int) -> int:
    """The unwrapped count ≡ value (mod 2²⁴) nearest to ``reference``."""
    return reference + (value - reference + _HALF) % tf.VC_FRAME_COUNT_MODULUS - _HALF


def status_tables(frames: NDArray[np.uint8], rows: NDArray[np.int64]) -> dict[int, dict]:
    """Session status read from good fill frames: per VC, first count, most sent, closed."""
    z0 = tf.FRAME_HEADER_BYTES
    out: dict[int, dict] = {}
    magic = np.frombuffer(tf.STATUS_MAGIC, np.uint8)
    good = rows[np.all(frames[rows, z0 : z0 + 4] == magic, axis=1)]
    if good.size == 0:
        return out
    most = (tf.ZONE_BYTES - 5) // tf.STATUS_ENTRY_DTYPE.itemsize
    n_entries = np.minimum(frames[good, z0 + 4].astype(np.int64), most)
    width = tf.STATUS_ENTRY_DTYPE.itemsize
    for k in range(int(n_entries.max(initial=0))):  # a handful of channels
        has = good[n_entries > k]
        raw = np.ascontiguousarray(frames[has, z0 + 5 + k * width : z0 + 5 + (k + 1) * width])
        e = raw.view(tf.STATUS_ENTRY_DTYPE).ravel()
        vc = (e["vc"] & 0x3F).astype(np.int64)
        closed = (e["vc"] & 0x80) != 0
        first = tf.from_u24(e["first_count"])
        for v in np.unique(vc):
            sel = vc == v
            out[int(v)] = {
                "first": int(first[sel][0]),
                "sent": int(e["sent"][sel].max()),
                "closed": bool(closed[sel].any()),
            }
    return out


def account(
    vc: int,
    rows: NDArray[np.int64],
    count24: NDArray[np.int64],
    corrected: NDArray[np.int64],
    status: NDArray[np.int64],
    table: dict | None,
    unwrapped: NDArray[np.int64],
) -> ChannelAccount:
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
        vc=vc,
        sent=expected,
        delivered=delivered,
        lost=expected - delivered,
        gaps=inner_gaps + int(uniq[0] > lo) + int(uniq[-1] < hi),
        duplicates=int((~is_first).sum()),
        out_of_order=int(late.sum()),
        corrected=int((is_first & (n_corr > 0)).sum()),
        symbols_corrected=int(n_corr[is_first].sum()),
        head_known=head_known,
        tail_known=tail_known,
        first_count=lo,
    )
