"""The channel between the sender and the station's recorder: what can go wrong, and truth.

In the order they act:

1. **Replay overlap** (on board, before the link): ``replay_runs`` stretches of
   ``replay_frames`` CADUs are sent a second time right after themselves, as when a tape
   dump overlaps the previous one.
2. **Reordering**: a fraction of CADUs is displaced by 1 … ``reorder_distance`` places.
3. **Random bit errors** at ``ber``, independent.
4. **Bursts** (Gilbert–Elliott): the link enters a bad state at a rate λ(e) = λ₀ / sin²(e)
   per second, e the elevation of the satellite seen from the station (longer path
   through the atmosphere and multipath near the horizon); a bad spell lasts a geometric
   number of bits of mean ``burst_length_bits`` with ``burst_ber`` inside.
5. **Fades**: the demodulator loses lock for an exponential time of mean
   ``fade_duration_ms`` (Poisson arrivals, ``fade_rate_per_min``): that stretch of the
   recording is noise, and since the bit clock is re-acquired the noise is not of the
   same length — the stream slips by a random number of bits, so the receiver has to find
   the frames again at any bit offset. An outage (``outage_start_s``,
   ``outage_duration_s``) is one more fade, placed by hand.

The result is the recorded bit stream (bytes; the last byte may be partly padding) and,
per CADU copy in it, which slot it came from, whether a fade touched it and the largest
number of symbol errors among its four codewords: what a perfect receiver could recover.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np
from numpy.typing import NDArray

from station.scenario import ChannelConfig
from station.telemetry import format as tf

__all__ = ["Reception", "impair"]

_MIN_ELEVATION_RAD = np.radians(1.0)  # below the mask bursts saturate rather than diverge


@dataclass(frozen=True, eq=False)
class Reception:
    """The recorded stream and the truth about each CADU copy in it (in stream order)."""

    stream: NDArray[np.uint8]
    n_bits: int
    copy_slot: NDArray[np.int64]
    copy_faded: NDArray[np.bool_]
    copy_max_symbol_errors: NDArray[np.int64]
    n_bit_errors: int
    n_fades: int
    n_bursts: int


def _frame_order(n: int, cfg: ChannelConfig, rng: np.random.Generator) -> NDArray[np.int64]:
    order = np.arange(n)
    if cfg.replay_runs and n > cfg.replay_frames:
        starts = np.sort(rng.integers(0, n - cfg.replay_frames, cfg.replay_runs))
        pieces, prev = [], 0
        for s in starts:  # one slice per run, not per frame
            end = s + cfg.replay_frames
            pieces += [order[prev:end], order[s:end]]
            prev = max(prev, end)
        pieces.append(order[prev:])
        order = np.concatenate(pieces)
    if cfg.reorder_fraction > 0:
        key = np.arange(order.size, dtype=np.float64)
        moved = rng.random(order.size) < cfg.reorder_fraction
        shift = rng.integers(1, cfg.reorder_distance + 1, moved.sum())
        key[moved] += shift + 0.5
        order = order[np.argsort(key, kind="stable")]
    return order


def _poisson_times(
    rate_per_s: NDArray[np.float64], t_s: NDArray[np.float64], rng: np.random.Generator
) -> NDArray[np.float64]:
    """Arrival times of a Poisson process of varying rate (sampled at ``t_s``), by thinning."""
    top = float(rate_per_s.max(initial=0.0))
    if top <= 0 or t_s.size < 2:
        return np.zeros(0)
    span = t_s[-1] - t_s[0]
    n = rng.poisson(top * span)
    cand = np.sort(t_s[0] + span * rng.random(n))
    keep = rng.random(n) * top < np.interp(cand, t_s, rate_per_s)
    return cand[keep]


@numba.njit(cache=True, nogil=True)
def _copy_bits(
    src: NDArray[np.uint8], src_bit: int, n_bits: int, dst: NDArray[np.uint8], dst_bit: int
) -> None:
    for i in range(n_bits):
        s = src_bit + i
        bit = (src[s >> 3] >> (7 - (s & 7))) & 1
        d = dst_bit + i
        if bit:
            dst[d >> 3] |= np.uint8(1 << (7 - (d & 7)))


def _flip(stream: NDArray[np.uint8], positions: NDArray[np.int64]) -> None:
    positions = np.unique(positions)
    np.bitwise_xor.at(stream, positions >> 3, (1 << (7 - (positions & 7))).astype(np.uint8))


def _bit_errors(
    n_bits: int,
    t_bits: NDArray[np.float64],
    elev: NDArray[np.float64],
    bit_s: float,
    cfg: ChannelConfig,
    rng: np.random.Generator,
) -> tuple[NDArray[np.int64], int]:
    """The bits the channel flips (positions in the stream from ``t_bits[0]``, repeats
    possible) and the number of bursts: random errors at ``cfg.ber``, and bursts (Poisson
    in time, their rate growing as 1/sin² of the elevation ``elev`` at the times
    ``t_bits`` of every CADU copy, geometric lengths, ``burst_ber`` inside)."""
    errors = [
        rng.choice(n_bits, rng.binomial(n_bits, cfg.ber), replace=True)
        if cfg.ber > 0
        else np.zeros(0, np.int64)
    ]
    rate = cfg.burst_rate_per_s / np.sin(np.maximum(elev, _MIN_ELEVATION_RAD)) ** 2
    bursts = _poisson_times(rate, t_bits, rng) if cfg.burst_rate_per_s > 0 else np.zeros(0)
    if bursts.size:
        b0 = ((bursts - t_bits[0]) / bit_s).astype(np.int64)
        length = rng.geometric(1.0 / cfg.burst_length_bits, b0.size)
        hits = rng.binomial(length, cfg.burst_ber)
        owner = np.repeat(np.arange(b0.size), hits)
        pos = b0[owner] + (rng.random(owner.size) * length[owner]).astype(np.int64)
        errors.append(pos[pos < n_bits])
    return np.concatenate(errors).astype(np.int64), int(bursts.size)


def _fades(
    t_bits: NDArray[np.float64], t0_s: float, cfg: ChannelConfig, rng: np.random.Generator
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The fades' start times and durations (Poisson starts over the pass, exponential
    durations) and the scenario's outage (``outage_start_s`` after ``t0_s``), by start."""
    fades = np.zeros(0)
    if cfg.fade_rate_per_min > 0:
        span = (t_bits[0], t_bits[-1])
        fades = np.sort(
            rng.uniform(*span, rng.poisson(cfg.fade_rate_per_min / 60.0 * (span[1] - span[0])))
        )
    lasts = rng.exponential(cfg.fade_duration_s, fades.size) if fades.size else fades
    if cfg.outage_duration_s > 0:
        fades = np.append(fades, t0_s + cfg.outage_start_s)
        lasts = np.append(lasts, cfg.outage_duration_s)
        by_start = np.argsort(fades, kind="stable")
        fades, lasts = fades[by_start], lasts[by_start]
    return fades, lasts


def _splice(
    stream: NDArray[np.uint8],
    n_bits: int,
    fades: NDArray[np.float64],
    lasts: NDArray[np.float64],
    faded: NDArray[np.bool_],
    bit_s: float,
    t0_s: float,
    rng: np.random.Generator,
) -> tuple[NDArray[np.uint8], int]:
    """The stream with each fade's bits (from ``t0_s``) replaced by noise of about the
    same length (the receiver's lock lost, a few bits gained or lost; overlapping fades
    one); ``faded`` marks the CADU copies a fade touches. Returns the new stream and its
    number of bits."""
    cut0 = ((fades - t0_s) / bit_s).astype(np.int64)
    cut1 = cut0 + (lasts / bit_s).astype(np.int64)
    cut0, cut1 = np.clip(cut0, 0, n_bits), np.clip(cut1, 0, n_bits)
    keep = np.concatenate([[True], cut0[1:] >= np.maximum.accumulate(cut1)[:-1]])
    group = np.flatnonzero(keep)  # overlapping fades merge into the first: one, longer
    cut0, cut1 = cut0[keep], np.maximum.reduceat(cut1, group)
    noise_len = np.maximum(cut1 - cut0 + rng.integers(-7, 8, cut0.size), 0)
    first_copy = cut0 // (8 * tf.CADU_BYTES)
    last_copy = (np.maximum(cut1, cut0 + 1) - 1) // (8 * tf.CADU_BYTES)
    span_copies = np.concatenate(
        [np.arange(a, b + 1) for a, b in zip(first_copy, last_copy, strict=True)]
    )
    faded[np.minimum(span_copies, faded.size - 1)] = True
    out_bits = n_bits - int((cut1 - cut0).sum()) + int(noise_len.sum())
    out = np.zeros((out_bits + 7) // 8, np.uint8)
    src, dst = 0, 0
    for a, b, m in zip(cut0, cut1, noise_len, strict=True):  # one splice per fade
        _copy_bits(stream, src, int(a - src), out, dst)
        dst += int(a - src)
        noise = rng.integers(0, 256, (int(m) + 7) // 8, dtype=np.uint8)
        _copy_bits(noise, 0, int(m), out, dst)
        dst += int(m)
        src = int(b)
    _copy_bits(stream, src, n_bits - src, out, dst)
    return out, out_bits


def impair(
    cadus: NDArray[np.uint8],
    slot_t_s: NDArray[np.float64],
    elevation_rad: NDArray[np.float64],
    cfg: ChannelConfig,
    bit_rate_bit_per_s: float,
    rng: np.random.Generator,
) -> Reception:
    """Send CADUs (n, 1024) through the channel (module docstring).

    ``elevation_rad`` is the satellite's elevation at each slot time; the stream's time runs
    at ``bit_rate_bit_per_s`` from the first slot.
    """
    order = _frame_order(cadus.shape[0], cfg, rng)
    stream = np.ascontiguousarray(cadus[order]).ravel()
    n_bits = stream.size * 8
    bit_s = 1.0 / bit_rate_bit_per_s
    t_bits = slot_t_s[0] + np.arange(0, n_bits + 1, 8 * tf.CADU_BYTES) * bit_s
    elev = np.interp(t_bits, slot_t_s, elevation_rad)
    err, n_bursts = _bit_errors(n_bits, t_bits, elev, bit_s, cfg, rng)
    _flip(stream, err)

    # Symbol errors per CADU copy and codeword: what a perfect receiver would face.
    byte = np.unique(err >> 3)
    in_cadu = byte % tf.CADU_BYTES
    block = byte[in_cadu >= 4]
    key = (block // tf.CADU_BYTES) * 4 + (block % tf.CADU_BYTES - 4) % 4
    per_word = np.bincount(key, minlength=order.size * 4).reshape(order.size, 4)
    max_sym = per_word.max(axis=1)

    fades, lasts = _fades(t_bits, slot_t_s[0], cfg, rng)
    faded = np.zeros(order.size, bool)
    if fades.size:
        stream, n_bits = _splice(stream, n_bits, fades, lasts, faded, bit_s, slot_t_s[0], rng)
    return Reception(
        stream=stream,
        n_bits=n_bits,
        copy_slot=order,
        copy_faded=faded,
        copy_max_symbol_errors=max_sym,
        n_bit_errors=int(np.unique(err).size),
        n_fades=int(fades.size),
        n_bursts=n_bursts,
    )
