"""RAF transfer buffers, encoded a piece of frames at a time (CCSDS 911.1's
``RafTransferBuffer``: a SEQUENCE OF ``[0] RafTransferDataInvocation``).

Each annotated frame is the same BER layout but for its data-link continuity, an INTEGER
of one to eight content bytes: the frames of a piece are laid as rows of one byte array,
the continuity right-aligned in its widest form, and the bytes a row does not use dropped
by one mask. The result is, byte for byte, what encoding each frame with
:mod:`station.live.ber` gives (``tests/test_sle.py``).

:class:`FrameQueue` is the provider's queue of frames waiting for a user, kept as the
pieces the front end offered, not a frame at a time.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from station.live.ber import CONTEXT, octets, tlv

__all__ = ["FrameQueue", "Frames", "transfer_buffer"]

_SEQUENCE_OF_8 = (CONTEXT, True, 8)  # RafTransferBuffer, [8] in the RAF PDUs' choice
_ENTRY = 0xA0  # [0] IMPLICIT RafTransferDataInvocation, constructed
_INTEGER, _NULL_0, _OCTETS = 0x02, bytes([0x80, 0x00]), 0x04


@dataclass(frozen=True, eq=False)
class Frames:
    """Frames of one piece for a user: their earth-receive time (CDS, 8 bytes), the
    channel's tag, and per frame its continuity, quality and CADU (n, 1024)."""

    ert: bytes
    tag: bytes
    continuity: NDArray[np.int64]
    quality: NDArray[np.int64]
    cadus: NDArray[np.uint8]

    def __len__(self) -> int:
        return int(self.quality.size)

    def part(self, a: int, b: int) -> Frames:
        return Frames(self.ert, self.tag, self.continuity[a:b], self.quality[a:b], self.cadus[a:b])


class FrameQueue:
    """Frames waiting for a user, piece by piece, oldest first."""

    def __init__(self) -> None:
        self._pieces: deque[Frames] = deque()
        self._n = 0

    def __len__(self) -> int:
        return self._n

    def put(self, frames: Frames) -> None:
        if len(frames):
            self._pieces.append(frames)
            self._n += len(frames)

    def take(self, n: int) -> list[Frames]:
        """The oldest ``n`` frames (or all there are), as pieces."""
        out: list[Frames] = []
        while n > 0 and self._pieces:
            head = self._pieces.popleft()
            if len(head) > n:
                out.append(head.part(0, n))
                self._pieces.appendleft(head.part(n, len(head)))
            else:
                out.append(head)
            n -= len(out[-1])
            self._n -= len(out[-1])
        return out

    def keep_newest(self, n: int) -> int:
        """The oldest frames dropped until ``n`` are left; how many were dropped."""
        dropped = max(0, self._n - n)
        self.take(dropped)
        return dropped


def _integer_width(v: NDArray[np.int64]) -> NDArray[np.int64]:
    """Content bytes of each value as a minimal two's-complement INTEGER."""
    bits = np.where(v < 0, ~v, v).astype(np.uint64)
    width = np.ones(v.size, np.int64)
    for k in range(1, 8):  # a width at a time, not a value
        width += bits >= np.uint64(1) << np.uint64(8 * k - 1)
    return width


def _entries(me: bytes, f: Frames) -> NDArray[np.uint8]:
    """The annotated frames of a piece, each a ``[0]`` element, laid end to end."""
    n = len(f)
    k = _integer_width(f.continuity)
    kmax = int(k.max())
    head = me + octets(f.ert, CONTEXT, 0) + octets(f.tag, CONTEXT, 1)
    tail_len = 3 + len(_NULL_0) + 4 + f.cadus.shape[1]  # quality, null, the data's octets
    content = len(head) + 2 + k + tail_len
    if int(content.max()) >= 1 << 16:
        raise ValueError("an annotated frame longer than 64 kB")
    cont = np.asarray(f.continuity, ">i8").view(np.uint8).reshape(n, 8)[:, 8 - kmax :]
    rows = np.concatenate(
        [
            np.array([[_ENTRY, 0x82]], np.uint8).repeat(n, 0),
            np.stack([content >> 8, content & 0xFF], 1).astype(np.uint8),
            np.frombuffer(head, np.uint8)[None, :].repeat(n, 0),
            np.stack([np.full(n, _INTEGER), k], 1).astype(np.uint8),
            cont,
            np.stack([np.full(n, _INTEGER), np.ones(n), f.quality], 1).astype(np.uint8),
            np.frombuffer(_NULL_0 + bytes([_OCTETS, 0x82]), np.uint8)[None, :].repeat(n, 0),
            np.array([[f.cadus.shape[1] >> 8, f.cadus.shape[1] & 0xFF]], np.uint8).repeat(n, 0),
            f.cadus,
        ],
        axis=1,
    )
    if np.all(k == kmax):  # one width (the usual: every frame follows its last)
        return rows.ravel()
    keep = np.ones(rows.shape, bool)
    at = 4 + len(head) + 2  # where the continuity's widest form starts
    keep[:, at : at + kmax] = np.arange(kmax)[None, :] >= (kmax - k)[:, None]
    return rows[keep]


def transfer_buffer(me: bytes, pieces: list[Frames]) -> bytes:
    """A ``RafTransferBuffer`` of the frames of ``pieces`` in order; ``me`` is the
    invoker's credentials, already encoded."""
    body = b"".join(_entries(me, f).tobytes() for f in pieces if len(f))
    return tlv(*_SEQUENCE_OF_8, body)
