"""Frame synchronisation and channel decoding: a recorded bit stream → checked frames.

Synchronisation (:func:`find_cadus`)
    The 32-bit attached sync marker 1ACFFC1D is searched at every bit offset; a candidate
    within ``search_tolerance`` bit errors is taken (*confirmed* when the marker is found
    again one CADU later, *unconfirmed* otherwise). Once locked, the receiver only looks
    where the next marker should be and accepts it with up to ``lock_tolerance`` errors (a
    flywheel). A marker damaged beyond that is still taken if the one after it is in place
    (the marker is not protected by the code, the block often still decodes); otherwise
    the receiver goes back to searching from just after the last marker, so that after a
    fade it re-locks at whatever bit offset the stream resumed.
    With 3 errors allowed in search, a false marker in random data has a probability of
    5489 / 2³² ≈ 1.3·10⁻⁶ per bit position; an unconfirmed frame that then fails the
    Reed–Solomon decoding is classed as a false sync, not as a lost frame.

Decoding (:func:`decode_cadus`)
    Each code block is extracted at its bit offset, derandomised, Reed–Solomon decoded
    (interleave 4) and its transfer frame's CRC checked; all in one compiled pass.
"""

from __future__ import annotations

import numba
import numpy as np
from numpy.typing import NDArray

from station.telemetry import format as tf
from station.telemetry.crc import crc16_kernel, crc_table
from station.telemetry.randomiser import pn_sequence
from station.telemetry.rs import decode_codeblock, rs_tables

__all__ = ["decode_cadus", "find_cadus", "find_more", "horizon_bit", "sync_state"]

_CADU_BITS = 8 * tf.CADU_BYTES


@numba.njit(cache=True, nogil=True)
def _popcount32(x: int) -> int:
    x = x - ((x >> 1) & 0x55555555)
    x = (x & 0x33333333) + ((x >> 2) & 0x33333333)
    x = (x + (x >> 4)) & 0x0F0F0F0F
    return ((x * 0x01010101) & 0xFFFFFFFF) >> 24


@numba.njit(cache=True, nogil=True)
def _word_at(stream: NDArray[np.uint8], bit: int) -> int:
    b = bit >> 3
    s = bit & 7
    w = 0
    for i in range(5):
        w <<= 8
        if b + i < stream.size:
            w |= int(stream[b + i])
    return (w >> (8 - s)) & 0xFFFFFFFF


@numba.njit(cache=True, nogil=True)
def _find(
    stream: NDArray[np.uint8],
    n_bits: int,
    asm: int,
    search_tol: int,
    lock_tol: int,
    offsets: NDArray[np.int64],
    confirmed: NDArray[np.bool_],
) -> tuple[int, int, int]:
    n = 0
    searched = 0
    losses = 0
    pos = 0
    locked = False
    last = -1
    while n < offsets.size:
        if locked:
            expected = last + _CADU_BITS
            if expected + _CADU_BITS > n_bits:
                break
            if _popcount32(_word_at(stream, expected) ^ asm) <= lock_tol:
                offsets[n] = expected
                confirmed[n] = True
                n += 1
                last = expected
                continue
            after = expected + _CADU_BITS  # coast: is the marker after it where it should be?
            if (
                after + _CADU_BITS <= n_bits
                and _popcount32(_word_at(stream, after) ^ asm) <= lock_tol
            ):
                offsets[n] = expected  # a damaged marker; the code block may still decode
                confirmed[n] = True
                n += 1
                last = expected
                continue
            locked = False
            losses += 1
            pos = last + 32
        # search, bit by bit, from pos
        found = -1
        p = pos
        while p + _CADU_BITS <= n_bits:
            if _popcount32(_word_at(stream, p) ^ asm) <= search_tol:
                found = p
                break
            p += 1
        searched += p - pos
        if found < 0:
            break
        nxt = found + _CADU_BITS
        ok = nxt + 32 <= n_bits and _popcount32(_word_at(stream, nxt) ^ asm) <= lock_tol
        offsets[n] = found
        confirmed[n] = ok
        n += 1
        last = found
        locked = True
    return n, searched, losses


def find_cadus(
    stream: NDArray[np.uint8], n_bits: int, search_tolerance: int = 3, lock_tolerance: int = 8
) -> tuple[NDArray[np.int64], NDArray[np.bool_], int, int]:
    """Bit offsets of the CADUs in a stream, whether each was confirmed, the bits scanned
    while searching and the number of times the lock was lost (module docstring)."""
    stream = np.ascontiguousarray(stream, np.uint8)
    n_bits = min(int(n_bits), stream.size * 8)
    cap = 2 * (n_bits // _CADU_BITS) + 16
    while True:  # false markers can be 32 bits apart in noise: grow if ever needed
        offsets = np.zeros(cap, np.int64)
        confirmed = np.zeros(cap, np.bool_)
        n, searched, losses = _find(
            stream, n_bits, tf.ASM_WORD, search_tolerance, lock_tolerance, offsets, confirmed
        )
        if n < cap:
            return offsets[:n], confirmed[:n], int(searched), int(losses)
        cap *= 4


#: The state of a resumable search (:func:`find_more`): where the search stands, whether
#: locked and on which marker, the bits scanned and the losses of lock so far.
POS, LOCKED, LAST, SEARCHED, LOSSES = range(5)


def sync_state() -> NDArray[np.int64]:
    """A search that has seen nothing yet (:func:`find_more`)."""
    return np.array([0, 0, -1, 0, 0], np.int64)


@numba.njit(cache=True, nogil=True)
def _find_more(
    stream: NDArray[np.uint8],
    base: int,
    n_bits: int,
    final: bool,
    asm: int,
    search_tol: int,
    lock_tol: int,
    state: NDArray[np.int64],
    offsets: NDArray[np.int64],
    confirmed: NDArray[np.bool_],
) -> int:
    """:func:`_find` on a stream that arrives piece by piece: ``stream`` holds bits
    ``base`` … ``base + 8·size`` of it, ``n_bits`` of which have arrived; every decision
    that needs a bit not yet arrived waits (``state`` says where) unless ``final`` (the
    stream has ended: the batch's decisions at its end). The same markers, in the same
    order, as :func:`_find` on the whole stream."""
    n = 0
    pos, locked, last = state[POS], state[LOCKED] == 1, state[LAST]
    while n < offsets.size:
        if locked:
            expected = last + _CADU_BITS
            if expected + _CADU_BITS > n_bits:
                break  # the end (final), or wait for the frame
            if _popcount32(_word_at(stream, expected - base) ^ asm) <= lock_tol:
                offsets[n] = expected
                confirmed[n] = True
                n += 1
                last = expected
                continue
            after = expected + _CADU_BITS
            if after + _CADU_BITS > n_bits and not final:
                break  # wait: is the marker after it in place?
            if (
                after + _CADU_BITS <= n_bits
                and _popcount32(_word_at(stream, after - base) ^ asm) <= lock_tol
            ):
                offsets[n] = expected
                confirmed[n] = True
                n += 1
                last = expected
                continue
            locked = False
            state[LOSSES] += 1
            pos = last + 32
        found = -1
        p = pos
        while p + _CADU_BITS <= n_bits:
            if _popcount32(_word_at(stream, p - base) ^ asm) <= search_tol:
                found = p
                break
            p += 1
        state[SEARCHED] += p - pos
        pos = p
        if found < 0:
            break  # nothing more (final), or wait for more bits from p
        nxt = found + _CADU_BITS
        if nxt + 32 > n_bits and not final:
            break  # wait: found again at p, to be confirmed
        ok = nxt + 32 <= n_bits and _popcount32(_word_at(stream, nxt - base) ^ asm) <= lock_tol
        offsets[n] = found
        confirmed[n] = ok
        n += 1
        last = found
        locked = True
    state[POS], state[LOCKED], state[LAST] = pos, 1 if locked else 0, last
    return n


def find_more(
    stream: NDArray[np.uint8],
    base_bit: int,
    n_bits: int,
    final: bool,
    state: NDArray[np.int64],
    search_tolerance: int = 3,
    lock_tolerance: int = 8,
) -> tuple[NDArray[np.int64], NDArray[np.bool_]]:
    """The markers found since the last call of a resumable search (``state``:
    :func:`sync_state`, updated), on ``stream``: bits ``base_bit`` onwards of the whole,
    ``n_bits`` of which have arrived (module docstring; :func:`_find_more`)."""
    stream = np.ascontiguousarray(stream, np.uint8)
    cap = 2 * ((n_bits - int(state[POS])) // _CADU_BITS) + 16
    offsets, confirmed = [], []
    while True:  # false markers can be 32 bits apart in noise: more rounds if ever needed
        o = np.zeros(cap, np.int64)
        c = np.zeros(cap, np.bool_)
        n = _find_more(
            stream,
            int(base_bit),
            int(n_bits),
            bool(final),
            tf.ASM_WORD,
            search_tolerance,
            lock_tolerance,
            state,
            o,
            c,
        )
        offsets.append(o[:n])
        confirmed.append(c[:n])
        if n < cap:
            return np.concatenate(offsets), np.concatenate(confirmed)


def horizon_bit(state: NDArray[np.int64]) -> int:
    """The first bit a resumable search may still read (bits before it can be let go):
    where it searches from, or the marker it is locked on."""
    return int(state[LAST] + 32) if state[LOCKED] == 1 else int(state[POS])


@numba.njit(cache=True, nogil=True)
def _decode(
    stream: NDArray[np.uint8],
    offsets: NDArray[np.int64],
    pn: NDArray[np.uint8],
    syndrome_rows: NDArray[np.uint64],
    exp_b: NDArray[np.int64],
    log_b: NDArray[np.int64],
    to_dual: NDArray[np.uint8],
    table: NDArray[np.uint16],
    blocks: NDArray[np.uint8],
    corrected: NDArray[np.int64],
    rs_ok: NDArray[np.bool_],
    crc_ok: NDArray[np.bool_],
) -> None:
    nb = blocks.shape[1]
    for f in range(offsets.size):
        start = offsets[f] + 32
        b = start >> 3
        s = start & 7
        blk = blocks[f]
        if s == 0:
            for i in range(nb):
                blk[i] = stream[b + i] ^ pn[i]
        else:
            for i in range(nb):
                v = (np.int64(stream[b + i]) << s) & 0xFF
                if b + i + 1 < stream.size:
                    v |= np.int64(stream[b + i + 1]) >> (8 - s)
                blk[i] = v ^ pn[i]
        rs_ok[f] = decode_codeblock(blk, syndrome_rows, exp_b, log_b, to_dual, corrected[f])
        if rs_ok[f]:
            crc = crc16_kernel(blk, tf.FRAME_BYTES - 2, table)
            crc_ok[f] = crc == ((np.int64(blk[tf.FRAME_BYTES - 2]) << 8) | blk[tf.FRAME_BYTES - 1])


def decode_cadus(
    stream: NDArray[np.uint8], offsets: NDArray[np.int64]
) -> tuple[NDArray[np.uint8], NDArray[np.int64], NDArray[np.bool_], NDArray[np.bool_]]:
    """Extract, derandomise, RS-decode and CRC-check the CADUs at ``offsets``.

    Returns the transfer frames (n, 892), the symbols corrected per codeword (n, 4; −1 where
    uncorrectable), whether RS decoding succeeded, and whether the CRC then matched.
    """
    t = rs_tables()
    n = offsets.size
    blocks = np.empty((n, tf.CODE_BLOCK_BYTES), np.uint8)
    corrected = np.zeros((n, 4), np.int64)
    rs_ok = np.zeros(n, np.bool_)
    crc_ok = np.zeros(n, np.bool_)
    _decode(
        np.ascontiguousarray(stream, np.uint8),
        np.asarray(offsets, np.int64),
        np.ascontiguousarray(pn_sequence(tf.CODE_BLOCK_BYTES)),
        t.syndrome_rows,
        t.exp_b,
        t.log_b,
        t.to_dual,
        crc_table(),
        blocks,
        corrected,
        rs_ok,
        crc_ok,
    )
    return blocks[:, : tf.FRAME_BYTES], corrected, rs_ok, crc_ok
