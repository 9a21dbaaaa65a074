"""The photogrammetric model: round trips image ⇄ ground on a synthetic HRV scene whose
orbit is exact (Keplerian) and whose attitude has offsets, drift and jitter."""

from __future__ import annotations

import numpy as np
import pytest
from _orbits import hrv_model

from levels.geometry import WGS84

#: The issue's bars.
GROUND_ROUNDTRIP_TOL_M = 1e-3
IMAGE_ROUNDTRIP_TOL_PX = 1e-3
MAX_ITERATIONS_INSIDE = 5


def _grid(model, n=41, margin=0.0):
    lines = np.linspace(-margin, model.n_lines - 1 + margin, n)
    cols = np.linspace(-margin, model.n_columns - 1 + margin, n)
    return [a.ravel() for a in np.meshgrid(lines, cols, indexing="ij")]


@pytest.mark.parametrize("mirror_step", [48, 93, 3], ids=["nadir", "27deg", "-27deg"])
@pytest.mark.parametrize("height_m", [0.0, 3500.0])
def test_image_ground_image(mirror_step: int, height_m: float) -> None:
    model = hrv_model(mirror_step)
    line, col = _grid(model)
    ground = model.image_to_ground(line, col, height_m)
    assert ground.ok.all()
    assert ground.h_m == pytest.approx(height_m, abs=1e-4)
    back = model.ground_to_image(ground.lat_rad, ground.lon_rad, height_m)
    assert back.converged.all()
    assert np.abs(back.line - line).max() < IMAGE_ROUNDTRIP_TOL_PX
    assert np.abs(back.column - col).max() < IMAGE_ROUNDTRIP_TOL_PX
    assert back.iterations.max() <= MAX_ITERATIONS_INSIDE


@pytest.mark.parametrize("mirror_step", [48, 93])
def test_ground_image_ground(mirror_step: int) -> None:
    model = hrv_model(mirror_step)
    centre = model.image_to_ground(2999.5, 2999.5)
    rng = np.random.default_rng(5)
    # Points spread over the scene (±25 km at nadir; wider when tilted) and heights.
    lat = centre.lat_rad + rng.uniform(-3.5e-3, 3.5e-3, 2000)
    lon = centre.lon_rad + rng.uniform(-3.5e-3, 3.5e-3, 2000) / np.cos(centre.lat_rad)
    h = rng.uniform(-200.0, 4000.0, 2000)
    image = model.ground_to_image(lat, lon, h)
    assert image.converged.all()
    ground = model.image_to_ground(image.line, image.column, h)
    miss = np.linalg.norm(
        WGS84.to_ecef(ground.lat_rad, ground.lon_rad, ground.h_m) - WGS84.to_ecef(lat, lon, h),
        axis=1,
    )
    assert miss.max() < GROUND_ROUNDTRIP_TOL_M


def test_relief_displaces_a_tilted_view_by_h_tan_theta() -> None:
    """The relief formula Δg = h·tanθ (Guindon, Goodenough and Teillet 1982, as the TM study
    at the end of paper 004 quotes it): 1000 m of relief seen 27° off nadir
    moves the located point by about 1000·tan(27° + Earth curvature) across track."""
    model = hrv_model(93)
    a = model.image_to_ground(2999.5, 2999.5, 0.0)
    b = model.image_to_ground(2999.5, 2999.5, 1000.0)
    shift = np.linalg.norm(
        WGS84.to_ecef(a.lat_rad, a.lon_rad, 0.0) - WGS84.to_ecef(b.lat_rad, b.lon_rad, 0.0)
    )
    # Incidence at the ground exceeds the 27° view angle by the Earth's curvature (~3°).
    assert shift == pytest.approx(1000.0 * np.tan(np.radians(30.6)), rel=0.03)


def test_points_that_cannot_be_located_are_flagged() -> None:
    model = hrv_model(48)
    centre = model.image_to_ground(2999.5, 2999.5)
    # the antipode (behind the Earth), and a point 4000 km along track (outside the ephemeris)
    lat = np.array([-centre.lat_rad[0], centre.lat_rad[0] + 0.6])
    lon = np.array([centre.lon_rad[0] + np.pi, centre.lon_rad[0]])
    image = model.ground_to_image(lat, lon, 0.0)
    assert not image.converged.any()
    # a line of sight outside the ephemeris span
    ground = model.image_to_ground(np.array([1e7]), np.array([10.0]))
    assert not ground.ok.any() and np.isnan(ground.lat_rad).all()


def test_strips_longer_than_a_scene_and_points_just_outside() -> None:
    model = hrv_model(48)
    line, col = _grid(model, n=15, margin=600.0)  # 10 % outside on every side
    ground = model.image_to_ground(line, col)
    back = model.ground_to_image(ground.lat_rad, ground.lon_rad)
    assert back.converged.all()
    assert np.abs(back.line - line).max() < IMAGE_ROUNDTRIP_TOL_PX
