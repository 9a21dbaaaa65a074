"""Hostile inputs for the receiver: random bytes, and mutations of a real stream.

Random mutations of a CADU stream mostly die at the Reed–Solomon decoder, which is what it
is for; to reach the packet parser with garbage, some mutations change a transfer frame's
contents and then re-encode it (CRC, RS, randomiser, marker), so that the receiver accepts
the frame and must survive whatever it holds: absurd packet lengths, header pointers,
APIDs, auxiliary records, status tables, channel ids and counts.

Used by ``tools/fuzz_receiver.py`` (100 000 inputs) and by the tests (a few dozen).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from station.spacecraft.downlink import frames_to_cadus
from station.telemetry import format as tf
from station.telemetry.crc import crc16_rows
from station.telemetry.randomiser import pn_sequence

__all__ = ["MUTATORS", "frames_of", "mutate"]

Mutator = Callable[[NDArray[np.uint8], np.random.Generator], NDArray[np.uint8]]


def frames_of(cadus: NDArray[np.uint8]) -> NDArray[np.uint8]:
    """The transfer frames (n, 892) inside clean CADUs (n, 1024): the code is systematic,
    so a frame is the first 892 bytes of its derandomised code block."""
    return cadus[:, 4 : 4 + tf.FRAME_BYTES] ^ pn_sequence(tf.FRAME_BYTES)


def _reencode(frames: NDArray[np.uint8]) -> NDArray[np.uint8]:
    crc = crc16_rows(frames, tf.FRAME_BYTES - 2)
    frames[:, -2] = crc >> 8
    frames[:, -1] = crc & 0xFF
    return frames_to_cadus(frames).ravel()


def _span(n: int, rng: np.random.Generator, most: int) -> tuple[int, int]:
    a = int(rng.integers(0, max(n, 1)))
    return a, min(n, a + int(rng.integers(1, most + 1)))


def _random_bytes(s: NDArray, rng: np.random.Generator) -> NDArray:
    return rng.integers(0, 256, int(rng.integers(0, 40_000)), dtype=np.uint8)


def _overwrite(s: NDArray, rng: np.random.Generator) -> NDArray:
    s = s.copy()
    for _ in range(int(rng.integers(1, 6))):
        a, b = _span(s.size, rng, 5000)
        s[a:b] = rng.integers(0, 256, b - a, dtype=np.uint8)
    return s


def _cut(s: NDArray, rng: np.random.Generator) -> NDArray:
    a, b = _span(s.size, rng, 20_000)
    return np.concatenate([s[:a], s[b:]])


def _repeat(s: NDArray, rng: np.random.Generator) -> NDArray:
    a, b = _span(s.size, rng, 20_000)
    return np.concatenate([s[:b], s[a:b], s[a:b], s[b:]])


def _slip(s: NDArray, rng: np.random.Generator) -> NDArray:
    a = int(rng.integers(0, s.size))
    bits = np.unpackbits(s[a:])
    k = int(rng.integers(1, 8))
    tail = (
        bits[k:]
        if rng.random() < 0.5
        else np.concatenate([rng.integers(0, 2, k, dtype=np.uint8), bits])
    )
    return np.concatenate([s[:a], np.packbits(tail)])


def _bit_storm(s: NDArray, rng: np.random.Generator) -> NDArray:
    s = s.copy()
    ber = 10 ** rng.uniform(-4, -0.3)
    flips = rng.random(s.size * 8) < ber
    return s ^ np.packbits(flips)[: s.size]


def _truncate(s: NDArray, rng: np.random.Generator) -> NDArray:
    return s[: int(rng.integers(0, s.size + 1))]


def _marker_spam(s: NDArray, rng: np.random.Generator) -> NDArray:
    n = int(rng.integers(1, 3000))
    spam = np.tile(tf.ASM, n)
    a = int(rng.integers(0, s.size + 1))
    return np.concatenate([s[:a], spam, s[a:]])


def _valid_garbage(s: NDArray, rng: np.random.Generator, frames: NDArray) -> NDArray:
    """Frames that pass RS and CRC but hold random or mutated contents."""
    f = frames.copy()
    rows = rng.choice(f.shape[0], min(f.shape[0], int(rng.integers(1, 20))), replace=False)
    for r in rows:
        kind = rng.integers(0, 4)
        if kind == 0:  # the whole frame random
            f[r, :-2] = rng.integers(0, 256, tf.FRAME_BYTES - 2, dtype=np.uint8)
        elif kind == 1:  # the header only: any channel, count and pointer, our spacecraft
            f[r, 2:8] = rng.integers(0, 256, 6, dtype=np.uint8)
            word = (1 << 14) | (tf.SPACECRAFT_ID << 6) | int(rng.integers(0, 64))
            f[r, 0], f[r, 1] = word >> 8, word & 0xFF
        else:  # a few bytes of the packet zone
            pos = rng.integers(8, tf.FRAME_BYTES - 2, int(rng.integers(1, 12)))
            f[r, pos] = rng.integers(0, 256, pos.size, dtype=np.uint8)
    return _reencode(f)


MUTATORS: dict[str, Mutator] = {
    "random_bytes": _random_bytes,
    "overwrite": _overwrite,
    "cut": _cut,
    "repeat": _repeat,
    "slip": _slip,
    "bit_storm": _bit_storm,
    "truncate": _truncate,
    "marker_spam": _marker_spam,
}


def mutate(
    stream: NDArray[np.uint8], frames: NDArray[np.uint8], rng: np.random.Generator
) -> tuple[str, NDArray[np.uint8]]:
    """One hostile input: its kind and its bytes. Half start from frames with valid codes
    and garbage inside; then 0 to 2 stream mutations are stacked."""
    chosen, s = [], stream
    if rng.random() < 0.5:
        chosen.append("valid_garbage")
        s = _valid_garbage(stream, rng, frames)
    names = list(MUTATORS)
    for _ in range(int(rng.integers(0 if chosen else 1, 3))):
        name = names[int(rng.integers(0, len(names)))]
        chosen.append(name)
        s = MUTATORS[name](s, rng)
    return "+".join(chosen), np.ascontiguousarray(s, np.uint8)
