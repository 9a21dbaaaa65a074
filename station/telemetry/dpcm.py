"""Closed-loop DPCM of panchromatic line segments: 8-bit counts to 6-bit codes.

SPOT compressed the P lines on board by DPCM to about 6 bits per pixel to fit a 25 Mbit/s
channel (DESIGN.md). The exact SPOT quantiser is not public; this one is documented in
``docs/telemetry.md`` and built the classic way:

* prediction: the previous *reconstructed* pixel of the segment (closed loop, so that the
  encoder and the decoder predict from the same values and errors never accumulate);
* the first pixel of a segment is sent as is (8 bits), so that each segment decodes on its
  own and a lost packet costs only its own pixels;
* the prediction error d = x − p is coded on 6 bits by a symmetric non-uniform quantiser:
  exact for |d| ≤ 8 (flat and textured ground), then levels growing by about 16 % up to 255
  (edges), 63 levels in all (code 63 is unused);
* the encoder picks, among all 63 codes, the one whose *clipped* reconstruction
  clip(p + q, 0, 255) is closest to x: both tables, code[p, x] and reconstruction[p, c],
  are tabulated once (256 × 256 and 256 × 64), so coding is two lookups per pixel.

The largest possible error is :data:`MAX_ERROR_COUNTS`, half the widest gap between levels;
on the emulated scenes the error is zero for most pixels (measured figures in
``docs/telemetry.md``). Codes are packed 4 to 3 bytes, most significant bit first.
"""

from __future__ import annotations

from functools import cache

import numba
import numpy as np
from numpy.typing import NDArray

__all__ = [
    "LEVELS",
    "MAX_ERROR_COUNTS",
    "decode_segments",
    "encode_segments",
    "payload_bytes",
    "reconstruction_table",
]


def _levels() -> NDArray[np.int64]:
    exact = np.arange(1, 9)
    grown = np.round(9.5 * 1.161 ** np.arange(23)).astype(np.int64)
    grown[-1] = 255
    positive = np.concatenate([exact, grown])  # 31 levels, strictly increasing
    return np.concatenate([-positive[::-1], [0], positive])  # 63 levels, code 0 … 62


#: Reconstruction levels of the prediction error, by code (63 codes; 63 unused).
LEVELS = _levels()
#: Largest reconstruction error the quantiser can make (counts), at a jump of ~240 counts.
MAX_ERROR_COUNTS = int(np.max(np.diff(LEVELS)) // 2)


@cache
def reconstruction_table() -> tuple[NDArray[np.uint8], NDArray[np.uint8]]:
    """(code[p, x], value[p, c]): the code for pixel x after prediction p, and the pixel a
    decoder reconstructs from prediction p and code c (code 63 repeats the prediction)."""
    p = np.arange(256)[:, None]
    value = np.clip(p + LEVELS[None, :], 0, 255)  # (256, 63)
    x = np.arange(256)
    err = np.abs(value[:, None, :] - x[None, :, None])  # (p, x, c)
    code = np.argmin(err, axis=2).astype(np.uint8)
    value64 = np.concatenate([value, p], axis=1).astype(np.uint8)  # code 63 → p
    return code, value64


def payload_bytes(n_pixels: int | NDArray[np.int64]) -> int | NDArray[np.int64]:
    """Bytes of a coded segment of ``n_pixels`` (int or array): 1 raw byte, then 6 bits
    per pixel."""
    return 1 + (6 * (n_pixels - 1) + 7) // 8


@numba.njit(cache=True, nogil=True)
def _encode(
    segments: NDArray[np.uint8],
    code: NDArray[np.uint8],
    value: NDArray[np.uint8],
    out: NDArray[np.uint8],
    recon: NDArray[np.uint8],
) -> None:
    n = segments.shape[1]
    for s in range(segments.shape[0]):
        x = segments[s]
        p = x[0]
        out[s, 0] = p
        recon[s, 0] = p
        acc = 0
        nbits = 0
        pos = 1
        for i in range(1, n):
            c = code[p, x[i]]
            p = value[p, c]
            recon[s, i] = p
            acc = (acc << 6) | c
            nbits += 6
            if nbits >= 8:
                nbits -= 8
                out[s, pos] = (acc >> nbits) & 0xFF
                pos += 1
        if nbits > 0:
            out[s, pos] = (acc << (8 - nbits)) & 0xFF


@numba.njit(cache=True, nogil=True)
def decode_one(
    payload: NDArray[np.uint8], first: int, n: int, value: NDArray[np.uint8], out: NDArray[np.uint8]
) -> None:
    """Decode one segment of ``n`` pixels from ``payload[first:]`` into ``out[:n]``."""
    p = payload[first]
    out[0] = p
    acc = 0
    nbits = 0
    pos = first + 1
    for i in range(1, n):
        while nbits < 6:
            acc = ((acc << 8) | payload[pos]) & 0xFFFF
            pos += 1
            nbits += 8
        nbits -= 6
        c = (acc >> nbits) & 0x3F
        p = value[p, c]
        out[i] = p


@numba.njit(cache=True, nogil=True)
def _decode(
    payloads: NDArray[np.uint8], n: int, value: NDArray[np.uint8], out: NDArray[np.uint8]
) -> None:
    for s in range(payloads.shape[0]):
        decode_one(payloads[s], 0, n, value, out[s])


def encode_segments(segments: NDArray[np.uint8]) -> tuple[NDArray[np.uint8], NDArray[np.uint8]]:
    """Code segments (m, n) of 8-bit counts: the payloads (m, payload_bytes(n)) and what the
    decoder will reconstruct (m, n), which is what the ground receives."""
    segments = np.ascontiguousarray(segments, np.uint8)
    m, n = segments.shape
    if n < 1:
        raise ValueError("a DPCM segment has at least one pixel")
    code, value = reconstruction_table()
    out = np.zeros((m, payload_bytes(n)), np.uint8)
    recon = np.empty((m, n), np.uint8)
    _encode(segments, code, value, out, recon)
    return out, recon


def decode_segments(payloads: NDArray[np.uint8], n_pixels: int) -> NDArray[np.uint8]:
    """Decode payloads (m, payload_bytes(n)) into segments (m, n)."""
    payloads = np.ascontiguousarray(payloads, np.uint8)
    if payloads.shape[1] != payload_bytes(n_pixels):
        raise ValueError(
            f"{n_pixels} pixels need {payload_bytes(n_pixels)} payload bytes, "
            f"got {payloads.shape[1]}"
        )
    _code, value = reconstruction_table()
    out = np.empty((payloads.shape[0], n_pixels), np.uint8)
    _decode(payloads, n_pixels, value, out)
    return out
