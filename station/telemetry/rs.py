"""Reed–Solomon (255,223) of CCSDS 131.0-B §4, in Berlekamp's dual basis, interleave 4.

The code
    Symbols are GF(2⁸) elements with field polynomial F(x) = x⁸+x⁷+x²+x+1 (0x187) and α a
    root of it. The code generator is g(x) = ∏_{j=112}^{143} (x − β^j) with β = α¹¹
    (CCSDS 131.0-B eq. 4-2): 32 check symbols, up to E = 16 symbol errors corrected per
    codeword. A codeword is sent highest degree first: 223 information symbols, then 32
    check symbols. Each symbol is sent in the dual basis {ℓ0 … ℓ7} of {1, β', …, β'^7},
    β' = α¹¹⁷ (§4.4.2): the bit ``z_i`` of a field element z is Tr(z·β'^i), z0 first (MSB).

Interleaving
    With depth I = 4, symbol k of the 1020-byte code block belongs to codeword k mod 4 at
    position k // 4 (§4.3.7): a burst of up to 64 consecutive bytes costs each codeword at
    most 16 symbols, which it corrects.

How it is fast
    Syndromes and check symbols are GF(2)-linear functions of the received bytes, and so is
    the change of basis. Both are therefore tabulated once per (position, byte value) as
    32-byte rows already in the right basis, and a whole codeword's 32 syndromes are the XOR
    of 255 rows (4 machine words each): about 1 µs per codeword in the numba kernels below,
    against ~8 µs for Horner evaluation of 32 syndromes. Only a codeword whose syndromes are
    not all zero goes through Berlekamp–Massey, Chien search and Forney's formula, which work
    with powers of β so that the code is an ordinary RS code with first root b = 112.
    The kernels copy arrays in loops, not by slice assignment: numba compiles a slice
    copy's shape-mismatch message, about 4 s of the first run after a fresh install.

References
    CCSDS 131.0-B-4, *TM Synchronization and Channel Coding*, §4 and Annex F (dual basis).
"""

from __future__ import annotations

from functools import cache

import numba
import numpy as np
from numpy.typing import NDArray

__all__ = [
    "CHECK",
    "DATA",
    "INTERLEAVE",
    "N",
    "RsTables",
    "decode_block",
    "dual_from_conventional",
    "encode_block",
    "rs_tables",
]

N = 255  # symbols per codeword
DATA = 223  # information symbols per codeword
CHECK = N - DATA  # 32 check symbols, 2E with E = 16
INTERLEAVE = 4
FIELD_POLY = 0x187  # x^8 + x^7 + x^2 + x + 1
FIRST_ROOT = 112  # first consecutive root, in powers of β
BETA_LOG_ALPHA = 11  # β = α^11
DUAL_BETA_LOG_ALPHA = 117  # β' = α^117, whose dual basis carries the bits


class RsTables:
    """Everything the kernels need, computed once (:func:`rs_tables`).

    ``exp_b[i] = β^i`` (i in 0…509, doubled to skip a modulo), ``log_b[x]`` its inverse
    (``log_b[0]`` unused); ``to_dual`` / ``to_conv`` map a conventional byte to the dual basis
    and back; ``syndrome_rows[k, byte]`` are the 32 syndromes contributed by the dual-basis
    ``byte`` at codeword position k (as 4 uint64); ``check_rows[k, byte]`` the 32 dual-basis
    check symbols contributed by information symbol k.
    """

    def __init__(self) -> None:
        alpha = np.zeros(255, np.int64)
        x = 1
        for i in range(255):
            alpha[i] = x
            x <<= 1
            if x & 0x100:
                x ^= FIELD_POLY
        log_a = np.zeros(256, np.int64)
        log_a[alpha] = np.arange(255)
        self.exp_b = alpha[(BETA_LOG_ALPHA * np.arange(510)) % 255]
        self.log_b = np.zeros(256, np.int64)
        self.log_b[self.exp_b[:255]] = np.arange(255)

        def mul(a: NDArray, b: NDArray) -> NDArray:
            a, b = np.broadcast_arrays(np.asarray(a), np.asarray(b))
            out = alpha[(log_a[a] + log_a[b]) % 255]
            return np.where((a == 0) | (b == 0), 0, out)

        def trace(z: NDArray) -> NDArray:
            t, p = np.zeros_like(z), z
            for _ in range(8):
                t ^= p
                p = mul(p, p)
            return t  # 0 or 1

        # Dual-basis bits z_i = Tr(z β'^i), z_0 the most significant (CCSDS Annex F).
        z = np.arange(256)
        bits = [trace(mul(z, alpha[(DUAL_BETA_LOG_ALPHA * i) % 255])) for i in range(8)]
        self.to_dual = np.asarray(sum(b << (7 - i) for i, b in enumerate(bits))).astype(np.uint8)
        self.to_conv = np.zeros(256, np.uint8)
        self.to_conv[self.to_dual] = np.arange(256, dtype=np.uint8)

        conv = self.to_conv.astype(np.int64)
        # Syndromes: S_j = Σ_k r_k β^{(b+j)(254−k)}.
        k = np.arange(N)[:, None, None]
        j = np.arange(CHECK)[None, None, :]
        power = self.exp_b[((FIRST_ROOT + j) * (N - 1 - k)) % 255]
        syn = mul(conv[None, :, None], power)  # (255, 256, 32), conventional values
        self.syndrome_rows = np.ascontiguousarray(syn.astype(np.uint8)).view(np.uint64)

        # Check symbols: x^m mod g(x) for m = 32 … 254, then scaled by each byte value.
        g = np.array([1], np.int64)  # coefficients, highest degree first
        for jj in range(CHECK):
            root = self.exp_b[FIRST_ROOT + jj]
            g = np.concatenate([g, [0]]) ^ np.concatenate([[0], mul(g, root)])
        self.generator = g  # g[0] = 1 … g[32]
        rem = np.zeros((N, CHECK), np.int64)  # rem[m] = x^m mod g, for m >= 32
        r = g[1:].copy()  # x^32 ≡ Σ g_i x^(32-i) over GF(2^8)
        for m in range(CHECK, N):
            rem[m] = r
            lead = r[0]
            r = np.concatenate([r[1:], [0]]) ^ mul(lead, g[1:])
        pos_power = rem[N - 1 - np.arange(DATA)]  # (223, 32): info symbol k has degree 254−k
        chk = mul(conv[None, :, None], pos_power[:, None, :])  # conventional check symbols
        self.check_rows = np.ascontiguousarray(self.to_dual[chk].astype(np.uint8)).view(np.uint64)


@cache
def rs_tables() -> RsTables:
    """The tables, built on first use (about 0.1 s) and shared."""
    return RsTables()


def dual_from_conventional(values: NDArray[np.uint8]) -> NDArray[np.uint8]:
    """Conventional (polynomial-basis) bytes to their dual-basis form (CCSDS Annex F)."""
    return rs_tables().to_dual[np.asarray(values, np.uint8)]


@numba.njit(cache=True, nogil=True)
def _xor_rows(
    rows: NDArray[np.uint64],
    symbols: NDArray[np.uint8],
    stride: int,
    first: int,
    count: int,
    out: NDArray[np.uint64],
) -> None:
    out[:] = 0
    for k in range(count):
        row = rows[k, symbols[first + k * stride]]
        out[0] ^= row[0]
        out[1] ^= row[1]
        out[2] ^= row[2]
        out[3] ^= row[3]


@numba.njit(cache=True, nogil=True)
def _encode_blocks(
    info: NDArray[np.uint8], check_rows: NDArray[np.uint64], out: NDArray[np.uint8]
) -> None:
    """info (n, 223·I) → out (n, 255·I), interleaved: information first, then checks."""
    depth = info.shape[1] // DATA
    acc = np.zeros(4, np.uint64)
    for f in range(info.shape[0]):
        for j in range(DATA * depth):  # a loop, not a slice copy (module note)
            out[f, j] = info[f, j]
        for c in range(depth):
            _xor_rows(check_rows, info[f], depth, c, DATA, acc)
            parity = acc.view(np.uint8)
            for j in range(CHECK):
                out[f, DATA * depth + j * depth + c] = parity[j]


@numba.njit(cache=True, nogil=True)
def _gf_mul(a: int, b: int, exp_b: NDArray[np.int64], log_b: NDArray[np.int64]) -> int:
    if a == 0 or b == 0:
        return 0
    return exp_b[log_b[a] + log_b[b]]


@numba.njit(cache=True, nogil=True)
def _correct(
    syn: NDArray[np.uint8],
    block: NDArray[np.uint8],
    first: int,
    stride: int,
    exp_b: NDArray[np.int64],
    log_b: NDArray[np.int64],
    to_dual: NDArray[np.uint8],
) -> int:
    """Correct one codeword in place from its (conventional) syndromes.

    Returns the number of symbols corrected, or −1 if the errors exceed what the code can
    correct (the codeword is then left as received).
    """
    t2 = CHECK
    s = np.empty(t2, np.int64)
    for j in range(t2):
        s[j] = syn[j]
    # Berlekamp–Massey: the shortest LFSR Λ generating the syndromes.
    lam = np.zeros(t2 + 1, np.int64)
    prev = np.zeros(t2 + 1, np.int64)
    tmp = np.zeros(t2 + 1, np.int64)
    lam[0] = 1
    prev[0] = 1
    length, shift, b_disc = 0, 1, 1
    for n in range(t2):
        d = s[n]
        for i in range(1, length + 1):
            d ^= _gf_mul(lam[i], s[n - i], exp_b, log_b)
        if d == 0:
            shift += 1
            continue
        coef = _gf_mul(d, exp_b[255 - log_b[b_disc]], exp_b, log_b)  # d / b
        for i in range(t2 + 1):  # loops, not slice copies (module note)
            tmp[i] = lam[i]
        for i in range(shift, t2 + 1):
            lam[i] ^= _gf_mul(coef, prev[i - shift], exp_b, log_b)
        if 2 * length <= n:
            length = n + 1 - length
            for i in range(t2 + 1):
                prev[i] = tmp[i]
            b_disc = d
            shift = 1
        else:
            shift += 1
    if length > t2 // 2:
        return -1
    # Chien search: Λ(β^{−e}) = 0 marks an error at degree e (position 254 − e).
    found = 0
    degrees = np.empty(length, np.int64)
    for e in range(N):
        acc = 1
        for i in range(1, length + 1):
            if lam[i] != 0:
                acc ^= exp_b[(log_b[lam[i]] + i * (255 - e)) % 255]
        if acc == 0:
            if found == length:
                return -1
            degrees[found] = e
            found += 1
    if found != length:
        return -1
    # Forney: Y = X^{1−b} Ω(X^{−1}) / Λ'(X^{−1}), Ω = S·Λ mod x^{2E}.
    omega = np.zeros(t2, np.int64)
    for i in range(t2):
        v = 0
        for k in range(min(i, length) + 1):
            v ^= _gf_mul(lam[k], s[i - k], exp_b, log_b)
        omega[i] = v
    for q in range(length):
        e = degrees[q]
        xinv = (255 - e) % 255  # log of X^{-1}
        num = 0
        for i in range(t2):
            if omega[i] != 0:
                num ^= exp_b[(log_b[omega[i]] + i * xinv) % 255]
        den = 0
        for i in range(1, length + 1, 2):  # odd terms of Λ give Λ'(x) x
            if lam[i] != 0:
                den ^= exp_b[(log_b[lam[i]] + (i - 1) * xinv) % 255]
        if den == 0:
            return -1
        if num == 0:
            continue
        log_y = (log_b[num] - log_b[den] + (e * (1 - FIRST_ROOT)) % 255 + 510) % 255
        y = exp_b[log_y]
        block[first + (N - 1 - e) * stride] ^= to_dual[y]
    return length


@numba.njit(cache=True, nogil=True)
def decode_codeblock(
    block: NDArray[np.uint8],
    syndrome_rows: NDArray[np.uint64],
    exp_b: NDArray[np.int64],
    log_b: NDArray[np.int64],
    to_dual: NDArray[np.uint8],
    corrected: NDArray[np.int64],
) -> bool:
    """Decode one interleaved code block (255·I bytes, dual basis) in place.

    ``corrected[c]`` receives the symbols corrected in codeword c, −1 where it failed.
    Returns True when every codeword is now valid.
    """
    depth = block.shape[0] // N
    acc = np.zeros(4, np.uint64)
    ok = True
    for c in range(depth):
        _xor_rows(syndrome_rows, block, depth, c, N, acc)
        if acc[0] == 0 and acc[1] == 0 and acc[2] == 0 and acc[3] == 0:
            corrected[c] = 0
            continue
        n = _correct(acc.view(np.uint8), block, c, depth, exp_b, log_b, to_dual)
        if n > 0:  # confirm: a miscorrection beyond E leaves non-zero syndromes
            _xor_rows(syndrome_rows, block, depth, c, N, acc)
            if acc[0] != 0 or acc[1] != 0 or acc[2] != 0 or acc[3] != 0:
                n = -1
        corrected[c] = n
        if n < 0:
            ok = False
    return ok


def encode_block(info: NDArray[np.uint8]) -> NDArray[np.uint8]:
    """Encode information bytes (…, 223·I) into interleaved code blocks (…, 255·I)."""
    info = np.asarray(info, np.uint8)
    if info.shape[-1] % DATA:
        raise ValueError(f"information length {info.shape[-1]} is not a multiple of {DATA}")
    flat = np.ascontiguousarray(info.reshape(-1, info.shape[-1]))
    depth = flat.shape[1] // DATA
    out = np.empty((flat.shape[0], N * depth), np.uint8)
    _encode_blocks(flat, rs_tables().check_rows, out)
    return out.reshape(*info.shape[:-1], N * depth)


def decode_block(block: NDArray[np.uint8]) -> tuple[NDArray[np.uint8], NDArray[np.int64]]:
    """Decode one interleaved code block (255·I bytes): the corrected block and, per
    codeword, the symbols corrected (−1: uncorrectable, that codeword left as received)."""
    t = rs_tables()
    work = np.array(block, np.uint8, copy=True)
    if work.ndim != 1 or work.size % N:
        raise ValueError(f"a code block is a multiple of {N} bytes, got shape {work.shape}")
    corrected = np.zeros(work.size // N, np.int64)
    decode_codeblock(work, t.syndrome_rows, t.exp_b, t.log_b, t.to_dual, corrected)
    return work, corrected
