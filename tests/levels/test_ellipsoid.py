"""WGS84 conversions against pyproj, and exact ray intersection at any height."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pyproj import Transformer

from levels.errors import GeometryError
from levels.geometry import WGS84, Ellipsoid

TO_ECEF = Transformer.from_crs("EPSG:4979", "EPSG:4978", always_xy=True)
TO_GEOD = Transformer.from_crs("EPSG:4978", "EPSG:4979", always_xy=True)

#: Forward: closed form on both sides, round-off only (1 µm).
POSITION_TOL_M = 1e-6
#: Our inverse applied to pyproj's forward: round-off only.
ANGLE_TOL_RAD = 1e-12
#: PROJ's own inverse is approximate and loses precision with height (measured: 1e-5 m at
#: 10 km, 1.5e-4 m at 100 km, 8 mm at 1000 km); near the surface it is compared at 0.1 mm.
PYPROJ_INVERSE_HEIGHT_TOL_M = 1e-4
PYPROJ_INVERSE_ANGLE_TOL_RAD = 1e-10
#: The intersection is refined until its step is below 0.1 mm.
INTERSECT_TOL_M = 1e-4

lats = st.floats(-89.999, 89.999)
lons = st.floats(-180.0, 180.0)
heights = st.floats(-500.0, 1_000_000.0)


@settings(max_examples=300, deadline=None)
@given(lat=lats, lon=lons, h=heights)
def test_to_ecef_matches_pyproj(lat: float, lon: float, h: float) -> None:
    ours = WGS84.to_ecef(np.radians(lat), np.radians(lon), h)
    ref = np.array(TO_ECEF.transform(lon, lat, h))
    assert ours == pytest.approx(ref, abs=POSITION_TOL_M)


@settings(max_examples=300, deadline=None)
@given(lat=lats, lon=lons, h=heights)
def test_to_geodetic_inverts_pyproj_forward(lat: float, lon: float, h: float) -> None:
    xyz = np.array(TO_ECEF.transform(lon, lat, h))
    glat, glon, gh = WGS84.to_geodetic(xyz)
    assert float(glat) == pytest.approx(np.radians(lat), abs=ANGLE_TOL_RAD)
    assert float(np.cos(glon - np.radians(lon))) == pytest.approx(1.0, abs=ANGLE_TOL_RAD)
    assert float(gh) == pytest.approx(h, abs=POSITION_TOL_M)


@settings(max_examples=200, deadline=None)
@given(lat=lats, lon=lons, h=st.floats(-500.0, 9000.0))
def test_to_geodetic_agrees_with_pyproj_inverse_near_the_surface(
    lat: float, lon: float, h: float
) -> None:
    xyz = np.array(TO_ECEF.transform(lon, lat, h))
    ref_lon, ref_lat, ref_h = TO_GEOD.transform(*xyz)
    glat, glon, gh = WGS84.to_geodetic(xyz)
    assert float(glat) == pytest.approx(np.radians(ref_lat), abs=PYPROJ_INVERSE_ANGLE_TOL_RAD)
    assert float(glon) == pytest.approx(np.radians(ref_lon), abs=PYPROJ_INVERSE_ANGLE_TOL_RAD)
    assert float(gh) == pytest.approx(ref_h, abs=PYPROJ_INVERSE_HEIGHT_TOL_M)


def test_vectorised_round_trip() -> None:
    rng = np.random.default_rng(1)
    lat = rng.uniform(-np.pi / 2, np.pi / 2, 100_000)
    lon = rng.uniform(-np.pi, np.pi, 100_000)
    h = rng.uniform(-400.0, 900_000.0, 100_000)
    back = WGS84.to_geodetic(WGS84.to_ecef(lat, lon, h))
    assert np.max(np.abs(back[0] - lat)) < ANGLE_TOL_RAD
    assert np.max(np.abs(back[2] - h)) < POSITION_TOL_M


@pytest.mark.parametrize("h_m", [0.0, 850.0, 4000.0, -300.0])
def test_intersection_lies_on_the_ray_at_the_height(h_m: float) -> None:
    rng = np.random.default_rng(2)
    n = 2000
    ground = WGS84.to_ecef(rng.uniform(-1.5, 1.5, n), rng.uniform(-3, 3, n), h_m)
    # Satellites 830 km up, looking down at up to 30° off the vertical.
    lat0, lon0, _ = WGS84.to_geodetic(ground)
    up = WGS84.up(lat0, lon0)
    tilt = rng.normal(size=(n, 3))
    tilt -= np.einsum("ni,ni->n", tilt, up)[:, None] * up  # horizontal
    tilt *= (np.tan(np.radians(30.0)) * rng.uniform(0, 1, n) / np.linalg.norm(tilt, axis=1))[
        :, None
    ]
    origin = ground + 830e3 * (up + tilt)
    direction = ground - origin
    point, ok = WGS84.intersect(origin, direction, np.full(n, h_m))
    assert ok.all()
    assert np.max(np.linalg.norm(point - ground, axis=1)) < INTERSECT_TOL_M


def test_inflated_axes_would_not_be_exact() -> None:
    """The inflated ellipsoid misses a 4 km surface at 27° incidence by about 6 mm, far more
    than the refinement's tolerance: the refinement is what makes the intersection exact."""
    lat, lon, h = np.radians(50.0), np.radians(88.0), 4000.0
    ground = WGS84.to_ecef(lat, lon, h)
    east = np.array([-np.sin(lon), np.cos(lon), 0.0])
    origin = ground + 830e3 * (WGS84.up(lat, lon) + np.tan(np.radians(27)) * east)
    point, ok = WGS84.intersect(origin[None], (ground - origin)[None], h)
    assert ok.all() and np.linalg.norm(point[0] - ground) < INTERSECT_TOL_M
    inflated = Ellipsoid(WGS84.a_m + h, 1.0 / (1.0 - (WGS84.b_m + h) / (WGS84.a_m + h)))
    approx, _ = inflated.intersect(origin[None], (ground - origin)[None], 0.0)
    assert np.linalg.norm(approx[0] - ground) > 10 * INTERSECT_TOL_M


def test_a_ray_that_misses_is_flagged() -> None:
    origin = np.array([[7.2e6, 0.0, 0.0]])
    point, ok = WGS84.intersect(origin, np.array([[0.0, 1.0, 0.0]]), 0.0)
    assert not ok[0] and np.isnan(point).all()


def test_bad_ellipsoid_is_rejected() -> None:
    with pytest.raises(GeometryError, match="inv_f"):
        Ellipsoid(6378137.0, 0.5)
