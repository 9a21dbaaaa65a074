"""GEO of emulated passes: level 1B and 2A grids over Cuiabá, the chain against truth (GEO's
own grids and arithmetic on a synthetic pass are ``tests/levels/test_geo_grids.py``'s and
``test_geo_arithmetic.py``'s).

Geometry only (the emulator with ``render=False``): no image is needed to know where the
products put each raw pixel, so these run at full scene size in seconds.
"""

from __future__ import annotations

import numpy as np
import pytest

from levels.geo.level1b import level1b_geometry
from levels.geo.level2a import INVERSE_METHODS, level2a_geometry, map_crs
from station.fixtures import emulated_scene
from station.scenario import ERRORS_OFF, merge_tables, scenario_from_dict
from station.spacecraft.emulator import emulate

#: The issue's bound on the 2A inverse from the four nearest direct-grid points.
MAX_INVERSE_PX = 0.05
#: The issue's bound on checkpoint errors of an unbiased chain (errors switched off).
UNBIASED_PX = 0.5
H_REF_M = 450.0
#: The 1B skew of a nadir scene at Cuiabá (derivation in the test that uses it), and the
#: share of it the along-track ellipsoid geometry and the polynomial fit may move.
EARTH_SKEW_PX = 465.1 * np.cos(np.radians(15.5)) * np.cos(np.radians(9.0)) * 6000 * 1.504e-3 / 10
EARTH_SKEW_REL = 0.05


def _scene(data: dict):
    acq = emulate(scenario_from_dict(data), render=False)
    _pg, scene, res = emulated_scene(acq, reference_height_m=H_REF_M)
    return acq, scene, res


@pytest.fixture(scope="module")
def nadir():
    return _scene({})


@pytest.fixture(scope="module")
def tilted():
    return _scene({"instrument": {"mirror_step": 93}})  # 27°


def test_scene_centre_and_corners_on_the_target(nadir) -> None:
    acq, scene, _ = nadir
    pc = acq.scenario.pass_
    # the emulator aims the strip's centre at the target; GEO finds it within the
    # system-level error (a few hundred metres)
    dlat = (scene.centre_lat_rad - pc.target_lat_rad) * 6.371e6
    assert abs(dlat) < 1000.0
    # corners clockwise on a descending pass: first line north of last line
    assert scene.corners_lat_rad[0] > scene.corners_lat_rad[3]
    assert scene.corners_lon_rad[1] > scene.corners_lon_rad[0]  # columns run east


def test_level1b_axes_and_round_trip(nadir) -> None:
    _acq, scene, res = nadir
    g = level1b_geometry(scene, res)
    lat, lon = scene.centre_lat_rad, scene.centre_lon_rad
    north = np.array([-np.sin(lat) * np.cos(lon), -np.sin(lat) * np.sin(lon), np.cos(lat)])
    east = np.array([-np.sin(lon), np.cos(lon), 0.0])
    assert g.plane.y_axis @ east > 0.95 and g.plane.x_axis @ north < -0.95  # Y east, X south
    line, col = np.meshgrid(np.linspace(0, 5999, 9), np.linspace(0, 5999, 9))
    i, j = g.corrected_of(line, col)
    back = g.raw_of(i, j)
    assert back[0] == pytest.approx(line, abs=1e-6)
    assert back[1] == pytest.approx(col, abs=1e-6)
    # 60 km at 10 m, and wider by the skew h: the Earth turns under the inertial frame of
    # SPOT 1–4 by its surface speed across the track, 465 m/s · cos 15.5° · cos 9° = 443 m/s,
    # for the 9.02 s of the scene: 400 px, h from −200 to +200 px (INPE's ±200)
    span_px = np.ptp(g.h(np.arange(g.n_rows, dtype=float)))
    assert span_px == pytest.approx(EARTH_SKEW_PX, rel=EARTH_SKEW_REL)
    assert 5900 < g.n_rows < 6300 and 5900 < g.n_cols - span_px < 6300


@pytest.mark.parametrize("case", ["nadir", "tilted"])
def test_2a_four_nearest_inverse_within_a_twentieth_of_a_pixel(case, request) -> None:
    _acq, scene, res = request.getfixturevalue(case)
    crs = map_crs("utm", scene.centre_lat_rad, scene.centre_lon_rad)
    g = level2a_geometry(scene, res, crs)
    errors = {m: g.approximation_error(scene.model, H_REF_M, m)["max_px"] for m in INVERSE_METHODS}
    assert errors["nearest4"] <= MAX_INVERSE_PX
    # the polynomials miss the attitude's high frequencies the gyros do see
    assert min(errors["poly3"], errors["poly4"], errors["poly5"]) > 2 * MAX_INVERSE_PX


#: The azimuth measured here is the raw lines' on the UTM grid minus the grid's meridian
#: convergence; INPE quotes it to a tenth of a degree.
AZIMUTH_TOL_DEG = 0.1


def test_a_2a_row_reads_inpes_950_raw_lines(nadir) -> None:
    """COR's load: a north-up 2A row crosses the raw lines at the inertial track's azimuth,
    6000 · tan 9.0° = 950 raw lines in P at Cuiabá (INPE), plus the UTM grid's convergence."""
    import pyproj

    _acq, scene, res = nadir
    crs = map_crs("utm", scene.centre_lat_rad, scene.centre_lon_rad)
    g = level2a_geometry(scene, res, crs)
    lines, cols = g.raw_line_span()
    azimuth = np.degrees(np.arctan2(lines, cols))
    lon, lat = np.degrees(scene.centre_lon_rad), np.degrees(scene.centre_lat_rad)
    convergence = abs(pyproj.Proj(crs).get_factors(lon, lat).meridian_convergence)
    assert azimuth - convergence == pytest.approx(INPE_TRACK_AZIMUTH_DEG, abs=AZIMUTH_TOL_DEG)
    assert 900 < lines < 1000  # INPE's 950, through the grid's convergence


def test_spot5_earth_fixed_frame_is_a_scenario_choice() -> None:
    """SPOT 5's convention (the attitude frame on the Earth-fixed velocity): the raw lines
    follow the ground track, the 1B skew vanishes, and the chain is as unbiased as with
    SPOT 1–4's inertial frame: the processing takes the velocity the bulletins carry."""
    over = merge_tables(ERRORS_OFF, {"attitude": {"reference_velocity": "earth_fixed"}})
    acq, scene, res = _scene(merge_tables({"instrument": {"n_detectors": 300}}, over))
    assert acq.orbit.reference_velocity == "earth_fixed"
    g1 = level1b_geometry(scene, res)
    # h of the reduced scene (300 columns of 200 m): the inertial frame's 400 px are 20
    assert np.ptp(g1.h(np.arange(g1.n_rows, dtype=float))) < 0.1 * EARTH_SKEW_PX / 20
    e1, e2, res = _errors(over)
    assert e2["max_px"] < UNBIASED_PX
    assert np.hypot(e1["mean_1_m"], e1["mean_2_m"]) / res < UNBIASED_PX
