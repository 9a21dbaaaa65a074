"""Rotations, the SPOT local orbital frame, and ECI ⇄ ECEF."""

from __future__ import annotations

import numpy as np
import pytest
from _orbits import EPOCH, kepler_eci

from levels.geometry.frames import (
    EARTH_ROTATION_RATE_RAD_PER_S,
    ecef_from_orbital,
    ecef_to_eci,
    eci_to_ecef,
    orbital_from_body,
    rot_x,
    rot_y,
    rot_z,
)

ROUND_OFF = 1e-12


def test_elementary_rotations_are_active_and_right_handed() -> None:
    a = np.pi / 2
    assert rot_z(a) @ [1, 0, 0] == pytest.approx([0, 1, 0], abs=ROUND_OFF)
    assert rot_x(a) @ [0, 1, 0] == pytest.approx([0, 0, 1], abs=ROUND_OFF)
    assert rot_y(a) @ [0, 0, 1] == pytest.approx([1, 0, 0], abs=ROUND_OFF)


def test_orbital_frame_follows_the_handbook() -> None:
    t = np.linspace(0, 6000, 50)
    r, v = kepler_eci(t)
    m = ecef_from_orbital(r, v)
    x, y, z = m[..., 0], m[..., 1], m[..., 2]
    assert np.einsum("ni,ni->n", z, r / np.linalg.norm(r, axis=1)[:, None]) == pytest.approx(
        1.0, abs=ROUND_OFF
    )
    assert np.abs(np.einsum("ni,ni->n", x, v)).max() < 1e-9  # X ⟂ V
    assert np.einsum("ni,ni->n", y, v).min() > 0  # Y forward
    assert np.linalg.det(m) == pytest.approx(1.0, abs=ROUND_OFF)


def test_attitude_signs_are_spot_s() -> None:
    # A positive SPOT roll turns the nadir look towards +X, where a right-handed rotation
    # about Y would turn it towards −X (levels.geometry.frames, "Satellite body").
    nadir = np.array([0.0, 0.0, -1.0])
    turned = orbital_from_body(0.01, 0.0, 0.0) @ nadir
    assert turned[0] == pytest.approx(np.sin(0.01))
    assert turned == pytest.approx(rot_y(-0.01) @ nadir)
    assert orbital_from_body(0.0, 0.02, 0.0) @ nadir == pytest.approx(rot_x(-0.02) @ nadir)
    assert orbital_from_body(0.0, 0.0, 0.03) == pytest.approx(rot_z(0.03))


def test_attitude_rotation_is_the_product_it_documents() -> None:
    rng = np.random.default_rng(3)
    roll, pitch, yaw = rng.uniform(-0.3, 0.3, (3, 50))
    expected = rot_x(-pitch) @ rot_y(-roll) @ rot_z(yaw)
    assert np.abs(orbital_from_body(roll, pitch, yaw) - expected).max() < ROUND_OFF


def test_eci_ecef_round_trip_and_earth_fixed_velocity() -> None:
    t = np.linspace(0.0, 60.0, 601)
    r_eci, v_eci = kepler_eci(t)
    era = EPOCH.era_rad(t)
    r, v = eci_to_ecef(r_eci, v_eci, era)
    back_r, back_v = ecef_to_eci(r, v, era)
    assert np.abs(back_r - r_eci).max() < 1e-6
    assert np.abs(back_v - v_eci).max() < 1e-9
    # The ECEF velocity is the time derivative of the ECEF position (central difference).
    dt = t[1] - t[0]
    fd = (r[2:] - r[:-2]) / (2 * dt)
    # Truncation of the difference: jerk · dt² / 6 ≈ 0.009 m/s³ × (0.1 s)² / 6 = 1.5e-5 m/s.
    assert np.abs(fd - v[1:-1]).max() < 1e-4
    assert EARTH_ROTATION_RATE_RAD_PER_S == pytest.approx(7.292115e-5, rel=1e-7)  # WGS84 ω
