"""The receiver on a stream as it arrives: frame sync, derandomisation, Reed–Solomon and CRC
on each piece of the stream as it comes, the rest of the receiver at any time on the frames
so far.

:class:`StreamDecoder` takes the demodulator's bytes piece by piece (:meth:`feed`); each
piece is searched for markers from where the last one left off (the resumable search of
:func:`station.srrs.frames.find_more`: every decision that needs a bit not yet arrived
waits for it), and the code blocks found are decoded at once; the bytes behind the
search's horizon are let go. The frames found go at once to the rest of the receiver
(accounting, packets, lines: :class:`station.srrs.assembler.Assembler`, in bounded memory
when given a spool directory) and are let go too. :meth:`decoded` is the receiver's pass
of what has arrived (a pass's archive written while it goes on); :meth:`finish` ends the
stream (its exact length in bits, when the sender says it) and returns what
:func:`station.srrs.receiver.receive` makes of the whole stream, array for array.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from station.srrs.assembler import REORDER_WINDOW, Assembler, Found
from station.srrs.frames import (
    LOSSES,
    POS,
    SEARCHED,
    decode_cadus,
    find_more,
    horizon_bit,
    sync_state,
)
from station.srrs.receiver import DecodedPass
from station.telemetry import format as tf

__all__ = ["StreamDecoder"]


class StreamDecoder:
    """One channel's stream, decoded as it arrives (module docstring)."""

    def __init__(
        self,
        search_tolerance: int = 3,
        lock_tolerance: int = 8,
        on_frames: Callable[[NDArray[np.uint8], Found], None] | None = None,
        spool: Path | None = None,
        window: int = REORDER_WINDOW,
    ) -> None:
        """``on_frames(cadus, found)``: called with each piece's CADUs as received (n,
        1024: the marker and the randomised code block, from their bit offsets) and what
        their decoding found (an SLE provider's frames: :mod:`station.live.raf`).
        ``spool``: where the assembler keeps the lines and image packets (a directory;
        None: in memory); ``window``: its reorder window (frames)."""
        self._tolerances = (search_tolerance, lock_tolerance)
        self.on_frames = on_frames
        self._state = sync_state()
        self._buffer = np.zeros(0, np.uint8)
        self._base_bit = 0  # the buffer's first bit in the stream
        self.n_bytes = 0  # bytes received
        self.assembler = Assembler(spool, window)
        self.ended = False
        self.n_frames = 0  # CADUs found so far
        self._rs_ok = self._corrected = 0

    def counts(self) -> dict[str, int]:
        """What has come so far: bytes, CADUs found, and how many decoded clean, corrected,
        or not at all (the progress line's)."""
        return {
            "bytes": self.n_bytes,
            "frames": self.n_frames,
            "corrected": self._corrected,
            "uncorrectable": self.n_frames - self._rs_ok,
        }

    def feed(self, data: bytes | NDArray[np.uint8]) -> int:
        """A piece of the stream; returns the CADUs it completed."""
        if self.ended:
            raise ValueError("the stream has ended")
        piece = np.frombuffer(data, np.uint8) if isinstance(data, bytes | bytearray) else data
        self.n_bytes += int(piece.size)
        self._buffer = np.concatenate([self._buffer, piece])
        return self._search(8 * self.n_bytes, final=False)

    def _search(self, n_bits: int, final: bool) -> int:
        offsets, confirmed = find_more(
            self._buffer, self._base_bit, n_bits, final, self._state, *self._tolerances
        )
        if offsets.size:
            frames, corrected, rs_ok, crc_ok = decode_cadus(self._buffer, offsets - self._base_bit)
            found = Found(offsets, confirmed, frames, corrected, rs_ok, crc_ok)
            self.n_frames += int(offsets.size)
            self._rs_ok += int(rs_ok.sum())
            self._corrected += int(((corrected > 0).any(axis=1) & rs_ok).sum())
            self.assembler.add(found)
            if self.on_frames is not None:
                self.on_frames(_cadus_at(self._buffer, offsets - self._base_bit), found)
        keep = (horizon_bit(self._state) >> 3) - (self._base_bit >> 3)
        if keep > 0:  # the bytes no decision will read again
            self._buffer = self._buffer[keep:].copy()
            self._base_bit += 8 * keep
        return int(offsets.size)

    def decoded(self) -> DecodedPass:
        """The receiver on the frames found so far, the stream cut where it stands."""
        s = self._state
        fields = self.assembler.result(8 * self.n_bytes, int(s[SEARCHED]), int(s[LOSSES]))
        return DecodedPass(**fields)

    def finish(self, n_bits: int | None = None) -> DecodedPass:
        """The stream has ended (``n_bits`` of it, default every byte's): the last
        decisions taken as the batch takes them at its end; the whole stream's pass."""
        n = 8 * self.n_bytes if n_bits is None else int(n_bits)
        if not 8 * self.n_bytes - 8 < n <= 8 * self.n_bytes and self.n_bytes:
            raise ValueError(f"{n} bits said, {self.n_bytes} bytes received")
        self._search(n, final=True)
        self.ended = True
        s = self._state
        return DecodedPass(**self.assembler.result(n, int(s[SEARCHED]), int(s[LOSSES]), True))

    @property
    def position_bit(self) -> int:
        """Where the search stands in the stream (bits)."""
        return int(self._state[POS])


def _cadus_at(buffer: NDArray[np.uint8], bits: NDArray[np.int64]) -> NDArray[np.uint8]:
    """The CADUs (n, 1024) of ``buffer`` at bit offsets ``bits``, each byte aligned."""
    b, s = bits >> 3, (bits & 7).astype(np.uint16)[:, None]
    idx = b[:, None] + np.arange(tf.CADU_BYTES + 1)[None, :]
    raw = np.take(buffer, np.minimum(idx, buffer.size - 1), mode="clip").astype(np.uint16)
    raw[idx >= buffer.size] = 0
    return (((raw[:, :-1] << s) | (raw[:, 1:] >> (8 - s))) & 0xFF).astype(np.uint8)
