"""The telemetry codecs against published references, and their inverse pairs."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from station.telemetry import dpcm
from station.telemetry.crc import crc16, crc16_rows
from station.telemetry.randomiser import pn_sequence
from station.telemetry.rs import DATA, N, decode_block, encode_block, rs_tables

REFERENCE = Path(__file__).parent / "reference"


def _hex_table(name: str) -> np.ndarray:
    lines = (REFERENCE / name).read_text().splitlines()
    return np.array(
        [int(v, 16) for ln in lines if not ln.startswith("#") for v in ln.split()], np.uint8
    )


# --- Reed–Solomon ------------------------------------------------------------------------

#: CCSDS 131.0-B-4 §4.3.4 / Annex: g(x) coefficients as powers of α, highest degree first
#: (also libfec's CCSDS_poly table). The code is self-reciprocal, hence the symmetry.
CCSDS_GENERATOR_ALPHA_LOGS = [
    0,
    249,
    59,
    66,
    4,
    43,
    126,
    251,
    97,
    30,
    3,
    213,
    50,
    66,
    170,
    5,
    24,
    5,
    170,
    66,
    50,
    213,
    3,
    30,
    97,
    251,
    126,
    43,
    4,
    66,
    59,
    249,
    0,
]
#: Conventional → dual basis for bytes 0…15 (CCSDS 131.0-B Annex F; libfec's Taltab).
CCSDS_DUAL_OF_0_TO_15 = [
    0x00,
    0x7B,
    0xAF,
    0xD4,
    0x99,
    0xE2,
    0x36,
    0x4D,
    0xFA,
    0x81,
    0x55,
    0x2E,
    0x63,
    0x18,
    0xCC,
    0xB7,
]


def _alpha_logs(values: np.ndarray) -> list[int]:
    alpha = [1]
    for _ in range(254):
        x = alpha[-1] << 1
        alpha.append(x ^ 0x187 if x & 0x100 else x)
    log = {v: i for i, v in enumerate(alpha)}
    return [log[int(v)] for v in values]


def test_generator_polynomial_is_the_ccsds_one() -> None:
    assert _alpha_logs(rs_tables().generator) == CCSDS_GENERATOR_ALPHA_LOGS


def test_dual_basis_is_the_ccsds_one() -> None:
    t = rs_tables()
    assert t.to_dual[:16].tolist() == CCSDS_DUAL_OF_0_TO_15
    assert np.array_equal(t.to_conv[t.to_dual], np.arange(256))  # a bijection


def test_known_answer_codeword_dual_basis() -> None:
    codeword = _hex_table("rs_ccsds_dual_basis.txt")
    assert codeword.size == N
    assert np.array_equal(encode_block(codeword[:DATA]), codeword)


def test_known_answer_codeword_conventional_basis() -> None:
    codeword = _hex_table("rs_ccsds_conventional.txt")
    t = rs_tables()
    dual = encode_block(t.to_dual[codeword[:DATA]])
    assert np.array_equal(t.to_conv[dual], codeword)


def test_interleaving_puts_symbol_k_in_codeword_k_mod_4() -> None:
    codeword = _hex_table("rs_ccsds_dual_basis.txt")
    info = np.repeat(codeword[:DATA], 4)  # four identical codewords, interleaved
    block = encode_block(info)
    for c in range(4):
        assert np.array_equal(block[c::4], codeword)


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n_errors=st.integers(0, 16))
def test_up_to_16_symbol_errors_per_codeword_are_corrected(seed: int, n_errors: int) -> None:
    rng = np.random.default_rng(seed)
    block = encode_block(rng.integers(0, 256, 4 * DATA, dtype=np.uint8))
    bad = block.copy()
    for c in range(4):
        pos = rng.choice(N, n_errors, replace=False)
        bad[pos * 4 + c] ^= rng.integers(1, 256, n_errors, dtype=np.uint8)
    fixed, corrected = decode_block(bad)
    assert np.array_equal(fixed, block)
    assert corrected.tolist() == [n_errors] * 4


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n_errors=st.integers(17, 40))
def test_more_than_16_errors_are_reported_not_miscorrected(seed: int, n_errors: int) -> None:
    # A miscorrection needs the errors to land within distance 16 of another codeword:
    # about 1/16! ≈ 5e-14 per codeword, never seen in a test run.
    rng = np.random.default_rng(seed)
    block = encode_block(rng.integers(0, 256, 4 * DATA, dtype=np.uint8))
    bad = block.copy()
    pos = rng.choice(N, n_errors, replace=False)
    bad[pos * 4 + 1] ^= rng.integers(1, 256, n_errors, dtype=np.uint8)
    fixed, corrected = decode_block(bad)
    assert corrected[1] == -1
    assert np.array_equal(fixed[1::4], bad[1::4])  # left as received
    assert corrected[[0, 2, 3]].tolist() == [0, 0, 0]


def test_decode_rejects_a_block_of_the_wrong_size() -> None:
    with pytest.raises(ValueError, match="multiple of 255"):
        decode_block(np.zeros(300, np.uint8))


# --- randomiser, CRC -----------------------------------------------------------------------


def test_randomiser_sequence_is_the_ccsds_one() -> None:
    # CCSDS 131.0-B-4 §10.4.1: the sequence begins 1111 1111 0100 1000 0000 1110 1100 0000
    # 1001 1010 ..., period 255 bits.
    pn = pn_sequence(2 * 255)
    assert pn[:5].tobytes() == bytes.fromhex("FF480EC09A")
    bits = np.unpackbits(pn)
    assert np.array_equal(bits[:255], bits[255:510])
    assert not np.array_equal(bits[:85], bits[85:170])  # and not a shorter period


def test_crc16_check_value() -> None:
    # CRC-16/IBM-3740 (CCITT, preset 0xFFFF) from the catalogue of parametrised CRCs.
    assert crc16(b"123456789") == 0x29B1
    rows = np.frombuffer(b"123456789" * 3, np.uint8).reshape(3, 9)
    assert crc16_rows(rows, 9).tolist() == [0x29B1] * 3


def test_crc16_detects_any_single_bit_flip() -> None:
    data = np.random.default_rng(5).integers(0, 256, 890, dtype=np.uint8)
    ref = crc16(data)
    for bit in range(0, 890 * 8, 97):
        flipped = data.copy()
        flipped[bit // 8] ^= 1 << (bit % 8)
        assert crc16(flipped) != ref


# --- DPCM ----------------------------------------------------------------------------------


def test_dpcm_levels_are_symmetric_and_fit_six_bits() -> None:
    assert dpcm.LEVELS.size == 63
    assert np.array_equal(dpcm.LEVELS, -dpcm.LEVELS[::-1])
    assert np.all(np.diff(dpcm.LEVELS) > 0)
    assert dpcm.LEVELS[31 - 8 : 31 + 9].tolist() == list(range(-8, 9))  # exact near zero


@settings(max_examples=50, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 1600), step=st.integers(0, 120))
def test_dpcm_round_trip(seed: int, n: int, step: int) -> None:
    rng = np.random.default_rng(seed)
    walk = 128 + np.cumsum(rng.integers(-step, step + 1, (4, n)), axis=1)
    x = np.clip(walk, 0, 255).astype(np.uint8)
    payload, recon = dpcm.encode_segments(x)
    assert payload.shape == (4, dpcm.payload_bytes(n))
    assert np.array_equal(dpcm.decode_segments(payload, n), recon)
    err = np.abs(recon.astype(int) - x)
    assert err.max() <= dpcm.MAX_ERROR_COUNTS
    assert np.all(recon[:, 0] == x[:, 0])  # each segment starts exact


def test_dpcm_is_lossless_for_small_differences() -> None:
    rng = np.random.default_rng(3)
    x = np.clip(100 + np.cumsum(rng.integers(-8, 9, (10, 1500)), axis=1), 0, 255)
    payload, recon = dpcm.encode_segments(x.astype(np.uint8))
    assert np.array_equal(recon, x)
    bits_per_pixel = 8 * payload.shape[1] / x.shape[1]
    assert bits_per_pixel == pytest.approx(6.0, abs=0.01)


def test_dpcm_rejects_wrong_payload_size() -> None:
    with pytest.raises(ValueError, match="payload bytes"):
        dpcm.decode_segments(np.zeros((2, 10), np.uint8), 100)
