"""UTC parsing, seconds since a named epoch, and the Earth rotation angle."""

from __future__ import annotations

import numpy as np
import pytest

from levels.errors import GeometryError
from levels.geometry import Epoch, parse_utc
from levels.geometry.times import J2000_UTC, earth_rotation_angle_rad

#: The sidereal day (IERS: mean sidereal day of ERA = 86164.0989036903 s of UT1).
SIDEREAL_DAY_S = 86164.0989036903
#: ERA is a linear function of time: round-off only, 1e-12 rad (6 µm at the equator).
ERA_TOL_RAD = 1e-11


def test_parse_iso_and_seconds_since_epoch() -> None:
    epoch = Epoch("2005-03-13T05:21:07.332158", name="scene centre")
    t = parse_utc(["2005-03-13T05:18:28.000000", "2005-03-13T05:21:07.332158Z"])
    assert epoch.seconds(t) == pytest.approx([-159.332158, 0.0], abs=1e-9)
    assert epoch.utc(epoch.seconds(t)).tolist() == t.tolist()


def test_epoch_seconds_keep_nanoseconds_over_days() -> None:
    epoch = Epoch(np.datetime64("2000-01-01T00:00:00", "ns"))
    t = np.datetime64("2000-01-04T00:00:00.000000001", "ns")
    assert epoch.seconds(t) == pytest.approx(3 * 86400 + 1e-9, abs=2e-10)


@pytest.mark.parametrize("bad", ["2005-03-13T05:21:07+02:00", "13/03/2005 05:21", "yesterday"])
def test_bad_times_are_rejected(bad: str) -> None:
    with pytest.raises(GeometryError):
        parse_utc(bad)


def test_era_at_j2000_is_the_iers_constant() -> None:
    # IERS 2010 eq. (5.15): ERA(J2000.0) = 2π × 0.7790572732640.
    assert float(earth_rotation_angle_rad(0.0)) == pytest.approx(
        2 * np.pi * 0.7790572732640, abs=ERA_TOL_RAD
    )


def test_era_advances_one_turn_per_sidereal_day() -> None:
    epoch = Epoch(np.datetime64("2012-01-15T04:48:00", "ns"))
    start = epoch.era_rad(0.0)
    one_day = epoch.era_rad(SIDEREAL_DAY_S)
    assert float(np.mod(one_day - start + np.pi, 2 * np.pi) - np.pi) == pytest.approx(0.0, abs=1e-9)


def test_era_is_the_same_from_any_epoch() -> None:
    a = Epoch(J2000_UTC)
    b = Epoch(np.datetime64("1998-02-20T09:16:40.045", "ns"))
    t = np.datetime64("1998-02-20T09:17:00", "ns")
    assert float(a.era_rad(a.seconds(t))) == pytest.approx(
        float(b.era_rad(b.seconds(t))), abs=ERA_TOL_RAD
    )


def test_gmst_vallado_example_3_5() -> None:
    # Vallado, Fundamentals of Astrodynamics, example 3-5: 1992-08-20 12:14 UT1
    # → GMST = 152.578787810°
    from levels.geometry.times import gmst_rad

    days = (np.datetime64("1992-08-20T12:14:00", "ns") - J2000_UTC).astype(np.int64) / 86400e9
    assert np.degrees(gmst_rad(days)) == pytest.approx(152.578787810, abs=1e-7)
