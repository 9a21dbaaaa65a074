"""SAR geocoding (:mod:`levels.sar`) against a truth of its own, without the emulator: the
synthetic ERS-like frame (``_orbits.synthetic_frame``) is annotated with five state vectors
of an exact Keplerian orbit, and the truth solves the range–Doppler equations on that orbit
itself (Kepler's equation, not the annotation's interpolation), with PROJ's geodesy:
a ground point is seen at the instant of zero Doppler, ``(P − S(t))·V(t) = 0``, at the
slant range ``|P − S(t)|`` (Curlander's equations, the model of ``levels.sar``).

What ``tests/test_sar.py`` checks against the emulator's frames, here on the geometry alone:
image → ground → image, the location against the truth, GEC over the ellipsoid and GTC
over hills put each output pixel where the truth sees it, and GEC over the hills displaced
by Δh / tan θ toward the radar."""

from __future__ import annotations

import numpy as np
import pyproj
import pytest
from _orbits import DESCENDING_M0_RAD, ecef_states, kepler_eci, synthetic_frame
from numpy.typing import NDArray

from levels.geometry.dem import Dem
from levels.sar import frame_grid
from levels.sar.geocoding import geocode

#: Ground → image by the annotation's five vectors against the exact orbit (slant pixels):
#: the interpolation's error over 40 s of a Keplerian arc (measured 2.5e-7 px).
LOCATION_PX = 1e-3
#: Each output pixel's (line, column) against the truth's (slant pixels): the geocoding's
#: anchors every few pixels, polynomial in height between them (issue 38's 0.1 px; measured
#: 0.0016 px at most, over the ellipsoid and over the hills).
GEOCODED_PX = 0.1
#: GEC's displacement over the hills against Δh / tan θ (relative; the Earth's curvature
#: over the displacement is the rest).
RELIEF_DISPLACEMENT_REL = 0.01
#: GEC's line of a raised point against the truth's: zero Doppler moves it in range alone
#: (measured 0.017 px over 400 m of hills, where the columns move by up to 25 samples).
ZERO_DOPPLER_LINE_PX = 0.05
#: Output pixel (m): about the frame's ground range sample (2 looks of 7.9 m at 23°).
PIXEL_M = 25.0
#: The GEC's reference height and the hills' (m).
BASE_M, HILLS_M = 200.0, 400.0
_GEODETIC = pyproj.Transformer.from_crs(4979, 4978)


def _orbit(t_s: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    return ecef_states(t_s, lambda t: kepler_eci(t, m0_rad=DESCENDING_M0_RAD))


def true_image_of(ann, lat_rad, lon_rad, h_m) -> tuple[NDArray, NDArray, NDArray]:
    """The truth's (line, column) of ground points, and their incidence (rad): Newton on
    the zero-Doppler condition over the exact orbit, from the frame's middle."""
    p = np.stack(_GEODETIC.transform(np.degrees(lat_rad), np.degrees(lon_rad), h_m), axis=-1)
    t = np.full(p.shape[0], ann.first_line_s + 0.5 * ann.shape[0] * ann.line_interval_s)
    for _ in range(8):
        s, v = _orbit(t)
        d = np.einsum("ij,ij->i", p - s, v)
        s2, v2 = _orbit(t + 1e-3)
        slope = (np.einsum("ij,ij->i", p - s2, v2) - d) / 1e-3
        t = t - d / slope
    s, _ = _orbit(t)
    look = p - s
    slant = np.linalg.norm(look, axis=-1)
    normal = np.stack(
        [np.cos(lat_rad) * np.cos(lon_rad), np.cos(lat_rad) * np.sin(lon_rad), np.sin(lat_rad)], -1
    )
    incidence = np.arccos(np.einsum("ij,ij->i", -look / slant[:, None], normal))
    line = (t - ann.first_line_s) / ann.line_interval_s
    return line, (slant - ann.near_range_m) / ann.range_spacing_m, incidence


def _hills(grid) -> Dem:
    """Smooth hills of ±``HILLS_M`` / 2 about ``BASE_M`` + ``HILLS_M`` / 2 over the grid's
    footprint, on a 0.0002° geographic DEM (ellipsoidal heights)."""
    lat, lon = _grid_lat_lon(grid)
    d = 2e-4
    west, north = np.degrees(lon.min()) - 0.01, np.degrees(lat.max()) + 0.01
    rows = int((north - np.degrees(lat.min()) + 0.01) / d) + 2
    cols = int((np.degrees(lon.max()) + 0.01 - west) / d) + 2
    y, x = np.mgrid[0:rows, 0:cols] * d
    h = BASE_M + HILLS_M * (0.5 + 0.5 * np.sin(x / 0.011) * np.cos(y / 0.007))
    crs = pyproj.CRS.from_epsg(4326).to_wkt()
    return Dem(h, (west - d / 2, d, 0.0, north + d / 2, 0.0, -d), crs, "ellipsoid", "hills")


def _grid_lat_lon(grid) -> tuple[NDArray, NDArray]:
    """Every output pixel centre's latitude and longitude (rad), (n_rows, n_cols)."""
    x0, dx, _, y0, _, dy = grid.geotransform
    j, i = np.meshgrid(np.arange(grid.n_cols) + 0.5, np.arange(grid.n_rows) + 0.5)
    to = pyproj.Transformer.from_crs(grid.crs_wkt, 4326, always_xy=True)
    lon, lat = to.transform(x0 + dx * j, y0 + dy * i)
    return np.radians(lat), np.radians(lon)


@pytest.fixture(scope="module")
def frame():
    image = synthetic_frame(n_lines=150, n_samples=150)
    return image, frame_grid(image.annotation, PIXEL_M, BASE_M)


def test_pixel_location_is_the_exact_orbits(frame) -> None:
    image, _ = frame
    ann = image.annotation
    rng = np.random.default_rng(0)
    line, col = rng.uniform(0, 149, 300), rng.uniform(0, 149, 300)
    h = rng.uniform(-200.0, 1500.0, 300)
    lat, lon = ann.ground_of_image(line, col, h)
    back_l, back_c = ann.image_of(lat, lon, h)
    np.testing.assert_allclose(back_l, line, atol=1e-6)
    np.testing.assert_allclose(back_c, col, atol=1e-6)
    true_l, true_c, _ = true_image_of(ann, lat, lon, h)
    assert np.max(np.hypot(back_l - true_l, back_c - true_c)) <= LOCATION_PX


def _miss(g, ann, height: NDArray) -> tuple[NDArray, NDArray, NDArray]:
    """Each valid output pixel's (line, column) minus the truth's, and its incidence."""
    lat, lon = _grid_lat_lon(g.grid)
    ok = np.isfinite(g.intensity)
    tl, tc, inc = true_image_of(ann, lat[ok], lon[ok], height[ok])
    return g.line[ok] - tl, g.column[ok] - tc, inc


def test_gec_on_the_ellipsoid_puts_each_pixel_where_the_truth_sees_it(frame) -> None:
    image, grid = frame
    gec = geocode(image, grid, reference_height_m=BASE_M)
    assert gec.kind == "GEC" and gec.anchor_error["max_px"] < 0.01
    dl, dc, _ = _miss(gec, image.annotation, np.full(grid.shape, BASE_M))
    assert dl.size > 0.4 * gec.intensity.size  # the frame covers its grid's middle
    assert np.max(np.hypot(dl, dc)) <= GEOCODED_PX
    assert not gec.layover.any() and not gec.shadow.any()  # the ellipsoid folds nowhere


def test_gtc_over_hills_is_on_the_truth_and_gec_moves_by_the_relief(frame) -> None:
    """GTC over the hills puts each pixel on the truth at the DEM's height; GEC at the
    base displaces the hills' points by Δh / tan θ, toward the radar."""
    image, grid = frame
    ann = image.annotation
    dem = _hills(grid)
    gtc = geocode(image, grid, dem=dem)
    assert gtc.kind == "GTC"
    dl, dc, _ = _miss(gtc, ann, gtc.height_m.astype(np.float64))
    assert np.max(np.hypot(dl, dc)) <= GEOCODED_PX
    # a point raised by Δh is Δh cos θ nearer the radar in slant range (Δh / tan θ on the
    # ground): GEC, which puts it at the base height, takes its column that much farther
    gec = geocode(image, grid, reference_height_m=BASE_M)
    ok = np.isfinite(gec.intensity) & np.isfinite(gtc.height_m)
    lat, lon = _grid_lat_lon(grid)
    h = gtc.height_m[ok].astype(np.float64)
    tl, tc, inc = true_image_of(ann, lat[ok], lon[ok], h)
    # zero Doppler: the relief moves the points in range alone (up to 25 samples here),
    # its lines by the Earth's rotation under the frame's few hundredths of a pixel
    assert np.max(np.abs(gec.line[ok] - tl)) < ZERO_DOPPLER_LINE_PX
    moved = gec.column[ok] - tc  # GEC's column of the point minus where the hill is seen
    predicted = (h - BASE_M) * np.cos(inc) / ann.range_spacing_m
    big = np.abs(predicted) > 2.0
    assert big.sum() > 100
    np.testing.assert_allclose(moved[big], predicted[big], rtol=RELIEF_DISPLACEMENT_REL)
