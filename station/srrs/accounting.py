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
    "Ledger",
    "merge_entries",
    "status_entries",
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


def _near(value: int, reference: int) -> int:
    """The unwrapped count ≡ value (mod 2²⁴) nearest to ``reference``."""
    return reference + (value - reference + _HALF) % tf.VC_FRAME_COUNT_MODULUS - _HALF


def status_entries(
    frames: NDArray[np.uint8], rows: NDArray[np.int64]
) -> dict[tuple[int, int], dict]:
    """Session status read from good fill frames, per (VC, place in the table): first
    count (of the first frame read), most sent, closed. Entries of successive pieces of a
    stream merge (:func:`merge_entries`) into those of the whole."""
    z0 = tf.FRAME_HEADER_BYTES
    out: dict[tuple[int, int], dict] = {}
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
            out[(int(v), k)] = {
                "first": int(first[sel][0]),
                "sent": int(e["sent"][sel].max()),
                "closed": bool(closed[sel].any()),
            }
    return out


def merge_entries(into: dict[tuple[int, int], dict], new: dict[tuple[int, int], dict]) -> None:
    """The entries of a later piece of the stream merged into ``into`` (in place)."""
    for key, e in new.items():
        old = into.get(key)
        if old is None:
            into[key] = e
        else:
            old["sent"] = max(old["sent"], e["sent"])
            old["closed"] = old["closed"] or e["closed"]


def status_tables(entries: dict[tuple[int, int], dict]) -> dict[int, dict]:
    """Per VC, its status from the entries (:func:`status_entries`): the table's last
    place holding it, the channels in the order they first appear."""
    places = sorted(entries, key=lambda vk: (vk[1], vk[0]))
    order = {v: i for i, (v, _) in reversed(list(enumerate(places)))}
    last = {v: entries[(v, k)] for v, k in places}
    return {v: dict(last[v]) for v in sorted(last, key=order.__getitem__)}


class Ledger:
    """One virtual channel's good frames, classified in arrival order piece by piece
    (counts unwrapped the shortest way round, the first copy of each count delivered,
    later copies duplicates, a first copy after a later count out of order), and its
    account (:meth:`account`)."""

    def __init__(self) -> None:
        self.last24 = -1
        self.last_u = 0
        self.base = 0
        self.seen = np.zeros(0, bool)  # counts delivered, from ``base``
        self.top = np.iinfo(np.int64).min  # the highest count delivered so far
        self.duplicates = self.out_of_order = self.corrected = self.symbols = 0

    def _cover(self, lo: int, hi: int) -> None:
        if self.seen.size == 0:
            self.base, self.seen = lo, np.zeros(hi - lo + 1, bool)
            return
        new_lo, new_hi = min(lo, self.base), max(hi, self.base + self.seen.size - 1)
        if new_lo < self.base or new_hi >= self.base + self.seen.size:
            span = new_hi - new_lo + 1
            grown = np.zeros(max(span, 2 * self.seen.size), bool)
            grown[self.base - new_lo : self.base - new_lo + self.seen.size] = self.seen
            self.base, self.seen = new_lo, grown

    def classify(
        self, count24: NDArray[np.int64], corrected: NDArray[np.int64]
    ) -> tuple[NDArray[np.int64], NDArray[np.bool_], NDArray[np.bool_]]:
        """A piece's good frames of the channel (24-bit counts, symbols corrected) in
        arrival order: their unwrapped counts, which are first copies, which are late."""
        if count24.size == 0:
            e = np.zeros(0, np.int64)
            return e, e.astype(bool), e.astype(bool)
        prev = count24[0] if self.last24 < 0 else self.last24
        step = (np.diff(count24, prepend=prev) + _HALF) % tf.VC_FRAME_COUNT_MODULUS - _HALF
        u = (count24[0] if self.last24 < 0 else self.last_u) + np.cumsum(step)
        self.last24, self.last_u = int(count24[-1]), int(u[-1])
        self._cover(int(u.min()), int(u.max()))
        _, first_idx = np.unique(u, return_index=True)
        is_first = np.zeros(u.size, bool)
        is_first[first_idx] = True
        is_first &= ~self.seen[u - self.base]
        self.seen[u[is_first] - self.base] = True
        running = np.maximum.accumulate(
            np.concatenate([[self.top], np.where(is_first, u, np.iinfo(np.int64).min)])
        )
        late = is_first & (u < running[:-1])
        self.top = int(running[-1])
        self.duplicates += int((~is_first).sum())
        self.out_of_order += int(late.sum())
        self.corrected += int((is_first & (corrected > 0)).sum())
        self.symbols += int(corrected[is_first].sum())
        return u, is_first, late

    def account(self, vc: int, table: dict | None) -> ChannelAccount:
        """The channel's frames accounted from what has been classified (module docstring)."""
        seen = self.seen  # a byte a count: no array of the counts themselves is made
        first = int(np.argmax(seen))
        last = seen.size - 1 - int(np.argmax(seen[::-1]))
        got_lo, got_hi = first + self.base, last + self.base
        span = seen[first : last + 1]
        delivered = int(np.count_nonzero(span))
        inner_gaps = int(np.count_nonzero(span[:-1] & ~span[1:]))
        head_known = tail_known = False
        lo, hi = got_lo, got_hi
        if table is not None:
            first = _near(table["first"], lo)
            if first > lo:  # the reported first cannot be after a frame received
                first -= tf.VC_FRAME_COUNT_MODULUS
            lo, head_known = first, True
            hi = max(hi, first + table["sent"] - 1)
            tail_known = table["closed"]
        expected = hi - lo + 1
        return ChannelAccount(
            vc=vc,
            sent=expected,
            delivered=delivered,
            lost=expected - delivered,
            gaps=inner_gaps + int(got_lo > lo) + int(got_hi < hi),
            duplicates=self.duplicates,
            out_of_order=self.out_of_order,
            corrected=self.corrected,
            symbols_corrected=self.symbols,
            head_known=head_known,
            tail_known=tail_known,
            first_count=lo,
        )
