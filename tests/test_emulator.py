"""Spacecraft emulator: imaging truth, footprints, radiometry, bulletins, control points.

Sizes are reduced the way the scenario allows (300 detectors with a 20× wider IFOV and a
line period 20× longer, so the scene is still 60 km and 9 s): the physics is the full one.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from levels.geometry.ellipsoid import WGS84
from levels.geometry.frames import ecef_from_orbital, inertial_velocity_ecef
from station.scenario import scenario_from_dict
from station.spacecraft.emulator import emulate, emulate_pass, truth_model
from station.spacecraft.imaging import HEIGHT_TOL_M, psf_quadrature, trace_pixels
from station.spacecraft.instrument import COUNTS_PER_RADIANCE, TWIN_SEPARATION_RAD

REPROJECTION_TOL_PX = 0.01  # the figure for the imaging truth
SWATH_NADIR_KM = 60.0
SWATH_TOL_KM = 1.0  # "60 km ± 1 km"
SWATH_27_KM = 80.0
SWATH_27_REL = 0.05  # "about 80 km"
SMALL = {"n_detectors": 300, "n_lines": 300, "psf_samples": 2}
NO_PASSES = {"ground_pass_days": 0.0}


def _acq(render: bool = True, **instrument):
    scn = scenario_from_dict({"instrument": {**SMALL, **instrument}, "pass": NO_PASSES})
    return emulate(scn, render=render)


@pytest.fixture(scope="module")
def nadir():
    return _acq(mirror_step=48)


@pytest.fixture(scope="module")
def tilted():
    return _acq(mirror_step=93)


def _random_pixels(acq, n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    return (rng.uniform(0, acq.hrv.n_lines - 1, n), rng.uniform(0, acq.hrv.n_columns - 1, n))


@pytest.mark.parametrize("which", ["nadir", "tilted"])
def test_ground_points_reproject_onto_their_pixel(which: str, request) -> None:
    acq = request.getfixturevalue(which)
    line, col = _random_pixels(acq, 400, 3)
    t = acq.line_times_s[0] + line * acq.hrv.line_period_s
    pts, ok = trace_pixels(acq.orbit, acq.attitude, acq.hrv.bands[0], acq.world, t, col)
    assert ok.all()
    back = truth_model(acq).ground_to_image(pts[:, 0], pts[:, 1], pts[:, 2])
    assert back.converged.all()
    assert np.abs(back.line - line).max() < REPROJECTION_TOL_PX
    assert np.abs(back.column - col).max() < REPROJECTION_TOL_PX
    # and each point lies on the terrain, not on the ellipsoid
    h, _, _ = acq.world.height(pts[:, 0], pts[:, 1])
    assert np.abs(pts[:, 2] - h).max() < HEIGHT_TOL_M
    assert np.ptp(pts[:, 2]) > 100.0  # there is relief to get wrong


def test_a_window_of_the_full_array_reprojects_too() -> None:
    acq = _acq(render=False, n_detectors=0, first_detector=2900, detector_count=200, n_lines=200)
    assert acq.hrv.detector_scale == 1.0 and acq.hrv.n_columns == 200
    line, col = _random_pixels(acq, 200, 4)
    t = acq.line_times_s[0] + line * acq.hrv.line_period_s
    pts, _ = trace_pixels(acq.orbit, acq.attitude, acq.hrv.bands[0], acq.world, t, col)
    back = truth_model(acq).ground_to_image(pts[:, 0], pts[:, 1], pts[:, 2])
    assert np.abs(back.line - line).max() < REPROJECTION_TOL_PX
    assert np.abs(back.column - col).max() < REPROJECTION_TOL_PX


def _swath_km(acq) -> float:
    t = acq.line_times_s[acq.hrv.n_lines // 2]
    n = acq.hrv.n_columns
    pts, _ = trace_pixels(
        acq.orbit, acq.attitude, acq.hrv.bands[0], acq.world, [t, t], [-0.5, n - 0.5]
    )  # outer edges of the first and last detector
    ends = WGS84.to_ecef(pts[:, 0], pts[:, 1], pts[:, 2])
    return float(np.linalg.norm(ends[1] - ends[0]) / 1e3)


def test_footprints(nadir, tilted) -> None:
    assert _swath_km(nadir) == pytest.approx(SWATH_NADIR_KM, abs=SWATH_TOL_KM)
    assert _swath_km(tilted) == pytest.approx(SWATH_27_KM, rel=SWATH_27_REL)
    # the strip is centred on the scenario's target (aim = "view"), columns run east
    scn = nadir.scenario
    t = nadir.t_centre_s
    pts, _ = trace_pixels(
        nadir.orbit,
        nadir.attitude,
        nadir.hrv.bands[0],
        nadir.world,
        [t, t],
        [0, nadir.hrv.n_columns - 1],
    )
    assert np.degrees(pts[:, 0].mean() - scn.pass_.target_lat_rad) == pytest.approx(0, abs=0.02)
    assert np.degrees(pts[:, 1].mean() - scn.pass_.target_lon_rad) == pytest.approx(0, abs=0.02)
    assert pts[1, 1] > pts[0, 1]


def test_rendered_counts(nadir) -> None:
    band = nadir.bands[0]
    assert band.counts.shape == (300, 300) and band.counts.dtype == np.uint8
    assert not band.failed.any()
    assert band.newton_max <= 6
    assert 20 < band.counts.mean() < 200 and band.counts.std() > 5
    # counts are the detector's response to the truth radiance, plus noise
    model = (
        band.radiance * COUNTS_PER_RADIANCE * nadir.hrv.bands[0].gain
        + nadir.hrv.bands[0].offset_counts
    )
    residual = band.counts - model
    noise = nadir.hrv.noise_counts
    quantisation = 1 / np.sqrt(12)
    assert residual.std() == pytest.approx(np.hypot(noise, quantisation), rel=0.05)
    # detector gains differ: the raw image is striped, which level 1A must remove
    column_means = band.counts.mean(axis=0)
    assert np.std(np.diff(column_means)) > 2.0


def test_rendering_is_deterministic_and_streams_independent() -> None:
    a = _acq(n_detectors=60, n_lines=60)
    b = _acq(n_detectors=60, n_lines=60)
    assert np.array_equal(a.bands[0].counts, b.bands[0].counts)
    scn = dataclasses.replace(a.scenario, gcps=dataclasses.replace(a.scenario.gcps, count=3))
    c = emulate(scn)
    assert np.array_equal(a.attitude.drift_rad, c.attitude.drift_rad)
    assert np.array_equal(a.bands[0].counts, c.bands[0].counts)


def test_xs_bands_are_registered_apart() -> None:
    acq = _acq(render=True, mode="XS", n_detectors=150, n_lines=150)
    assert [b.name for b in acq.bands] == ["XS1", "XS2", "XS3"]
    # vegetation is bright in the near infrared: XS3 has the highest mean of the three
    means = [b.radiance.mean() for b in acq.bands]
    assert means[2] == max(means)
    # the same ground point falls at slightly different pixels in each band (sub-pixel)
    t = acq.line_times_s[75]
    pts, _ = trace_pixels(acq.orbit, acq.attitude, acq.hrv.bands[0], acq.world, [t], [75.0])
    positions = []
    for k in range(3):
        m = truth_model(acq, band=k)
        ip = m.ground_to_image(pts[:, 0], pts[:, 1], pts[:, 2])
        positions.append((ip.line[0], ip.column[0]))
    offsets = np.ptp(np.array(positions), axis=0)
    assert 0.0 < offsets.max() < 1.0


def test_twin_hrvs_look_3926_apart() -> None:
    hrv1 = _acq(render=False, twin=True, hrv=1, n_lines=10).hrv
    hrv2 = _acq(render=False, twin=True, hrv=2, n_lines=10).hrv
    centre = hrv1.n_columns // 2
    d = hrv2.bands[0].look_nominal.psi_y_rad[centre] - hrv1.bands[0].look_nominal.psi_y_rad[centre]
    assert d == pytest.approx(TWIN_SEPARATION_RAD, abs=1e-12)


def test_look_tables_truth_and_nominal_differ_by_the_calibration_error(nadir) -> None:
    band = nadir.hrv.bands[0]
    diff = band.look_true.psi_y_rad - band.look_nominal.psi_y_rad
    assert 0 < np.abs(diff).max() < 10e-6  # a few µrad: unknown to the station
    # the four CCDs sit at their butting offsets along track
    along = band.look_nominal.psi_x_rad
    assert len(np.unique(along)) == 4


def test_bulletins_carry_the_stated_errors(nadir) -> None:
    cfg = nadir.scenario.bulletins
    eph = nadir.bulletins
    assert np.allclose(np.diff(eph.t_s), cfg.period_s)
    assert np.allclose(eph.t_s / cfg.period_s, np.round(eph.t_s / cfg.period_s))
    assert eph.t_s[0] <= nadir.line_times_s[0] - cfg.margin_s
    r, v = nadir.orbit.state_ecef(eph.t_s)
    # SPOT 1–4 bulletins carry the inertial velocity in ECEF axes (levels.geometry.frames)
    assert nadir.orbit.reference_velocity == "inertial"
    v_ref = inertial_velocity_ecef(r, v)
    axes = ecef_from_orbital(r, v_ref)
    err_local = np.einsum("nji,nj->ni", axes, eph.r_ecef_m - r)  # (X across, Y along, Z up)
    expected = np.asarray(cfg.bias_m) + np.outer(eph.t_s - nadir.t_centre_s, cfg.drift_m_per_s)
    assert err_local[:, [1, 0, 2]] == pytest.approx(expected, abs=1e-6)
    dv_local = np.einsum("nji,nj->ni", axes, eph.v_ecef_m_per_s - v_ref)
    assert dv_local[:, [1, 0, 2]] == pytest.approx(
        np.broadcast_to(cfg.drift_m_per_s, dv_local.shape), abs=1e-9
    )


def test_control_points(nadir) -> None:
    g = nadir.gcps
    cfg = nadir.scenario.gcps
    assert g.line.size == cfg.count
    back = truth_model(nadir).ground_to_image(g.true_lat_rad, g.true_lon_rad, g.true_h_m)
    assert np.abs(back.line - g.true_line).max() < REPROJECTION_TOL_PX
    assert np.abs(back.column - g.true_column).max() < REPROJECTION_TOL_PX
    assert np.abs(g.line - g.true_line).max() < 5 * cfg.pointing_error_px
    north_m = (g.lat_rad - g.true_lat_rad) * WGS84.a_m
    assert 0 < np.abs(north_m).max() < 5 * cfg.horizontal_error_m


def test_psf_quadrature() -> None:
    o, w = psf_quadrature(1.2, 3)
    assert w.sum() == pytest.approx(1.0, rel=1e-15)
    assert o == pytest.approx(-o[::-1], abs=1e-15) and w[1] > w[0]
    assert psf_quadrature(1.2, 1) == (pytest.approx([0.0]), pytest.approx([1.0]))


def test_world_is_continuous_and_its_slopes_right(nadir) -> None:
    w = nadir.world
    lat = np.radians(-15.6) + np.linspace(0, 0.01, 50)
    lon = np.full(50, np.radians(-56.1))
    h, _gx, gy = w.height(lat, lon)
    step = 1e-8  # rad, 6 cm
    h2, _, _ = w.height(lat + step, lon)
    assert (h2 - h) / (step * WGS84.a_m) == pytest.approx(gy, abs=2e-3)
    # no jumps: 2000 points 0.64 m apart (crossing lattice cells of every octave) never step
    # by more than the steepest slope allows
    fine = np.radians(-15.6) + 1e-7 * np.arange(2000)
    hf, _, gyf = w.height(fine, np.full(2000, np.radians(-56.1)))
    assert np.abs(np.diff(hf)).max() <= 1e-7 * WGS84.a_m * np.abs(gyf).max() * 1.05
    for band in ("P", "XS1", "XS2", "XS3"):
        rho = w.reflectance(lat, lon, band)
        assert ((rho > 0) & (rho < 1)).all()


def test_dem_export(nadir) -> None:
    spacing = np.radians(1 / 1200)  # 3 arc-seconds
    lat0, lon0 = nadir.scenario.pass_.target_lat_rad, nadir.scenario.pass_.target_lon_rad
    box = ((lat0 - 0.002, lat0 + 0.002), (lon0 - 0.002, lon0 + 0.002))
    exact = nadir.world.dem(*box, spacing)
    noisy = nadir.world.dem(*box, spacing, error_rms_m=5.0, rng=np.random.default_rng(0))
    assert exact.height_m.shape == (exact.lat_rad.size, exact.lon_rad.size)
    assert np.diff(exact.lat_rad) == pytest.approx(spacing, rel=1e-9)
    assert np.std(noisy.height_m - exact.height_m) == pytest.approx(5.0, rel=0.15)
    with pytest.raises(ValueError, match="needs an rng"):
        nadir.world.dem(*box, spacing, error_rms_m=1.0)


def test_orbit_from_a_tle_of_refdata(refdata) -> None:
    tle = refdata / "tle" / "spot5_27421_20020504_orekit.tle"
    scn = scenario_from_dict(
        {
            "orbit": {"kind": "tle", "tle_path": str(tle)},
            "pass": {"target_lat_deg": 45.0, "target_lon_deg": 5.0, "ground_pass_days": 1.0},
            "instrument": {"n_detectors": 60, "n_lines": 60},
            "ground_station": {"lat_deg": 43.56, "lon_deg": 1.48},  # Toulouse
        }
    )
    acq = emulate(scn, render=False)
    assert str(acq.epoch.t0_utc)[:10] == "2002-05-04"
    # the strip is on the target latitude, southbound, within the 3 days searched
    t = acq.t_centre_s
    pts, _ = trace_pixels(acq.orbit, acq.attitude, acq.hrv.bands[0], acq.world, [t], [30.0])
    assert np.degrees(pts[0, 0]) == pytest.approx(45.0, abs=0.05)
    _, v = acq.orbit.state_ecef([t])
    assert v[0, 2] < 0
    assert (
        0 < t - float(acq.epoch.seconds(np.datetime64("2002-05-04T11:45:15.695", "ns"))) < 3 * 86400
    )
    # bulletins cover the strip; a launch-day orbit at ~800 km passes over Toulouse
    assert acq.bulletins.t_s[0] < acq.line_times_s[0] < acq.line_times_s[-1] < acq.bulletins.t_s[-1]
    assert len(acq.passes) >= 2


#: Twin HRVs: view axes 3.926° apart from 822 km (plus Earth curvature): ground centres
#: about 56.5 km apart, two 60 km swaths side by side, 117 km together (SPOT's figure).
TWIN_CENTRES_KM = 56.5
TWIN_CENTRES_TOL_KM = 1.0


def test_both_hrvs_ride_one_platform() -> None:
    """A pass imaged by both HRVs: one orbit, attitude, gyro record and set of bulletins;
    each HRV its own lines (XS twice as long), centred on the same instant; and an HRV's
    acquisition is the same emulated alone or with the other."""
    scn = scenario_from_dict(
        {
            "instrument": [
                {**SMALL, "twin": True, "hrv": 1},
                {**SMALL, "twin": True, "hrv": 2, "mode": "XS", "n_detectors": 150, "n_lines": 150},
            ],
            "pass": NO_PASSES,
        }
    )
    p, xs = emulate_pass(scn, render=False)
    assert (p.hrv.number, p.hrv.mode, xs.hrv.number, xs.hrv.mode) == (1, "P", 2, "XS")
    assert p.orbit is xs.orbit and p.attitude is xs.attitude and p.gyros is xs.gyros
    assert xs.hrv.line_period_s == pytest.approx(2 * p.hrv.line_period_s, rel=1e-12)
    assert p.line_times_s.mean() == pytest.approx(xs.line_times_s.mean(), abs=1e-9)
    assert p.gyros.t_s[0] < p.line_times_s[0] and p.gyros.t_s[-1] > p.line_times_s[-1]
    alone = emulate(scn, render=False, instrument=1)
    assert np.array_equal(alone.line_times_s, xs.line_times_s)
    assert np.array_equal(alone.gcps.line, xs.gcps.line)  # its own streams, the same
    assert np.array_equal(
        alone.hrv.bands[0].look_true.psi_y_rad, xs.hrv.bands[0].look_true.psi_y_rad
    )
    assert not np.array_equal(p.gcps.true_line, xs.gcps.true_line)  # but not the other's
    # side by side on the ground, seen at the same instant
    centres = []
    for acq in (p, xs):
        g = truth_model(acq).image_to_ground(
            [(acq.hrv.n_lines - 1) / 2], [(acq.hrv.n_columns - 1) / 2], 450.0
        )
        centres.append(WGS84.to_ecef(g.lat_rad[0], g.lon_rad[0], 0.0))
    distance_km = np.linalg.norm(centres[0] - centres[1]) / 1e3
    assert distance_km == pytest.approx(TWIN_CENTRES_KM, abs=TWIN_CENTRES_TOL_KM)
