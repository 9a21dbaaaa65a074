"""The downlink end to end: sender → impaired channel → receiver → L0 archive → reader.

The sender's truth says which data frames each image packet occupies; the receiver must
account for every frame sent, mask exactly the segments whose packets touched a lost frame,
and deliver every other segment as sent (bit for bit in XS; the DPCM reconstruction in P).
"""

from __future__ import annotations

import dataclasses

import h5py
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from levels.errors import L0Error
from levels.readers.l0 import read_l0
from station.chain.fuzzing import frames_of, mutate
from station.chain.report import expected_valid, lost_data_frames
from station.chain.session import downlink, record
from station.scenario import scenario_from_dict
from station.spacecraft.channel import impair
from station.spacecraft.downlink import transmit
from station.spacecraft.emulator import emulate
from station.srrs.frames import find_cadus
from station.srrs.receiver import ReceiverError, receive
from station.telemetry import dpcm
from station.telemetry import format as tf

#: Line times come from 1 ms time codes fitted over the strip: the fit is good to a small
#: fraction of a millisecond (this project's recovery, station.srrs.clock). 0.1 ms is 0.66 m of
#: along-track ground motion at 6.6 km/s, a fifteenth of a P pixel.
LINE_TIME_TOL_S = 1e-4
ELEVATION_RAD = np.radians(40.0)

_DOWN = {"bit_rate_mbps": 0.25, "preamble_s": 0.05, "postamble_s": 0.05}
_P = {
    "name": "p",
    "seed": 11,
    "instrument": {"n_detectors": 300, "n_lines": 240},
    "downlink": _DOWN,
    "gcps": {"count": 2},
}
_XS = {
    "name": "xs",
    "seed": 12,
    "instrument": {"mode": "XS", "n_detectors": 160, "n_lines": 120, "hrv": 2},
    "downlink": {**_DOWN, "first_frame_count": 2**24 - 40},
    "gcps": {"count": 2},
}


@pytest.fixture(scope="module")
def acq_p():
    return emulate(scenario_from_dict(_P))


@pytest.fixture(scope="module")
def acq_xs():
    return emulate(scenario_from_dict(_XS))


def _send(acq, seed: int = 1, **channel):
    scn = acq.scenario
    tx = transmit(acq, scn.downlink, np.random.default_rng(seed))
    cfg = dataclasses.replace(scn.channel, **channel)
    elev = np.full(tx.slot_t_s.size, ELEVATION_RAD)
    rx = impair(
        tx.cadus, tx.slot_t_s, elev, cfg, tx.bit_rate_bit_per_s, np.random.default_rng(seed + 1)
    )
    return tx, rx, receive(rx.stream, rx.n_bits)


# --- clean channel ---------------------------------------------------------------------------


def test_clean_channel_xs_is_bit_for_bit(acq_xs) -> None:
    _tx, _rx, d = _send(acq_xs, ber=0.0, burst_rate_per_s=0.0)
    assert d.status_counts["uncorrectable"] == 0 and d.status_counts["false_sync"] == 0
    for b, band in enumerate(acq_xs.bands):
        assert np.array_equal(d.images[b], band.counts)  # XS is sent raw
        assert d.valid[b].all()
    assert d.mode == "XS" and d.hrv == 2 and len(d.images) == 3


def test_clean_channel_p_is_the_dpcm_reconstruction(acq_p) -> None:
    tx, _rx, d = _send(acq_p, ber=0.0, burst_rate_per_s=0.0)
    raw = acq_p.bands[0].counts
    assert np.array_equal(d.images[0], tx.ground_bands[0])
    assert np.abs(d.images[0].astype(int) - raw).max() <= dpcm.MAX_ERROR_COUNTS
    assert d.valid[0].all()


def test_frame_counts_wrap_at_24_bits(acq_xs) -> None:
    tx, _rx, d = _send(acq_xs, ber=0.0, burst_rate_per_s=0.0)
    assert tx.count[tx.vc == tx.data_vc].min() == 0  # it did wrap
    acc = d.accounts[tx.data_vc]
    assert (acc.sent, acc.lost, acc.gaps) == (tx.sent[tx.data_vc], 0, 0)


def test_line_times_and_gyros_come_back(acq_p) -> None:
    _tx, _rx, d = _send(acq_p, ber=0.0, burst_rate_per_s=0.0)
    assert d.epoch_utc == acq_p.epoch.t0_utc
    err = d.line_t_s - acq_p.line_times_s
    assert np.abs(err).max() < LINE_TIME_TOL_S
    mid = err.size // 2
    assert abs(err[mid]) <= d.line_clock_uncertainty_s  # the truth is where the codes allow
    assert d.line_period_s == pytest.approx(acq_p.hrv.line_period_s, rel=1e-4)
    assert np.array_equal(d.aux_t_s, np.floor(acq_p.gyros.t_s * 1e3 + 1e-6) / 1e3)
    assert np.allclose(
        d.gyro_rates_rad_per_s, acq_p.gyros.rates_rad_per_s, rtol=0, atol=1e-15
    )  # quantised on board, sent as counts of the LSB


# --- impaired channel: accounting and masks ---------------------------------------------------

HARSH = dict(
    burst_rate_per_s=4.0,
    burst_length_bits=600.0,
    burst_ber=0.1,
    fade_rate_per_min=40.0,
    fade_duration_s=0.03,
    replay_runs=3,
    replay_frames=8,
    reorder_fraction=0.05,
    reorder_distance=3,
)


@pytest.mark.parametrize("ber", [1e-7, 1e-6, 1e-5, 1e-4, 1e-3])
@pytest.mark.parametrize("which", ["p", "xs"])
def test_every_frame_accounted_and_every_lost_segment_masked(acq_p, acq_xs, which, ber):
    acq = acq_p if which == "p" else acq_xs
    tx, rx, d = _send(acq, seed=int(ber * 1e9) % 97, ber=ber, **HARSH)
    for vc, sent in tx.sent.items():
        acc = d.accounts[vc]
        assert acc.head_known and acc.tail_known
        assert acc.sent == sent
        assert acc.delivered + acc.lost == sent
    lost = lost_data_frames(tx, d)
    assert lost.size == d.accounts[tx.data_vc].lost
    n_lines = acq.line_times_s.size
    expected = expected_valid(tx, lost, n_lines)
    assert np.array_equal(np.stack(d.valid), expected)  # masked exactly where touched
    for b in range(len(acq.bands)):
        ok = d.pixel_valid(b)
        assert np.array_equal(d.images[b][ok], tx.ground_bands[b][ok])  # nothing silent
        assert not d.images[b][~ok].any()  # nothing invented
    counts = d.status_counts
    assert sum(counts.values()) == d.frame_status.size
    assert rx.n_fades > 0 and counts["duplicate"] > 0


def test_no_decodable_frame_is_lost_without_fades(acq_p) -> None:
    tx, rx, d = _send(acq_p, seed=5, ber=2e-4, burst_rate_per_s=3.0, fade_rate_per_min=0.0)
    decodable = np.zeros(tx.cadus.shape[0], bool)
    decodable[rx.copy_slot[rx.copy_max_symbol_errors <= 16]] = True
    data_slots = np.flatnonzero(tx.vc == tx.data_vc)
    lost = lost_data_frames(tx, d)
    assert not decodable[data_slots[lost]].any()
    assert (~decodable[data_slots]).sum() == lost.size


@pytest.mark.parametrize("random_fades", [0.0, 600.0])
def test_an_outage_loses_the_frames_under_it_and_only_those(acq_p, random_fades) -> None:
    """A scenario's outage is one fade placed by hand: the copies sent while it lasts are
    noise, all of them (also when random fades overlap it), and nothing else is lost."""
    frame_s = 8 * tf.CADU_BYTES / (_DOWN["bit_rate_mbps"] * 1e6)
    span = acq_p.line_times_s[-1] - acq_p.line_times_s[0]
    start, length = 0.3 * span, 0.2 * span
    tx, rx, d = _send(
        acq_p,
        seed=3,
        ber=0.0,
        burst_rate_per_s=0.0,
        outage_start_s=start,
        outage_duration_s=length,
        fade_rate_per_min=random_fades,
        fade_duration_s=0.01,
    )
    faded = np.flatnonzero(rx.copy_faded)
    under = np.arange(
        np.ceil(start / frame_s), np.floor((start + length) / frame_s) - 1, dtype=int
    )  # copies wholly inside the outage
    assert np.isin(under, faded).all()  # every copy under the outage is lost
    if not random_fades:  # and the outage alone loses no copy beyond its edges
        assert faded.min() >= under[0] - 1 and faded.max() <= under[-1] + 2
    lost = lost_data_frames(tx, d)
    data = np.flatnonzero(tx.vc == tx.data_vc)
    assert np.isin(data[lost], rx.copy_slot[faded]).all()  # nothing lost outside fades
    data_under = np.intersect1d(rx.copy_slot[under], data)
    assert data_under.size and np.isin(data_under, data[lost]).all()  # and those are lost


def test_markers_are_found_at_any_bit_offset(acq_xs) -> None:
    tx = transmit(acq_xs, acq_xs.scenario.downlink, np.random.default_rng(1))
    rng = np.random.default_rng(9)
    cadus = tx.cadus[:6].ravel()
    for shift in range(8):
        noise_bits = 8 * 37 + shift
        bits = np.concatenate(
            [rng.integers(0, 2, noise_bits, dtype=np.uint8), np.unpackbits(cadus)]
        )
        offsets, confirmed, _searched, _losses = find_cadus(np.packbits(bits), bits.size)
        assert offsets.tolist() == [noise_bits + 8192 * k for k in range(6)]
        assert confirmed[:5].all()


def test_markers_with_a_few_bit_errors_are_still_found(acq_xs) -> None:
    tx = transmit(acq_xs, acq_xs.scenario.downlink, np.random.default_rng(1))
    stream = tx.cadus[:7].ravel().copy()

    def damage(frame: int, n_bits: int) -> None:
        bits = np.unpackbits(stream[frame * 1024 : frame * 1024 + 4])
        bits[:n_bits] ^= 1
        stream[frame * 1024 : frame * 1024 + 4] = np.packbits(bits)

    damage(0, 3)  # found by search (≤ 3 errors)
    damage(2, 12)  # beyond the lock tolerance, but the next marker is in place: coasted
    damage(3, 5)  # accepted while locked (≤ 8)
    damage(4, 12)
    damage(5, 12)  # two in a row: lock lost
    damage(6, 2)  # found again by search
    offsets, confirmed, _s, losses = find_cadus(stream, stream.size * 8)
    assert offsets.tolist() == [8192 * k for k in (0, 1, 2, 3, 6)]
    assert losses == 1 and confirmed[:4].all()


@settings(
    max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(
    seed=st.integers(0, 2**31),
    log_ber=st.floats(-7.0, -3.0),
    bursts=st.floats(0.0, 10.0),
    fades=st.floats(0.0, 80.0),
    replays=st.integers(0, 4),
    reorder=st.floats(0.0, 0.1),
)
def test_round_trip_property(acq_xs, seed, log_ber, bursts, fades, replays, reorder) -> None:
    """Whatever the channel does: accounts balance, masks are exactly the segments touched
    by lost frames, and every valid pixel is what was sent."""
    tx, _rx, d = _send(
        acq_xs,
        seed=seed,
        ber=10.0**log_ber,
        burst_rate_per_s=bursts,
        fade_rate_per_min=fades,
        replay_runs=replays,
        replay_frames=5,
        reorder_fraction=reorder,
    )
    for vc, acc in d.accounts.items():
        assert acc.delivered + acc.lost == acc.sent
        if acc.tail_known:
            assert acc.sent == tx.sent[vc]
    lost = lost_data_frames(tx, d)
    assert np.array_equal(np.stack(d.valid), expected_valid(tx, lost, d.line_counter.size))
    for b in range(3):
        ok = d.pixel_valid(b)
        assert np.array_equal(d.images[b][ok], tx.ground_bands[b][ok])


# --- bad input --------------------------------------------------------------------------------


def test_noise_alone_is_an_error_not_a_crash() -> None:
    noise = np.random.default_rng(0).integers(0, 256, 200_000, dtype=np.uint8)
    with pytest.raises(ReceiverError, match="no data frame"):
        receive(noise)


@pytest.fixture(scope="module")
def clean_stream(acq_xs):
    tx = transmit(acq_xs, acq_xs.scenario.downlink, np.random.default_rng(1))
    return tx.cadus.ravel(), frames_of(tx.cadus)


@pytest.mark.parametrize("seed", range(40))
def test_fuzz_mutated_streams(clean_stream, seed: int) -> None:
    """Hostile inputs (tools/fuzz_receiver.py runs 100 000): a result whose accounts
    balance, or a ReceiverError; nothing else."""
    stream, frames = clean_stream
    _kind, data = mutate(stream, frames, np.random.default_rng([7, seed]))
    try:
        d = receive(data)
    except ReceiverError:
        return
    for acc in d.accounts.values():
        assert acc.delivered + acc.lost == acc.sent


# --- L0 archive -------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def l0_path(acq_xs, tmp_path_factory):
    res = downlink(acq_xs)
    return record(acq_xs, res, tmp_path_factory.mktemp("l0") / "pass.h5"), res


def test_l0_round_trip(acq_xs, l0_path) -> None:
    path, res = l0_path
    l0 = read_l0(path)
    d = res.decoded
    assert list(l0.bands) == ["XS1", "XS2", "XS3"]
    for b, name in enumerate(l0.bands):
        band = l0.bands[name]
        assert np.array_equal(band.counts, d.images[b])
        assert np.array_equal(band.valid, d.valid[b])
        assert band.pixel_valid().shape == band.counts.shape
        nominal = acq_xs.hrv.bands[b].look_nominal
        assert np.array_equal(band.look.psi_y_rad, nominal.psi_y_rad)
    assert np.array_equal(l0.line_t_s, d.line_t_s)
    assert l0.epoch.t0_utc == acq_xs.epoch.t0_utc
    assert np.array_equal(l0.ephemeris.r_ecef_m, acq_xs.bulletins.r_ecef_m)
    assert np.array_equal(l0.ephemeris.t_s, acq_xs.bulletins.t_s)
    ch = l0.decode["channels"][f"vc{tf.vc_of_hrv(2):02d}"]
    assert ch["sent"] == res.transmission.sent[2]
    assert sum(l0.decode["status_counts"].values()) == d.frame_status.size
    assert not any(p.name.endswith(".tmp") for p in path.parent.iterdir())


def test_l0_truncated_is_rejected(l0_path, tmp_path) -> None:
    path, _res = l0_path
    cut = tmp_path / "cut.h5"
    cut.write_bytes(path.read_bytes()[: path.stat().st_size // 2])
    with pytest.raises(L0Error, match=r"truncated|damaged"):
        read_l0(cut)


def test_l0_other_files_are_rejected(l0_path, tmp_path) -> None:
    _path, _res = l0_path
    with pytest.raises(L0Error, match="no such"):
        read_l0(tmp_path / "missing.h5")
    text = tmp_path / "text.h5"
    text.write_text("not hdf5")
    with pytest.raises(L0Error, match="not a readable HDF5"):
        read_l0(text)
    other = tmp_path / "other.h5"
    with h5py.File(other, "w") as f:
        f.attrs["format"] = "something else"
    with pytest.raises(L0Error, match="not an L0 archive"):
        read_l0(other)


def test_l0_inconsistent_shapes_are_rejected(l0_path, tmp_path) -> None:
    path, _res = l0_path
    short_times, no_mask = tmp_path / "short.h5", tmp_path / "nomask.h5"
    for p in (short_times, no_mask):
        p.write_bytes(path.read_bytes())
    with h5py.File(short_times, "a") as f:
        del f["lines/t_s"]
        f["lines/t_s"] = np.zeros(3)
    with pytest.raises(L0Error, match="lines/t_s"):
        read_l0(short_times)
    with h5py.File(no_mask, "a") as f:
        del f["bands/XS2/valid"]
    with pytest.raises(L0Error, match="XS2/valid"):
        read_l0(no_mask)


def test_damaged_aux_records_do_not_move_the_line_clock(acq_p) -> None:
    from station.srrs.clock import line_clock, on_the_clock, plausible_times

    _tx, _rx, d = _send(acq_p, ber=0.0, burst_rate_per_s=0.0)
    aux = d.aux.copy()
    aux["line_time_ms"][5] += 50  # a record damaged on board: 50 ms off its line
    aux["time_ms"][9] = 2**63  # an impossible time code
    keep = plausible_times(aux)
    assert keep.tolist().count(False) == 1 and not keep[9]
    aux = aux[keep]
    assert on_the_clock(aux, d.first_line_counter).tolist().count(False) == 1
    _epoch, t, _period, _unc = line_clock(aux, d.first_line_counter, d.line_counter.size)
    assert np.abs(t - acq_p.line_times_s).max() < LINE_TIME_TOL_S


#: A full pass imaged in P: 11 min of lines, the station's longest recording.
_PASS_LINES = int(11 * 60 / 1.504e-3)
#: Between the two fits of the codes on that strip (measured: the feasible-set middle is
#: within 0.3 µs of the true line times, its 3500 records pinning the clock; the
#: least-squares line through codes + 0.5 ms misses by 71 µs, the bias of the truncation's
#: pattern): a bound of 10 µs passes the first only.
LONG_STRIP_CLOCK_TOL_S = 10e-6


def test_line_clock_on_a_long_strip_beats_least_squares() -> None:
    """The clock of a whole pass from its aux records (one per 125 ms gyro sample, each
    with its 1 ms truncated codes): the feasible-set middle (station.srrs.clock's
    recovery) meets a bound that the least-squares fit misses."""
    from station.srrs.clock import line_clock
    from station.telemetry import format as tf

    period_s, first_line = 1.504e-3 * (1 + 3e-7), 123_456  # a clock slightly off nominal
    t0_s = 37_000.123_456_7  # the first line's start, s into the day
    epoch = np.datetime64("1998-02-20", "ms")
    t_rec = np.arange(0.0, _PASS_LINES * period_s - 0.2, 0.125)  # gyro samples
    k = np.ceil((t_rec - 1e-12) / period_s).astype(np.int64)  # first line at or after
    aux = np.zeros(t_rec.size, tf.AUX_DTYPE)
    aux["time_ms"] = tf.ms_since_cnes_epoch(epoch, t0_s + t_rec)
    aux["line"] = first_line + k
    aux["line_time_ms"] = tf.ms_since_cnes_epoch(epoch, t0_s + k * period_s)
    truth = t0_s + np.arange(_PASS_LINES) * period_s
    miss = {}
    for method in ("feasible", "least_squares"):
        _e, t, _p, _u = line_clock(aux, first_line, _PASS_LINES, method=method)
        miss[method] = float(np.abs(t - truth).max())
    assert miss["feasible"] < LONG_STRIP_CLOCK_TOL_S < miss["least_squares"], miss
