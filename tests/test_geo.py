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
from station.truth.optical import Truth, checkpoints_1b, checkpoints_2a

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


def _errors(over: dict):
    data = merge_tables({"instrument": {"n_detectors": 300}}, over)
    acq, scene, res = _scene(data)
    truth = Truth(acq, 0)
    g1 = level1b_geometry(scene, res)
    g2 = level2a_geometry(scene, res, map_crs("utm", scene.centre_lat_rad, scene.centre_lon_rad))
    return (
        checkpoints_1b(truth, scene, g1, 0, 11)["line_of_sight"],
        checkpoints_2a(truth, scene, g2, 0, 11)["line_of_sight"],
        res,
    )


@pytest.mark.parametrize("mirror_step", [48, 93])
def test_chain_is_unbiased_with_errors_off(mirror_step) -> None:
    e1, e2, res = _errors(
        merge_tables(ERRORS_OFF, {"instrument": {"mirror_step": mirror_step, "n_detectors": 6000}})
    )
    assert e2["max_px"] < UNBIASED_PX
    # 1B: its mean is unbiased; its spread is its cubics' approximation error, measured
    # on its own (test above)
    assert np.hypot(e1["mean_1_m"], e1["mean_2_m"]) / res < UNBIASED_PX
    assert e1["rms_px"] < 1.0


def test_default_errors_are_the_sum_of_their_sources() -> None:
    """How the size of the default errors is checked: each source alone gives the
    displacement it implies, and together they add up."""
    att_only = merge_tables(
        ERRORS_OFF, {"attitude": {"roll_offset_urad": 150.0, "pitch_offset_urad": -200.0}}
    )
    eph_only = merge_tables(ERRORS_OFF, {"bulletins": {"bias_m": [150.0, -100.0, 0.0]}})
    both = merge_tables(att_only, {"bulletins": eph_only["bulletins"]})
    _, a, _ = _errors(att_only)
    _, e, _ = _errors(eph_only)
    _, b, _ = _errors(both)
    # attitude: the angle times the 822 km height (flat Earth, nadir)
    expected_att = 822e3 * np.hypot(150e-6, 200e-6)
    assert np.hypot(a["mean_1_m"], a["mean_2_m"]) == pytest.approx(expected_att, rel=0.03)
    # ephemeris: the horizontal bias, carried to the ground (× (R)/(R + H) on a sphere)
    expected_eph = np.hypot(150.0, 100.0) * 6.371e6 / (6.371e6 + 822e3)
    assert np.hypot(e["mean_1_m"], e["mean_2_m"]) == pytest.approx(expected_eph, rel=0.03)
    sum_1, sum_2 = a["mean_1_m"] + e["mean_1_m"], a["mean_2_m"] + e["mean_2_m"]
    assert np.hypot(b["mean_1_m"] - sum_1, b["mean_2_m"] - sum_2) < 2.0


def test_xs_bands_registered_each_through_its_own_geometry() -> None:
    """XS: the three bands' look angles differ by tenths of a pixel; each gets its own 1B
    polynomials and 2A grids on the first band's output grid, and every band's checkpoints
    fall where the unbiased chain puts them."""
    acq = emulate(
        scenario_from_dict(
            merge_tables(ERRORS_OFF, {"instrument": {"mode": "XS", "n_detectors": 1500}})
        ),
        render=False,
    )
    looks = [b.name for b in acq.hrv.bands]
    _pg, scene, res = emulated_scene(acq, reference_height_m=H_REF_M)
    crs = map_crs("utm", scene.centre_lat_rad, scene.centre_lon_rad)
    first, *others = looks
    g2 = {first: level2a_geometry(scene, res, crs, band=first)}
    g1 = {first: level1b_geometry(scene, res, band=first)}
    for b in others:
        g2[b] = level2a_geometry(scene, res, crs, band=b, like=g2[first])
        g1[b] = level1b_geometry(scene, res, band=b, like=g1[first])
    truth = Truth(acq, 0)
    shared_first = []
    for k, b in enumerate(looks):
        assert (g2[b].map_grid.geotransform, g2[b].map_grid.n_rows, g2[b].map_grid.n_cols) == (
            g2[first].map_grid.geotransform,
            g2[first].map_grid.n_rows,
            g2[first].map_grid.n_cols,
        )
        assert (g1[b].i_origin, g1[b].n_cols) == (g1[first].i_origin, g1[first].n_cols)
        assert g2[b].approximation_error(scene.models[b], H_REF_M)["max_px"] <= MAX_INVERSE_PX
        own = checkpoints_2a(truth, scene, g2[b], k, 11)["line_of_sight"]
        assert own["max_px"] < UNBIASED_PX
        e1 = checkpoints_1b(truth, scene, g1[b], k, 11)["line_of_sight"]
        assert np.hypot(e1["mean_1_m"], e1["mean_2_m"]) / res < UNBIASED_PX
        shared_first.append(
            (
                own["rms_px"],
                checkpoints_2a(truth, scene, g2[first], k, 11)["line_of_sight"]["rms_px"],
            )
        )
    # the band registration the shared geometry would miss, and its own geometry does not
    assert max(s for _o, s in shared_first) > 0.1
    assert max(o for o, _s in shared_first) < 0.05


#: INPE's figure (paper 004_…): each corrected line relates to 6000 · tan 9.0° = 950 raw
#: lines in P, 9.0° being the azimuth of the inertial track at Cuiabá.
INPE_TRACK_AZIMUTH_DEG = 9.0
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
