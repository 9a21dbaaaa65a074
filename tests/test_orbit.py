"""Truth orbit: SPOT's phased sun-synchronous orbit, its passes over Cuiabá, TLEs, the Sun.

Outside references: the SPOT 1–4 orbit facts (822 km, 98.7°, 101.4 min, 14 + 5/26 rev/day,
26-day cycle, 0.9856°/day), the Cuiabá station's pass statistics (about 3.9 passes a day,
median 11.4 min at 5° mask: DESIGN.md), Vallado's GMST example 3-5, the Sun at the 2024
March equinox, and real TLEs in refdata.
"""

from __future__ import annotations

import numpy as np
import pytest

from levels.geometry.ellipsoid import WGS84
from levels.geometry.times import Epoch
from station.spacecraft.orbit import (
    RE_M,
    OrbitError,
    TruthOrbit,
    _node_to_node,
    ascending_node_ecef,
    node_state,
    phased_targets,
    secular_targets,
)
from station.spacecraft.passes import find_passes
from station.spacecraft.placement import nadir_point, place_orbit
from station.spacecraft.sun import sun_direction_ecef, sun_direction_eci
from station.spacecraft.tle import read_tle, tle_state_eci

DAY_S = 86400.0
CUIABA = (np.radians(-15.555), np.radians(-56.07), 200.0)
MASK_RAD = np.radians(5.0)
EPOCH = Epoch("1998-02-20", name="day")

PERIOD_TOL_S = 0.1  # "101.4 min" is quoted to 6 s; our solve must hit its own target to 1 ms
RAAN_RATE_TOL_DEG_PER_DAY = 1e-4  # 0.9856°/day quoted to 4 digits
# Ground-track repeat after 26 days. SPOT's track was kept within ±3 km of its reference;
# what the one-revolution solve leaves (the eccentricity vector turning over the cycle) is
# 2.3 km here. A wrong phasing would miss by tens of km per day.
REPEAT_TOL_M = 3_000.0
PASS_TOL = 0.10  # the issue: "within 10 %"


@pytest.fixture(scope="module")
def spot_orbit() -> tuple[TruthOrbit, float]:
    """SPOT's orbit over 26 days and two hours, placed over Cuiabá on the first day."""
    period, rate = phased_targets(369, 26)
    a, i = node_state(period, rate)
    return place_orbit(EPOCH, a, i, 0.0, 10.5, CUIABA[0], CUIABA[1], (0.0, 26 * DAY_S + 7000))


def test_phased_orbit_is_spots() -> None:
    period, rate = phased_targets(369, 26)
    assert period / 60 == pytest.approx(101.4, abs=0.1)
    assert np.degrees(rate) * DAY_S == pytest.approx(0.9856, abs=RAAN_RATE_TOL_DEG_PER_DAY)
    a, i = node_state(period, rate)
    # the integrated orbit keeps both targets node to node
    t_node, d_raan = _node_to_node(a, i, 0.0)
    assert t_node == pytest.approx(period, abs=1e-3)
    assert np.degrees(d_raan / t_node) * DAY_S == pytest.approx(0.98565, abs=1e-5)
    # and its mean elements are SPOT's published ones (822 km, 98.7°)
    from station.spacecraft.orbit import _mean_elements_for

    a_mean, i_mean = _mean_elements_for(period, rate, 0.0)
    assert (a_mean - RE_M) / 1e3 == pytest.approx(822.0, abs=1.0)
    assert np.degrees(i_mean) == pytest.approx(98.7, abs=0.05)


def test_mean_elements_round_trip() -> None:
    period, rate = secular_targets(RE_M + 822e3, 0.0, np.radians(98.7))
    from station.spacecraft.orbit import _mean_elements_for

    a, i = _mean_elements_for(period, rate, 0.0)
    assert a == pytest.approx(RE_M + 822e3, abs=1e-3)
    assert i == pytest.approx(np.radians(98.7), abs=1e-12)


def test_orbit_is_placed_on_the_target_at_1030(spot_orbit) -> None:
    orbit, t_c = spot_orbit
    lat, lon = nadir_point(orbit, np.array([t_c]))
    assert lat[0] == pytest.approx(CUIABA[0], abs=1e-8)
    assert lon[0] == pytest.approx(CUIABA[1], abs=1e-8)
    _, v = orbit.state_ecef([t_c])
    assert v[0, 2] < 0  # descending: the daylight branch
    # local mean solar time of the descending node, found on the integrated orbit
    t = np.linspace(t_c - 1200, t_c, 2401)
    r, _ = orbit.state_ecef(t)
    k = np.flatnonzero(np.diff(np.sign(r[:, 2])) < 0)[0]
    node_lon = np.arctan2(r[k, 1], r[k, 0])
    local_h = np.mod(t[k] / 3600 + np.degrees(node_lon) / 15, 24)
    assert local_h == pytest.approx(10.5, abs=1 / 60)  # within one minute


def test_ground_track_repeats_after_26_days(spot_orbit) -> None:
    orbit, _ = spot_orbit
    shift = np.linalg.norm(ascending_node_ecef(orbit, 26 * DAY_S) - ascending_node_ecef(orbit, 0.0))
    assert shift < REPEAT_TOL_M


def test_passes_over_cuiaba(spot_orbit) -> None:
    orbit, _ = spot_orbit
    passes = find_passes(orbit, *CUIABA, MASK_RAD, 0.0, 26 * DAY_S)
    per_day = len(passes) / 26
    median_min = np.median([p.duration_s for p in passes]) / 60
    assert per_day == pytest.approx(3.9, rel=PASS_TOL)
    assert median_min == pytest.approx(11.4, rel=PASS_TOL)
    daylight = sum(p.daylight for p in passes) / 26
    assert daylight == pytest.approx(2.0, rel=PASS_TOL)  # "2 of them in daylight"
    assert all(p.descending == p.daylight for p in passes)  # 10:30 descending, 22:30 up
    # a pass is above the mask inside and at the mask at its ends
    from station.spacecraft.passes import elevation_rad

    p = passes[0]
    el = elevation_rad(orbit, np.array([p.aos_s, p.t_max_s, p.los_s]), *CUIABA)
    assert el[0] == pytest.approx(MASK_RAD, abs=1e-4)
    assert el[2] == pytest.approx(MASK_RAD, abs=1e-4)
    assert el[1] == pytest.approx(p.max_elevation_rad) and el[1] > MASK_RAD


def test_tle_files_of_refdata(refdata) -> None:
    spot5 = read_tle(refdata / "tle" / "spot5_27421_20020504_orekit.tle")[0]
    assert spot5.name == "SPOT 5"
    assert spot5.epoch_utc == np.datetime64("2002-05-04T11:45:15.695136", "ns")
    # launch-day orbit: 14.26 rev/day, below the operational 822 km
    assert (spot5.semi_major_axis_m() - RE_M) / 1e3 == pytest.approx(802, abs=3)
    spot67 = read_tle(refdata / "tle" / "spot6_spot7_20191030.tle")
    assert [t.name for t in spot67] == ["SPOT 6", "SPOT 7"]
    for t in spot67:
        assert (t.semi_major_axis_m() - RE_M) / 1e3 == pytest.approx(695, abs=5)
    # the state from a TLE, propagated one period, comes back to the same place
    epoch = Epoch(spot5.epoch_utc, name="TLE epoch")
    t0, r0, v0 = tle_state_eci(spot5, epoch)
    assert t0 == 0.0
    assert np.linalg.norm(r0) == pytest.approx(spot5.semi_major_axis_m(), rel=0.01)
    assert np.linalg.norm(v0) == pytest.approx(7450, rel=0.01)


def test_tle_errors(tmp_path) -> None:
    good = (
        "1 27421U 02021A   02124.48976499 -.00021470  00000-0 -89879-2 0    20",
        "2 27421  98.7490 199.5121 0001333 133.9522 226.1918 14.26113993    62",
    )
    f = tmp_path / "bad.tle"
    f.write_text(good[0] + "\n" + good[1].replace("98.7490", "98.7491") + "\n")
    with pytest.raises(OrbitError, match=r"line 2 .* fails its checksum"):
        read_tle(f)
    f.write_text("no elements here\n")
    with pytest.raises(OrbitError, match="no two-line element set"):
        read_tle(f)
    with pytest.raises(OrbitError, match="not found"):
        read_tle(tmp_path / "none.tle")


def test_unreachable_target_is_refused() -> None:
    period, rate = phased_targets(369, 26)
    a, i = node_state(period, rate)
    with pytest.raises(OrbitError, match="beyond the orbit's reach"):
        place_orbit(EPOCH, a, i, 0.0, 10.5, np.radians(89.5), 0.0, (0.0, 600.0))


def test_sun_at_the_2024_march_equinox() -> None:
    # equinox 2024-03-20 03:06 UTC; equation of time −7.5 min puts the subsolar point at
    # 15° × (12 − 3.1 + 7.5/60) = 135.4° E
    epoch = Epoch("2024-03-20T03:06:00")
    u = sun_direction_ecef(epoch, [0.0])[0]
    assert np.degrees(np.arcsin(u[2])) == pytest.approx(0.0, abs=0.02)
    assert np.degrees(np.arctan2(u[1], u[0])) == pytest.approx(135.4, abs=0.1)
    # the ECI and ECEF directions differ by the Earth rotation angle only
    ui = sun_direction_eci(epoch, [0.0])[0]
    era = float(epoch.era_rad(0.0))
    turn = np.angle(np.exp(1j * (np.arctan2(ui[1], ui[0]) - era - np.arctan2(u[1], u[0]))))
    assert turn == pytest.approx(0.0, abs=1e-3)


def test_truth_orbit_is_nan_outside_its_span(spot_orbit) -> None:
    orbit, _ = spot_orbit
    r, v = orbit.state_ecef([-10.0, 27 * DAY_S])
    assert np.isnan(r).all() and np.isnan(v).all()
    r, _ = orbit.state_ecef([1000.0])
    assert WGS84.to_geodetic(r)[2][0] == pytest.approx(822e3, abs=30e3)
