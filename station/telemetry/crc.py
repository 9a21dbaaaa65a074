"""The frame error control field: CRC-16-CCITT (CCSDS 132.0-B / 732.0-B §4.1.6).

Generator x¹⁶ + x¹² + x⁵ + 1 (0x1021), register preset to all ones, no reflection, no final
XOR (the "CRC-16/IBM-3740" of the CRC catalogues; check value 0x29B1 for b"123456789").
A table of 256 entries makes it one lookup per byte.
"""

from __future__ import annotations

from functools import cache

import numba
import numpy as np
from numpy.typing import NDArray

__all__ = ["crc16", "crc16_rows", "crc_table"]

_POLY = 0x1021


@cache
def crc_table() -> NDArray[np.uint16]:
    """CRC of each byte value shifted into a zero register."""
    reg = np.arange(256, dtype=np.uint32) << 8
    for _ in range(8):
        reg = np.where(reg & 0x8000, (reg << 1) ^ _POLY, reg << 1) & 0xFFFF
    return reg.astype(np.uint16)


@numba.njit(cache=True, nogil=True)
def crc16_kernel(data: NDArray[np.uint8], length: int, table: NDArray[np.uint16]) -> int:
    reg = 0xFFFF
    for i in range(length):
        reg = ((reg << 8) & 0xFFFF) ^ table[((reg >> 8) ^ data[i]) & 0xFF]
    return reg


@numba.njit(cache=True, nogil=True)
def _crc_rows(
    rows: NDArray[np.uint8], length: int, table: NDArray[np.uint16], out: NDArray[np.uint16]
) -> None:
    for r in range(rows.shape[0]):
        out[r] = crc16_kernel(rows[r], length, table)


def crc16(data: bytes | NDArray[np.uint8]) -> int:
    """CRC-16-CCITT of a byte string."""
    arr = np.frombuffer(bytes(data), np.uint8) if not isinstance(data, np.ndarray) else data
    arr = np.ascontiguousarray(arr, np.uint8)
    return int(crc16_kernel(arr, arr.size, crc_table()))


def crc16_rows(rows: NDArray[np.uint8], length: int) -> NDArray[np.uint16]:
    """CRC of the first ``length`` bytes of every row of a (n, m) byte array."""
    rows = np.ascontiguousarray(rows, np.uint8)
    out = np.empty(rows.shape[0], np.uint16)
    _crc_rows(rows, length, crc_table(), out)
    return out
