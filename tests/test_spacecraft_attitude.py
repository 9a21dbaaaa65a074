"""Truth attitude: Westin's variograms (paper 000_…, eqs. 24–26), jitter, gyros.

The variogram test compares, at several lags, the variance of attitude increments over an
ensemble of independently drawn drifts with 2γ(Δt). One increment per realisation and lag
makes the draws independent, so the sample variance has relative standard error
sqrt(2 / M); the tolerance is four of those.
"""

from __future__ import annotations

import numpy as np
import pytest

from levels.geometry.attitude import integrate_rates
from station.spacecraft.attitude import (
    MICRODEGREE_RAD,
    TruthAttitude,
    fractional_brownian,
    sample_gyros,
    westin_variogram_rad2,
)

M = 1500
VARIOGRAM_REL_TOL = 4 * np.sqrt(2 / M)  # 4σ of a sample variance of M normal draws
LAGS_S = (0.5, 2.0, 8.0, 31.0)


def test_westin_units_are_microdegrees() -> None:
    # the paper's own check: [2γ_ω(31)]^½ = 0.93° × 10⁻³ and [2γ_ρ(31)]^½ = 0.50° × 10⁻³
    assert np.degrees(np.sqrt(westin_variogram_rad2(0, 31.0))) == pytest.approx(0.93e-3, abs=5e-6)
    assert np.degrees(np.sqrt(westin_variogram_rad2(1, 31.0))) == pytest.approx(0.50e-3, abs=5e-6)
    assert MICRODEGREE_RAD == pytest.approx(1.745329e-8, rel=1e-6)


@pytest.fixture(scope="module")
def ensemble() -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(2024)
    draws = [TruthAttitude.generate(0.0, 40.0, rng, drift_step_s=0.125) for _ in range(M)]
    return draws[0].t_grid_s, np.stack([d.drift_rad for d in draws])


@pytest.mark.parametrize("axis", [0, 1, 2], ids=["roll eq24", "pitch eq25", "yaw eq26"])
@pytest.mark.parametrize("lag_s", LAGS_S)
def test_drift_follows_westin_variograms(ensemble, axis: int, lag_s: float) -> None:
    t, drift = ensemble
    k = round(lag_s / (t[1] - t[0]))
    start = 8  # any fixed start: the increments are stationary
    increments = drift[:, start + k, axis] - drift[:, start, axis]
    empirical = np.mean(increments**2)
    assert empirical == pytest.approx(
        float(westin_variogram_rad2(axis, lag_s)), rel=VARIOGRAM_REL_TOL
    )


def test_fractional_brownian_rejects_a_non_power_law() -> None:
    with pytest.raises(ValueError, match="0 < alpha < 2"):
        fractional_brownian(10, 0.1, 1.0, 2.0, np.random.default_rng(0))


def test_offsets_and_jitter() -> None:
    rng = np.random.default_rng(5)
    att = TruthAttitude.generate(
        0.0,
        10.0,
        rng,
        offsets_rad=(1e-4, -2e-4, 3e-4),
        drift_scale=0.0,
        jitter_amplitude_rad=(1e-6, 0.0, 0.0),
        jitter_frequency_hz=(20.0, 0.0, 0.0),
    )
    a = att.angles_rad(np.linspace(0, 10, 20001))
    assert a[:, 1] == pytest.approx(-2e-4, abs=1e-18)
    assert a[:, 0].max() - 1e-4 == pytest.approx(1e-6, rel=1e-3)  # a 20 Hz sine, peak 1 µrad
    assert np.isnan(att.angles_rad([-1.0, 11.0])).all()  # no silent extrapolation


def test_gyros_integrate_back_to_the_attitude() -> None:
    """Rates integrated by the model's rule give the attitude up to the offsets, the noise
    random walk and the jitter the 125 ms boxcar cannot follow."""
    rng = np.random.default_rng(11)
    att = TruthAttitude.generate(0.0, 20.0, rng, offsets_rad=(1e-4, 2e-4, -3e-4))
    gyro = sample_gyros(att, 1.0, 145, 0.125, 0.5e-6, 0.2e-6, rng)
    assert np.allclose(gyro.rates_rad_per_s / 0.2e-6, np.round(gyro.rates_rad_per_s / 0.2e-6))
    angles = integrate_rates(gyro.t_s, gyro.rates_rad_per_s, start_t_s=gyro.t_s[0]).angles_rad(
        gyro.t_s
    )
    truth = att.angles_rad(gyro.t_s) - att.angles_rad(gyro.t_s[:1])
    # Pitch (eq. 25) is rough: its increments over T/2 = 62.5 ms have σ = 1.2 µrad, which no
    # 8 Hz boxcar resolves; the noise walk adds σ·T·sqrt(n) = 0.75 µrad. 6 µrad is 4σ of both.
    assert np.abs(angles - truth).max() < 6e-6
    # roll (eq. 24, Hurst 0.9) is smooth: noiseless rates integrate back to 0.5 µrad
    quiet = sample_gyros(att, 1.0, 145, 0.125, 0.0, 0.0, rng)
    roll = integrate_rates(quiet.t_s, quiet.rates_rad_per_s, start_t_s=quiet.t_s[0]).angles_rad(
        quiet.t_s
    )[:, 0]
    assert np.abs(roll - truth[:, 0]).max() < 0.5e-6
    # the offsets are invisible to the gyros
    assert np.abs(angles[0]).max() == 0.0


#: Drifts drawn for the interpolation test, and its tolerance on the RMS: the errors of
#: one drift's intervals are nearly independent (each interval's own wander), so the RMS
#: of N of them has relative standard error about 1 / sqrt(2 N); four of those, and the
#: drift's own 1/128 s sampling (its finest wander is not drawn: a few per cent low).
INTERP_DRIFTS, INTERP_SPAN_S = 8, 20.0
INTERP_REL_TOL = 4 / np.sqrt(2 * INTERP_DRIFTS * INTERP_SPAN_S / 0.125) + 0.05


def test_the_attitude_between_gyro_records_misses_what_westin_says() -> None:
    """:func:`levels.geometry.attitude.interpolation_sigma_rad` (what level 2 adds to every
    point and to its prediction) against drawn Westin drifts: each sampled every 0.125 s
    and interpolated linearly, its error between the samples, in pitch (0.83 µrad) and yaw
    (0.14 µrad); roll's smooth drift misses almost nothing."""
    from levels.geometry.attitude import interpolation_sigma_rad

    period = 0.125
    rng = np.random.default_rng(11)
    err = []
    for _ in range(INTERP_DRIFTS):
        att = TruthAttitude.generate(0.0, INTERP_SPAN_S, rng)
        t = att.t_grid_s
        samples = np.arange(0.0, t[-1], period)
        fine = t[t < samples[-1]]
        truth = att.angles_rad(fine)
        at = att.angles_rad(samples)
        err.append(truth - np.stack([np.interp(fine, samples, at[:, k]) for k in range(3)], 1))
    rms = np.sqrt(np.mean(np.concatenate(err) ** 2, axis=0))
    said = interpolation_sigma_rad(period)
    assert said[1] == pytest.approx(0.83e-6, rel=0.01)
    for axis in (1, 2):
        assert rms[axis] == pytest.approx(said[axis], rel=INTERP_REL_TOL), (rms, said)
    assert rms[0] < 0.1e-6 and said[0] < 0.1e-6
