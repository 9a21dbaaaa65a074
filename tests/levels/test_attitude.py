"""Attitude: interpolation of samples, trapezoid integration of rates, INPE's zeroing."""

from __future__ import annotations

import numpy as np
import pytest

from levels.errors import GeometryError
from levels.geometry import ConstantAttitude, SampledAttitude, integrate_rates
from levels.geometry.attitude import attitude_gaps

ROUND_OFF_RAD = 1e-15


def test_constant_rates_integrate_exactly() -> None:
    t = np.arange(0.0, 9.0, 0.125)
    rates = np.tile([1e-5, -2e-5, 3e-6], (t.size, 1))
    att = integrate_rates(t, rates, start_angles_rad=(1e-4, 0.0, -1e-4))
    got = att.angles_rad(np.array([0.0, 4.3, 8.875]))
    expected = np.array([1e-4, 0.0, -1e-4]) + np.outer([0.0, 4.3, 8.875], [1e-5, -2e-5, 3e-6])
    assert got == pytest.approx(expected, abs=1e-14)


def test_trapezoid_error_on_a_sinusoidal_jitter_is_second_order() -> None:
    """Jitter of 1 Hz, amplitude 1e-5 rad/s, sampled at 8 Hz: the trapezoid error is
    bounded by T·h²·max|ω''|/12 = 9 s × (0.125 s)² × 1e-5 × (2π)² / 12 ≈ 4.6e-6 rad."""
    t = np.arange(0.0, 9.0001, 0.125)
    omega = 2 * np.pi
    rates = np.zeros((t.size, 3))
    rates[:, 0] = 1e-5 * np.cos(omega * t)
    att = integrate_rates(t, rates)
    exact = 1e-5 * np.sin(omega * t) / omega
    bound = 9.0 * 0.125**2 * 1e-5 * omega**2 / 12
    err = np.abs(att.angles_rad_samples[:, 0] - exact).max()
    assert err < bound
    # and halving the step divides the error by about four (second order)
    t2 = np.arange(0.0, 9.0001, 0.0625)
    r2 = np.zeros((t2.size, 3))
    r2[:, 0] = 1e-5 * np.cos(omega * t2)
    err2 = np.abs(
        integrate_rates(t2, r2).angles_rad_samples[:, 0] - 1e-5 * np.sin(omega * t2) / omega
    ).max()
    assert err / err2 == pytest.approx(4.0, rel=0.1)


def test_zeroed_at_scene_centre_is_null_there() -> None:
    t = np.arange(-4.5, 4.5, 0.125)
    rates = np.column_stack([np.full(t.size, 2e-6), np.sin(t) * 1e-6, np.full(t.size, -1e-6)])
    att = integrate_rates(t, rates).zeroed_at(0.0)
    assert np.abs(att.angles_rad(np.array([0.0]))).max() < ROUND_OFF_RAD
    # differences between instants are kept
    a = integrate_rates(t, rates)
    d1 = a.angles_rad(np.array([3.0])) - a.angles_rad(np.array([-2.0]))
    d2 = att.angles_rad(np.array([3.0])) - att.angles_rad(np.array([-2.0]))
    assert d1 == pytest.approx(d2, abs=ROUND_OFF_RAD)


def test_start_before_the_first_rate_sample() -> None:
    t = np.arange(0.127, 5.0, 0.125)
    rates = np.tile([1e-5, 0.0, 0.0], (t.size, 1))
    att = integrate_rates(t, rates, start_t_s=0.0, start_angles_rad=(2e-6, 0, 0))
    assert att.angles_rad(np.array([0.0]))[0, 0] == pytest.approx(2e-6, abs=1e-15)
    assert att.angles_rad(np.array([1.0]))[0, 0] == pytest.approx(2e-6 + 1e-5, abs=1e-15)


def test_end_values_held_for_one_interval_then_nan() -> None:
    att = SampledAttitude(
        np.array([0.0, 0.125, 0.25]), np.array([[1.0, 2, 3], [2, 3, 4], [3, 4, 5]]) * 1e-6
    )
    got = att.angles_rad(np.array([-0.1, 0.0625, 0.3, 0.4]))
    assert got[0] == pytest.approx([1e-6, 2e-6, 3e-6])
    assert got[1] == pytest.approx([1.5e-6, 2.5e-6, 3.5e-6])
    assert got[2] == pytest.approx([3e-6, 4e-6, 5e-6])
    assert np.isnan(got[3]).all()


def test_constant_attitude_has_the_shape_of_time() -> None:
    assert ConstantAttitude(1e-3).angles_rad(np.zeros((4, 2))).shape == (4, 2, 3)


@pytest.mark.parametrize(
    ("t", "a", "match"),
    [
        (np.array([0.0, 0.0, 1.0]), np.zeros((3, 3)), "increase"),
        (np.array([0.0, 1.0]), np.zeros((3, 3)), "sizes differ"),
        (np.array([0.0, 1.0]), np.full((2, 3), np.nan), "non-finite"),
    ],
)
def test_bad_samples_are_rejected(t, a, match) -> None:
    with pytest.raises(GeometryError, match=match):
        SampledAttitude(t, a)


def test_geo_holds_the_attitude_across_lost_records() -> None:
    t = np.r_[np.arange(0.0, 1.0, 0.125), np.arange(5.0, 6.0, 0.125)]
    rates = np.full((t.size, 3), 1e-4)
    held = integrate_rates(t, rates, max_gap_s=0.2)
    across = integrate_rates(t, rates)
    jump = held.angles_rad(np.array([5.0]))[0] - held.angles_rad(np.array([0.875]))[0]
    assert np.all(jump == 0.0)
    assert np.allclose(across.angles_rad(np.array([5.0]))[0], 5.0 * 1e-4)
    assert attitude_gaps(t).tolist() == [[0.875, 5.0]]
