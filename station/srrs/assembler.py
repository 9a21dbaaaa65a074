"""The receiver's assembly of a stream's frames, piece by piece, in bounded memory.

:class:`Assembler` takes the CADUs found in a stream in arrival order, a piece at a time
(:meth:`Assembler.add`: a whole recorded pass is one piece, a stream at a front end many),
and keeps only what the rest of the pass can still change:

* each frame's log (bit offset, status, channel, unwrapped count, symbols corrected: 20
  bytes a frame) and each channel's ledger (:class:`station.srrs.accounting.Ledger`: a
  frame's status is final when it arrives);
* the data channel's delivered frames not yet released to the packet cutter: a frame
  waits until a count ``window`` frames later has arrived (a frame displaced or replayed
  within the window is put back in its place; one arriving after that is counted
  ``late_beyond_window`` and its packets dropped, as a gap);
* the packet cutter's state (:func:`station.srrs.packets.cut_packets`) and the frames
  from the packet it stands in;
* the auxiliary records (8 a second) and the strip's valid segments;
* the image lines, in a :class:`Lines` store: in memory (a recorded pass), or in a file
  (:class:`FileLines`, a front end's), so that a pass of any length is received in the
  same memory; and the image packets, spooled as received (in memory, or in a file), so
  that a strip's shape that a later majority of auxiliary records overturns is laid again.

:meth:`Assembler.result` is the receiver's pass of what has arrived (a front end's archive
while the pass goes on), or, ``final``, of the whole stream: array for array what the
batch receiver makes of it (the batch receiver *is* this, one piece long).
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from station.srrs.accounting import (
    CORRECTED,
    DUPLICATE,
    FALSE_SYNC,
    FILL,
    OK,
    OUT_OF_ORDER,
    UNCORRECTABLE,
    ChannelAccount,
    Ledger,
    merge_entries,
    status_entries,
    status_tables,
)
from station.srrs.errors import ReceiverError
from station.srrs.packets import (
    Segments,
    Strip,
    aux_records,
    cut_packets,
    image_segments,
    is_image_candidate,
    packet_ids,
    place_segments,
    strip_facts,
)
from station.telemetry import format as tf

__all__ = [
    "REORDER_WINDOW",
    "Assembler",
    "FileLines",
    "Found",
    "Lines",
    "SpooledColumn",
    "StoredBand",
]

#: Frames a delivered frame waits for displaced or replayed frames before it: the
#: emulator's channel displaces by 1000 at most (``[channel] reorder_distance``) and
#: replays 50 by default; 7.3 MB of frames.
REORDER_WINDOW = 8192
#: Lines a file store reads and writes at a time, and the blocks it keeps (a P block is
#: 3 MB).
BLOCK_LINES, CACHED_BLOCKS = 512, 2
_H0 = tf.FRAME_HEADER_BYTES
_NO_AUX = np.zeros(0, tf.AUX_DTYPE)


@dataclass(frozen=True, eq=False)
class Found:
    """The CADUs found in a stream, in stream order: bit offsets, whether each marker was
    confirmed, their transfer frames (n, 892), the symbols corrected per codeword (n, 4;
    −1 where uncorrectable), and whether Reed–Solomon then the CRC checked."""

    offsets: NDArray[np.int64]
    confirmed: NDArray[np.bool_]
    frames: NDArray[np.uint8]
    corrected: NDArray[np.int64]
    rs_ok: NDArray[np.bool_]
    crc_ok: NDArray[np.bool_]


class Lines:
    """The strip's image lines, in memory: (bands, lines, detectors) counts."""

    def __init__(self, n_bands: int, n_lines: int, n_detectors: int) -> None:
        self.shape = (n_bands, n_lines, n_detectors)
        self.images = np.zeros(self.shape, np.uint8)

    def place(self, zone: NDArray[np.uint8], seg: Segments) -> None:
        place_segments(zone, seg, self.images)

    def bands(self) -> tuple[NDArray[np.uint8] | StoredBand, ...]:
        return tuple(self.images)

    def close(self) -> None:
        """Let go of what the store holds."""


class FileLines(Lines):
    """The strip's image lines in a file (band after band, a sparse file of zeros at
    first), placed a block of lines at a time through a cache of the last
    :data:`CACHED_BLOCKS` blocks (the lines arrive in order): the memory of a few blocks,
    whatever the strip's length."""

    def __init__(self, path: Path, n_bands: int, n_lines: int, n_detectors: int) -> None:
        self.shape = (n_bands, n_lines, n_detectors)
        self.path = Path(path)
        self._fd = os.open(self.path, os.O_RDWR | os.O_CREAT | os.O_TRUNC, 0o644)
        os.ftruncate(self._fd, n_bands * n_lines * n_detectors)
        self._cache: dict[int, NDArray[np.uint8]] = {}  # block → (bands, lines, detectors)
        self._dirty: set[int] = set()

    def read(self, band: int, a: int, b: int) -> NDArray[np.uint8]:
        """Lines ``a`` to ``b`` of a band, as the file holds them (:meth:`flush` first)."""
        _, n_lines, n_det = self.shape
        raw = os.pread(self._fd, (b - a) * n_det, (band * n_lines + a) * n_det)
        return np.frombuffer(raw, np.uint8).reshape(b - a, n_det).copy()

    def _block(self, block: int) -> NDArray[np.uint8]:
        rows = self._cache.pop(block, None)
        if rows is None:
            a, b = self._span(block)
            rows = np.stack([self.read(k, a, b) for k in range(self.shape[0])])
        self._cache[block] = rows  # the most recent last
        while len(self._cache) > CACHED_BLOCKS:
            oldest = next(iter(self._cache))
            self._write(oldest)
            del self._cache[oldest]
        return rows

    def _span(self, block: int) -> tuple[int, int]:
        return block * BLOCK_LINES, min((block + 1) * BLOCK_LINES, self.shape[1])

    def _write(self, block: int) -> None:
        if block in self._dirty:
            _, n_lines, n_det = self.shape
            a, _ = self._span(block)
            for k, rows in enumerate(self._cache[block]):
                os.pwrite(self._fd, rows.tobytes(), (k * n_lines + a) * n_det)
            self._dirty.discard(block)

    def flush(self) -> None:
        """Every block placed, in the file."""
        for block in list(self._dirty):
            self._write(block)

    def place(self, zone: NDArray[np.uint8], seg: Segments) -> None:
        for block in np.unique(seg.row // BLOCK_LINES):  # a block or two a piece
            a, _ = self._span(int(block))
            sel = (seg.row >= a) & (seg.row < a + BLOCK_LINES)
            part = Segments(
                seg.starts[sel], seg.row[sel], seg.band[sel], seg.first_detector[sel],
                seg.count[sel], seg.encoding[sel], 0,
            )  # fmt: skip
            place_segments(zone, part, self._block(int(block)), a)
            self._dirty.add(int(block))

    def bands(self) -> tuple[NDArray[np.uint8] | StoredBand, ...]:
        self.flush()
        return tuple(StoredBand(self, k) for k in range(self.shape[0]))

    def close(self) -> None:
        os.close(self._fd)
        self.path.unlink(missing_ok=True)


class StoredBand:
    """One band of a :class:`FileLines` store as an array to read rows from: ``shape``,
    ``dtype``, and slices of rows (and columns) read from the file when asked."""

    dtype = np.dtype(np.uint8)
    ndim = 2

    def __init__(self, store: FileLines, band: int) -> None:
        self.store, self.band = store, band
        self.shape = store.shape[1:]

    def __getitem__(self, key: slice | tuple[slice, ...]) -> NDArray[np.uint8]:
        rows, cols = (key[0], key[1:]) if isinstance(key, tuple) else (key, ())
        if rows.step in (None, 1):
            a, b, _ = rows.indices(self.shape[0])
            return self.store.read(self.band, a, max(a, b))[(slice(None), *cols)]
        return np.asarray(self)[key]

    def __array__(self, dtype: object = None, copy: object = None) -> NDArray[np.uint8]:
        return self.store.read(self.band, 0, self.shape[0])


class _Spool:
    """The image packets as received (zone, starts, lengths), to lay again: in memory
    (references to each piece's zone), or each piece's zone appended to a file."""

    def __init__(self, path: Path | None) -> None:
        self.path = path
        self._pieces: list[tuple[NDArray[np.uint8], NDArray[np.int64], NDArray[np.int64]]] = []
        self._size = 0
        self._index: list[NDArray[np.int64]] = []  # per piece: (n, 2) offsets, lengths
        if path is not None:
            self._f = path.open("w+b")

    def append(self, zone: NDArray[np.uint8], starts: NDArray[np.int64], lengths: NDArray) -> None:
        if starts.size == 0:
            return
        if self.path is None:
            self._pieces.append((zone, starts, lengths))
            return
        self._f.seek(self._size)
        self._f.write(np.ascontiguousarray(zone).data)  # the piece's zone, whole
        self._index.append(np.stack([self._size + starts, lengths], 1))
        self._size += int(zone.size)

    def replay(self) -> Iterator[tuple[NDArray[np.uint8], NDArray[np.int64], NDArray[np.int64]]]:
        if self.path is None:
            yield from self._pieces
            return
        self._f.flush()
        for idx in self._index:
            lo = int(idx[0, 0])
            hi = int(idx[-1, 0] + idx[-1, 1])
            zone = np.frombuffer(os.pread(self._f.fileno(), hi - lo, lo), np.uint8)
            yield zone, idx[:, 0] - lo, idx[:, 1]

    def close(self) -> None:
        self._pieces.clear()
        if self.path is not None:
            self._f.close()
            self.path.unlink(missing_ok=True)


class SpooledColumn:
    """One field of a front end's frame log as an array to read blocks from (its first
    ``n`` values in the file): ``shape``, ``dtype``, slices read when asked, the whole
    through ``np.asarray``."""

    ndim = 1

    def __init__(self, path: Path, dtype: type, n: int) -> None:
        self.path, self.dtype, self.size = path, np.dtype(dtype), n
        self.shape = (n,)

    def __getitem__(self, key: slice) -> NDArray:
        a, b, step = key.indices(self.size)
        count = max(b - a, 0) if step == 1 else self.size
        part = np.fromfile(self.path, self.dtype, count, offset=a * self.dtype.itemsize)
        return part if step == 1 else part[key]

    def __array__(self, dtype: object = None, copy: object = None) -> NDArray:
        return self[:]

    def blocks(self, n: int = 1 << 16) -> Iterator[NDArray]:
        for a in range(0, self.size, n):
            yield self[a : a + n]


class _FrameLog:
    """Each frame's bit offset, status, channel, unwrapped count and symbols corrected
    (20 bytes a frame), piece by piece: in memory, or appended to files (one a field)."""

    DTYPES = (np.int64, np.int8, np.int8, np.int64, np.int16)

    def __init__(self, path: Path | None) -> None:
        self.path = path
        self._pieces: list[tuple[NDArray, ...]] = []
        self._files = [] if path is None else [path.with_suffix(f".{k}") for k in range(5)]
        self._handles = [f.open("wb") for f in self._files]
        self.n = 0

    def append(self, fields: tuple[NDArray, ...]) -> None:
        fields = tuple(np.ascontiguousarray(a, d) for a, d in zip(fields, self.DTYPES, strict=True))
        self.n += int(fields[0].size)
        if self.path is None:
            self._pieces.append(fields)
        else:
            for f, a in zip(self._handles, fields, strict=True):
                f.write(a.data)

    def arrays(self) -> list[NDArray] | list[SpooledColumn] | None:
        """The fields of every frame so far (None before the first): arrays, or columns
        of the files read a block at a time."""
        if self.n == 0:
            return None
        if self.path is None:
            return [np.concatenate(x) for x in zip(*self._pieces, strict=True)]
        for f in self._handles:
            f.flush()
        return [SpooledColumn(f, d, self.n) for f, d in zip(self._files, self.DTYPES, strict=True)]

    def close(self) -> None:
        self._pieces.clear()
        for f, h in zip(self._files, self._handles, strict=True):
            h.close()
            f.unlink(missing_ok=True)


class Assembler:
    """A stream's frames assembled piece by piece (module docstring). ``spool``: a
    directory for the lines and the image packets (a front end's); None keeps them in
    memory (a recorded pass)."""

    def __init__(self, spool: Path | None = None, window: int = REORDER_WINDOW) -> None:
        self.spool, self.window = spool, window
        self._log = _FrameLog(None if spool is None else spool / "frames")
        self._ledgers: dict[int, Ledger] = {}
        self._entries: dict[tuple[int, int], dict] = {}
        self.data_vc: int | None = None
        # the data channel's frames waiting, and the cutter's carry and state
        self._waiting: list[tuple[NDArray[np.int64], NDArray[np.uint8]]] = []
        self._released = np.iinfo(np.int64).min
        self._carry = (np.zeros(0, np.int64), np.zeros((0, tf.FRAME_BYTES), np.uint8))
        self._cut_state = (-1, 0, 0)
        self._stats = dict.fromkeys(
            ("complete", "idle", "image", "sane", "dropped_at_gaps", "late_beyond_window"), 0
        )
        self._aux: list[NDArray] = []
        self._images = _Spool(None if spool is None else spool / "image_packets.bin")
        self._strip: Strip | None = None
        self._lines: Lines | None = None
        self._valid = np.zeros((0, 0, 0), bool)
        self.ended = False

    # -- frames ------------------------------------------------------------------------
    def add(self, found: Found) -> None:
        """The next CADUs found in the stream, in stream order: their status, their
        channels' ledgers, the data channel's frames."""
        if self.ended:
            raise ValueError("the stream has ended")
        offsets, confirmed, frames = found.offsets, found.confirmed, found.frames
        corrected, rs_ok, crc_ok = found.corrected, found.rs_ok, found.crc_ok
        head = np.ascontiguousarray(frames[:, :6])
        word = (head[:, 0].astype(np.int64) << 8) | head[:, 1]
        version, scid, vc = word >> 14, (word >> 6) & 0xFF, word & 0x3F
        count24 = tf.from_u24(head[:, 2:5])
        good = rs_ok & crc_ok & (version == 1) & (scid == tf.SPACECRAFT_ID)
        n_corr = np.where(corrected < 0, 0, corrected).sum(axis=1)
        status = np.where(good, np.where(n_corr > 0, CORRECTED, OK), UNCORRECTABLE)
        status[~good & ~confirmed] = FALSE_SYNC
        fill = good & (vc == tf.VC_FILL)
        merge_entries(self._entries, status_entries(frames, np.flatnonzero(fill)))
        unwrapped = np.full(offsets.size, -1, np.int64)
        for v in np.unique(vc[good]):  # a few channels
            rows = np.flatnonzero(good & (vc == v))
            ledger = self._ledgers.setdefault(int(v), Ledger())
            u, is_first, late = ledger.classify(count24[rows], n_corr[rows])
            unwrapped[rows] = u
            status[rows[~is_first]] = DUPLICATE
            status[rows[late]] = OUT_OF_ORDER
            if self.data_vc is None and v != tf.VC_FILL:
                self.data_vc = int(vc[good & (vc != tf.VC_FILL)][0])  # the first to arrive
            if v == self.data_vc:
                self._wait(u[is_first], frames[rows[is_first]])
        status[fill & (status != DUPLICATE)] = FILL
        self._log.append((offsets, status, np.where(good, vc, -1), unwrapped, n_corr))
        self._release(final=False)

    def _wait(self, u: NDArray[np.int64], frames: NDArray[np.uint8]) -> None:
        late = u <= self._released
        self._stats["late_beyond_window"] += int(late.sum())
        if (~late).any():
            self._waiting.append((u[~late], frames[~late]))

    def _release(self, final: bool) -> None:
        """The waiting frames no later arrival can precede, to the packet cutter in
        count order (a piece's frames move whole, but for the piece astride the limit)."""
        limit = np.iinfo(np.int64).max
        if not final and self.data_vc is not None:
            limit = self._ledgers[self.data_vc].top - self.window
        go_u, go_frames, keep = [], [], []
        for u, frames in self._waiting:
            if u.max() <= limit:
                go_u.append(u)
                go_frames.append(frames)
            elif u.min() > limit:
                keep.append((u, frames))
            else:
                go = u <= limit
                go_u.append(u[go])
                go_frames.append(frames[go])
                keep.append((u[~go], frames[~go]))
        self._waiting = keep
        if not go_u:
            if final:
                self._cut(np.zeros(0, np.int64), np.zeros((0, tf.FRAME_BYTES), np.uint8), True)
            return
        u = np.concatenate(go_u)
        frames = np.concatenate(go_frames)
        self._released = max(self._released, int(u.max()))
        if np.any(u[1:] < u[:-1]):  # displaced frames put back in their place
            order = np.argsort(u, kind="stable")
            u, frames = u[order], frames[order]
        self._cut(u, frames, final)

    def _cut(self, u: NDArray[np.int64], frames: NDArray[np.uint8], final: bool) -> None:
        zone, starts, lengths, dropped, (pos, anchor, f), seq, fr = self._cut_from(u, frames, final)
        self._stats["dropped_at_gaps"] += dropped
        keep = anchor if pos >= 0 else min(f, seq.size)
        self._carry = (seq[keep:], fr[keep:])
        self._cut_state = (pos - keep * tf.ZONE_BYTES if pos >= 0 else -1, anchor - keep,
                           max(f - keep, 0))  # fmt: skip
        if starts.size:
            self._aux += self._packets(zone, starts, lengths, self._stats, commit=True)

    def _cut_from(self, u: NDArray[np.int64], frames: NDArray[np.uint8], final: bool) -> tuple:
        """The cutter run on its carry and these frames, from its state."""
        seq = np.concatenate([self._carry[0], u])
        fr = np.concatenate([self._carry[1], frames])
        zone = np.ascontiguousarray(fr[:, _H0 : _H0 + tf.ZONE_BYTES]).ravel()
        fhp = ((fr[:, 6].astype(np.int64) << 8) | fr[:, 7]) & 0x7FF
        return (zone, *cut_packets(zone, seq, fhp, self._cut_state, final), seq, fr)

    def _peek(self) -> tuple[list[NDArray], dict[str, int]]:
        """The packets of the frames still waiting, as they stand (a pass so far): their
        aux records and counts, their segments placed (as they will be once released:
        the same bytes in the same places); nothing of the cutter's state changes."""
        tally = dict.fromkeys(self._stats, 0)
        if not self._waiting:
            return [], tally
        u = np.concatenate([w[0] for w in self._waiting])
        frames = np.concatenate([w[1] for w in self._waiting])
        order = np.argsort(u, kind="stable")
        zone, starts, lengths, *_ = self._cut_from(u[order], frames[order], False)
        return self._packets(zone, starts, lengths, tally, commit=False), tally

    # -- packets and lines -------------------------------------------------------------
    def _packets(
        self, zone: NDArray[np.uint8], starts: NDArray, lengths: NDArray, tally: dict,
        commit: bool,
    ) -> list[NDArray]:  # fmt: skip
        """Packets cut: counted into ``tally``, image segments placed (and, ``commit``,
        spooled); returns their aux records."""
        pid = packet_ids(zone, starts)
        tally["complete"] += int(starts.size)
        tally["idle"] += int((pid == tf.APID_IDLE).sum())
        aux, _ = aux_records(zone, starts, lengths, pid)
        found = [aux] if aux.size else []
        cand = is_image_candidate(pid, lengths)
        if commit:
            self._images.append(zone, starts[cand], lengths[cand])
        if self._strip is None and (self._aux or found):
            try:
                strip = Strip.of(np.concatenate(self._aux + found))
            except ReceiverError:  # an impossible strip so far: said by the result
                return found
            self._lay(strip)  # every image packet spooled so far
            if commit:
                return found
        if self._strip is not None:
            self._place(zone, starts[cand], lengths[cand], tally)
        return found

    def _lay(self, strip: Strip) -> None:
        """The lines laid out for ``strip``, every image packet spooled placed in them."""
        if self._lines is not None:
            self._lines.close()
        self._strip = strip
        shape = (strip.n_bands, strip.n_lines, strip.n_detectors)
        self._lines = (
            Lines(*shape) if self.spool is None else FileLines(self.spool / "lines.u8", *shape)
        )
        n_segments = strip.segment_first_detector.size
        self._valid = np.zeros((strip.n_bands, strip.n_lines, n_segments), bool)
        self._stats["image"] = self._stats["sane"] = 0
        for zone, starts, lengths in self._images.replay():
            self._place(zone, starts, lengths, self._stats)

    def _place(
        self, zone: NDArray[np.uint8], starts: NDArray, lengths: NDArray, tally: dict
    ) -> None:
        assert self._strip is not None and self._lines is not None
        seg = image_segments(zone, starts, lengths, packet_ids(zone, starts), self._strip)
        tally["image"] += seg.n_image
        tally["sane"] += int(seg.starts.size)
        self._lines.place(zone, seg)
        self._valid[seg.band, seg.row, seg.segment] = True

    # -- the pass ----------------------------------------------------------------------
    def accounts(self) -> dict[int, ChannelAccount]:
        tables = status_tables(self._entries)
        accounts = {v: self._ledgers[v].account(v, tables.get(v)) for v in sorted(self._ledgers)}
        for v, t in tables.items():  # channels that sent frames none of which arrived
            if v not in accounts:
                accounts[v] = ChannelAccount(
                    v, t["sent"], 0, t["sent"], 1, 0, 0, 0, 0, True, t["closed"], t["first"]
                )
        return accounts

    def result(self, n_bits: int, searched: int, losses: int, final: bool = False) -> dict:
        """The fields of :class:`receiver.DecodedPass` for what has arrived (``final``: the
        stream has ended; nothing can be added after). Raises :class:`ReceiverError` when
        nothing usable has come."""
        if final and not self.ended:
            self._release(final=True)
            self.ended = True
        log = self._log.arrays()
        if self.data_vc is None or log is None:
            n = self._log.n
            raise ReceiverError(
                f"no data frame could be decoded in the stream ({n} markers found in {n_bits} bits)"
            )
        peek_aux, peek = ([], dict.fromkeys(self._stats, 0)) if final else self._peek()
        t = {k: v + peek[k] for k, v in self._stats.items()}
        aux_all = np.concatenate(self._aux + peek_aux) if self._aux or peek_aux else _NO_AUX
        strip = Strip.of(aux_all)
        if self._strip is None or not strip.same(self._strip):
            self._lay(strip)  # outvoted: every image packet laid again
            if not final:
                peek_aux, peek = self._peek()
                t = {k: v + peek[k] for k, v in self._stats.items()}
        assert self._lines is not None
        agree = strip.agreeing(aux_all)
        aux = np.sort(aux_all[agree], order="time_ms")
        stats = {
            "complete": t["complete"],
            "idle": t["idle"],
            "aux": int(agree.sum()),
            "aux_rejected": int((~agree).sum()),
            "image": t["sane"],
            "image_rejected": t["image"] - t["sane"],
            "dropped_at_gaps": t["dropped_at_gaps"],
            "other": t["complete"] - t["idle"] - int(agree.size) - t["image"],
        }
        if t["late_beyond_window"]:
            stats["late_beyond_window"] = t["late_beyond_window"]
        return {
            "frame_bit_offset": log[0],
            "frame_status": log[1],
            "frame_vc": log[2],
            "frame_count": log[3],
            "frame_symbols_corrected": log[4],
            "accounts": self.accounts(),
            "bits_in": n_bits,
            "bits_searched": searched,
            "sync_losses": losses,
            **strip_facts(strip, aux),
            "images": self._lines.bands(),
            "valid": tuple(self._valid),
            "packets": stats,
        }

    def close(self) -> None:
        """Let go of the spooled lines and packets (a front end's, once archived)."""
        if self._lines is not None:
            self._lines.close()
        self._images.close()
        self._log.close()
