"""Stereo's kernels (issue 37) against plain references: epipolar resampling as cubic
convolution at the grids' positions, the least-squares windows of the matcher, a sloping
disparity matched pixel by pixel, PHOTOMOD's common perpendicular of lines that meet, a
DEM's blunders. ``levels`` alone; the pair end to end is ``tests/test_stereo.py``."""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from levels.cor.epipolar import WINDOW_SUMS, resample_epipolar, shift_rows, window_solve
from levels.stereo import blunder_cells, closest_approach, match
from levels.stereo.matching import _window_sums

#: A sloping disparity (0.15 px per px, as on the full pair's steepest slopes) with a
#: v-parallax of 0.1 px, matched on a band-limited texture without noise: measured 0.003 px
#: RMS (0.013 px at most); a window solving for one shift was off by 0.081 px RMS (0.34 at
#: most: the slope times where the texture lies in the window), 0.023 px with the
#: v-parallax alone.
SLOPE_MATCH_PX = 0.01


def test_epipolar_resampling_is_the_cubic_convolution_at_the_grids_positions() -> None:
    """One segment: each output pixel is Keys' cubic convolution of the raw image at the
    bilinearly interpolated (line, column) of its node grid; checked against scipy's
    order-1 interpolation of a linear image (exact for both) and a quadratic one."""
    rng = np.random.default_rng(1)
    lines, cols = np.mgrid[0:120, 0:100].astype(np.float64)
    image = (3.0 * lines + 2.0 * cols).astype(np.float32)
    step, shape = 8, (40, 48)
    nv, nu = -(-(shape[0] - 1) // step) + 1, -(-(shape[1] - 1) // step) + 1
    v, u = np.mgrid[0:nv, 0:nu] * step
    col_nodes = 20.0 + 0.7 * u + 0.2 * v + rng.uniform(-0.3, 0.3, u.shape)
    line_nodes = (30.0 + 0.1 * u + 0.9 * v)[None].astype(np.float64)
    out = resample_epipolar(image, step, col_nodes, line_nodes, np.array([0.0]), shape)
    vv, uu = np.mgrid[0 : shape[0], 0 : shape[1]].astype(np.float64)
    c = ndimage.map_coordinates(col_nodes, [vv / step, uu / step], order=1)
    ln = ndimage.map_coordinates(line_nodes[0], [vv / step, uu / step], order=1)
    # Keys' kernel reproduces a linear image exactly
    np.testing.assert_allclose(out, 3.0 * ln + 2.0 * c, atol=2e-3)


def test_a_shift_along_the_rows_is_cubic_convolution() -> None:
    """``shift_rows`` moves a linear ramp exactly, and marks reads off the row NaN."""
    image = np.tile(np.arange(50, dtype=np.float32) * 1.5, (6, 1))
    shift = np.full(image.shape, 2.25, dtype=np.float32)
    out = shift_rows(image, shift)
    np.testing.assert_allclose(out[:, 1:45], image[:, 1:45] + 1.5 * 2.25, atol=1e-4)
    assert np.isnan(out[:, -1]).all()


def test_each_window_is_the_least_squares_solution_of_its_pixels() -> None:
    """``window_solve`` from the window sums equals numpy's least squares of each window's
    pixels (``y = c + g·(θ₃ + θ₀·x + θ₁·z) + θ₂·gv``, left-out pixels dropped): the shift,
    its variance per unit weight and the residual variance."""
    rng = np.random.default_rng(3)
    w, shape = 7, (20, 24)
    g, gv, y = (rng.normal(size=shape).astype(np.float32) for _ in range(3))
    kept = rng.uniform(size=shape) > 0.2
    g, gv, y = (np.where(kept, x, 0.0).astype(np.float32) for x in (g, gv, y))
    sums = _window_sums(g, gv, y, kept.astype(np.float32), w)
    assert sums.shape[0] == len(WINDOW_SUMS)
    shift, var, s2 = window_solve(sums, w * w // 2)
    h = w // 2
    z, x = np.mgrid[-h : h + 1, -h : h + 1]
    for i, j in [(5, 5), (10, 12), (14, 17)]:
        win = (slice(i - h, i + h + 1), slice(j - h, j + h + 1))
        k = kept[win]
        a = np.column_stack(
            [np.ones(k.sum()), (g[win] * x)[k], (g[win] * z)[k], gv[win][k], g[win][k]]
        )
        theta, sse, *_ = np.linalg.lstsq(a.astype(np.float64), y[win][k], rcond=None)
        n = int(k.sum())
        cov = np.linalg.inv(a.T @ a)
        np.testing.assert_allclose(shift[i, j], theta[4], rtol=1e-3, atol=1e-4)
        np.testing.assert_allclose(var[i, j], cov[4, 4], rtol=1e-3)
        np.testing.assert_allclose(s2[i, j], sse[0] / (n - 5), rtol=1e-3)


def test_a_sloping_disparity_is_matched_at_each_pixel_not_averaged_over_its_window() -> None:
    rng = np.random.default_rng(7)
    n_k = 40
    k = rng.uniform(0.05, 1.6, n_k) * np.exp(1j * rng.uniform(0, 2 * np.pi, n_k))
    amp, phase = rng.uniform(4, 10, n_k) / np.sqrt(n_k / 10), rng.uniform(0, 2 * np.pi, n_k)

    def texture(xx: np.ndarray, yy: np.ndarray) -> np.ndarray:
        f = xx[..., None] * k.real + yy[..., None] * k.imag + phase
        return (128 + np.sum(amp * np.sin(f), axis=-1)).astype(np.float32)

    v, u = np.mgrid[0:160, 0:320].astype(np.float64)
    a, b, dv = -6.0, 0.15, 0.1
    left = texture(u, v)
    right = texture((u - a) / (1 + b), v - dv)  # right(u + a + b·u, v + dv) = left(u, v)
    got = match(left, right, -10.0, 40.0)
    inner = (slice(20, -20), slice(100, -60))  # SGBM leaves its search's width on the left
    e = (got.d - (a + b * u))[inner]
    assert np.isfinite(e).mean() > 0.95
    assert np.sqrt(np.nanmean(e**2)) < SLOPE_MATCH_PX


def test_the_common_perpendicular_of_lines_that_meet_is_their_meeting_point() -> None:
    rng = np.random.default_rng(2)
    p = rng.normal(size=(50, 3)) * 1000.0
    u1, u2 = (x / np.linalg.norm(x, axis=1, keepdims=True) for x in rng.normal(size=(2, 50, 3)))
    mid, miss = closest_approach(p - 700.0 * u1, u1, p + 300.0 * u2, u2)
    np.testing.assert_allclose(mid, p, atol=1e-6)
    np.testing.assert_allclose(miss, 0.0, atol=1e-6)
    # moved apart along their common perpendicular by 2 m: the mid-point stays, miss 2 m
    n = np.cross(u1, u2)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    mid, miss = closest_approach(p - n - 700.0 * u1, u1, p + n + 300.0 * u2, u2)
    np.testing.assert_allclose(mid, p, atol=1e-6)
    np.testing.assert_allclose(np.abs(miss), 2.0, atol=1e-6)


def test_a_spike_in_a_dem_is_a_blunder_and_the_relief_is_not() -> None:
    """A planted patch 300 m off a sloping, rough surface is found, and only it."""
    rng = np.random.default_rng(3)
    rows, cols = np.mgrid[0:200, 0:240].astype(np.float64)
    h = 400.0 + 2.0 * rows + 40.0 * np.sin(cols / 15.0) + rng.normal(0, 3.0, rows.shape)
    h = h.astype(np.float32)
    h[50:53, 60:63] += 300.0
    h[120:140, 10:30] = np.nan  # a hole stays a hole, and does not count
    wild = blunder_cells(h, floor_m=30.0)
    assert wild[50:53, 60:63].all()
    assert wild.sum() == 9
