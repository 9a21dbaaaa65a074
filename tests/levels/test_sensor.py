"""Look-angle tables and the HRV mirror."""

from __future__ import annotations

import numpy as np
import pytest

from levels.errors import GeometryError
from levels.geometry import LookAngleTable, mirror_angle_rad
from levels.geometry.sensor import look_direction


def test_mirror_steps_are_spot_s() -> None:
    # SPOT 1–4 HRV: 91 positions, 0.6° apart, ±27° (DESIGN.md; the Izmit scene's step 93 is 27°).
    assert np.degrees(mirror_angle_rad(np.array([3, 48, 93]))) == pytest.approx([-27.0, 0.0, 27.0])
    with pytest.raises(GeometryError, match="mirror step"):
        mirror_angle_rad(97)


def test_look_direction_follows_the_handbook() -> None:
    u = look_direction(0.01, 0.2)
    expected = np.array([-np.tan(0.2), np.tan(0.01), -1.0])
    assert u == pytest.approx(expected / np.linalg.norm(expected))


def test_first_and_last_detector_interpolated_linearly_and_inverted() -> None:
    table = LookAngleTable(
        np.array([0.0, 5999.0]), np.array([0.0107, 0.0111]), np.array([0.4328, 0.5047]), 6000
    )
    cols = np.array([-3.0, 0.0, 1234.5, 5999.0, 6010.0])
    psi_x, psi_y = table.angles_rad(cols)
    assert psi_y == pytest.approx(0.4328 + cols / 5999.0 * (0.5047 - 0.4328))
    assert psi_x == pytest.approx(0.0107 + cols / 5999.0 * 0.0004)
    assert table.column_of_psi_y(psi_y) == pytest.approx(cols, abs=1e-9)


def test_a_decreasing_table_inverts_too() -> None:
    table = LookAngleTable(np.array([0.0, 1.0, 2.0]), np.zeros(3), np.array([0.03, 0.0, -0.03]), 3)
    assert table.column_of_psi_y(np.array([0.015, -0.045])) == pytest.approx([0.5, 2.5])


def test_mirror_shifts_psi_y() -> None:
    table = LookAngleTable(np.array([0.0, 99.0]), np.zeros(2), np.array([-0.03, 0.03]), 100)
    tilted = table.with_mirror(float(mirror_angle_rad(93)))
    assert tilted.angles_rad(49.5)[1] == pytest.approx(np.radians(27.0))


@pytest.mark.parametrize(
    ("cols", "px", "py", "n", "match"),
    [
        ([0.0, 0.0], [0, 0], [0, 1e-3], 10, "increase"),
        ([0.0, 1.0, 2.0], [0, 0, 0], [0, 1e-3, 0], 10, "monotonic"),
        ([0.0, 20.0], [0, 0], [0, 1e-3], 10, "outside"),
        ([0.0, 1.0], [0, 0], [0, 2.0], 10, "radians"),
        ([0.0, 1.0], [0, 0], [0, 1e-3, 2e-3], 10, "sizes"),
    ],
)
def test_bad_tables_are_rejected(cols, px, py, n, match) -> None:
    with pytest.raises(GeometryError, match=match):
        LookAngleTable(np.array(cols), np.array(px, float), np.array(py, float), n)
