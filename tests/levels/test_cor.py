"""COR: calibration, deconvolution, and the resampling kernels of 1B and 2A."""

from __future__ import annotations

import numpy as np
import pytest
from _orbits import synthetic_pass

from levels.cor.radiometry import (
    calibrate,
    deconvolution_taps,
    deconvolve,
    fir_response,
    mtf,
    stripe_level,
    to_counts,
)
from levels.cor.resample import resample_1b, resample_2a, with_nan
from levels.geo.level1b import level1b_geometry
from levels.geo.level2a import level2a_geometry, map_crs

#: float32 image values against float64 references: 1e-3 counts is far below the 8-bit step.
FLOAT32_COUNTS = 1e-3


@pytest.fixture(scope="module")
def scene():
    """A 400 × 400 scene (a synthetic pass, ``_orbits.synthetic_pass``) and its pixel."""
    _pg, scene, res = synthetic_pass(400, 400)
    return scene, res


@pytest.fixture(scope="module")
def geometry(scene):
    scene, res = scene
    g2 = level2a_geometry(scene, res, map_crs("utm", scene.centre_lat_rad, scene.centre_lon_rad))
    return level1b_geometry(scene, res), g2


def test_calibration_removes_detector_stripes() -> None:
    rng = np.random.default_rng(3)
    lines, dets = 400, 300
    scene = (
        80.0
        + 20.0 * np.sin(np.linspace(0, 6, dets))[None, :]
        + 5.0 * rng.standard_normal((lines, dets))
    )
    gain = 1.0 + 0.05 * rng.standard_normal(dets)
    offset = 5.0 + 2.0 * rng.standard_normal(dets)
    counts = to_counts(gain * scene + offset)
    valid = np.ones(counts.shape, dtype=bool)
    before = stripe_level(counts.astype(np.float32), valid)
    after = stripe_level(calibrate(counts, valid, gain, offset), valid)
    assert before > 3.0  # 5 % of 80 counts and 2 counts of offsets
    assert after < before / 5  # what remains is the scene's own noise in the means


def test_deconvolution_raises_the_mtf_and_keeps_the_mean() -> None:
    taps = deconvolution_taps(1.2, 0.05)
    assert taps.sum() == pytest.approx(1.0, abs=1e-12)
    gain_nyquist = abs(fir_response(taps, np.array([0.5]))[0])
    assert mtf(np.array([0.5]), 1.2)[0] * gain_nyquist > 1.5 * mtf(np.array([0.5]), 1.2)[0]
    img = np.full((50, 60), 100.0, dtype=np.float32)
    valid = np.ones(img.shape, dtype=bool)
    valid[20, 30] = False
    out, ok = deconvolve(img, valid, taps)
    assert out[ok] == pytest.approx(100.0, abs=FLOAT32_COUNTS)
    assert not ok[17:24, 27:34].any() and ok[:16].all()  # the ringing reach is masked


def test_deconvolution_is_scipys_separable_convolution() -> None:
    """The parallel kernels give the bytes of ``scipy.ndimage.convolve1d`` (edges
    replicated, float32 between the passes) and the validity of a minimum filter over the
    FIR's reach."""
    from scipy import ndimage

    rng = np.random.default_rng(5)
    img = rng.uniform(-10.0, 260.0, (61, 47)).astype(np.float32)
    valid = rng.random(img.shape) > 0.02
    taps = deconvolution_taps(1.5, 0.05)
    w = taps.astype(np.float32)
    ref = ndimage.convolve1d(img, w, axis=1, mode="nearest")
    ndimage.convolve1d(ref, w, axis=0, mode="nearest", output=ref)
    ref_ok = ndimage.minimum_filter(valid.view(np.uint8), taps.size, mode="nearest")
    out, ok = deconvolve(img, valid, taps)
    assert np.array_equal(out, ref) and np.array_equal(ok, ref_ok.view(bool))
    with pytest.raises(ValueError, match="symmetric FIR of odd length"):
        deconvolve(img, valid, np.array([0.2, 0.8]))


def _ramp(n_lines: int, n_cols: int) -> np.ndarray:
    line, col = np.mgrid[0:n_lines, 0:n_cols].astype(np.float64)
    return (20.0 + 0.3 * line + 0.2 * col).astype(np.float32)


def test_2a_kernel_samples_where_the_grid_says(geometry) -> None:
    """Cubic convolution reproduces a linear ramp exactly, so the output must equal the
    ramp at the (L, C) the inverse grid gives for each pixel."""
    _g1, g2 = geometry
    img = _ramp(400, 400)
    out, ok = resample_2a(img, np.ones(img.shape, bool), g2, "cubic")
    i, j = np.nonzero(ok)
    line, col = g2.raw_of(i, j)
    expected = 20.0 + 0.3 * line + 0.2 * col
    assert np.abs(out[i, j] - np.rint(expected)).max() <= 1  # 8-bit rounding at .5 edges
    assert np.mean(out[i, j] == np.rint(expected)) > 0.99
    assert 0.4 < ok.mean() < 0.9  # the raw footprint, rotated, inside a north-up grid


@pytest.mark.parametrize("method", ["nearest", "bilinear", "cubic"])
def test_2a_tiles_equal_whole(geometry, method) -> None:
    _g1, g2 = geometry
    rng = np.random.default_rng(5)
    img = (rng.random((400, 400)) * 200).astype(np.float32)
    valid = rng.random((400, 400)) > 0.01
    whole, ok = resample_2a(img, valid, g2, method)
    nan_img = with_nan(img, valid)
    for rows, cols in [(slice(0, 77), slice(13, 200)), (slice(77, 500), slice(0, 13))]:
        tile, tok = resample_2a(nan_img, None, g2, method, rows, cols)
        assert np.array_equal(tile, whole[rows, cols])
        assert np.array_equal(tok, ok[rows, cols])
    # a pixel is valid only if every raw pixel it uses is
    assert ok.mean() < resample_2a(img, np.ones_like(valid), g2, method)[1].mean()


@pytest.mark.parametrize("method", ["nearest", "bilinear", "cubic"])
def test_2a_spans_and_pieces_equal_pixel_by_pixel(scene, method) -> None:
    """With inverse-grid cells 30 pixels wide (a full scene's), a row's pixels go by spans
    (one cell's pixels at once), spans across a CCD butting or an image edge by pieces of
    8, and the rest pixel by pixel: each must give the bytes of its pixel computed alone
    (a tile one column wide, where every span is one pixel)."""
    scene, res = scene
    crs = map_crs("utm", scene.centre_lat_rad, scene.centre_lon_rad)
    wide = level2a_geometry(scene, res, crs, inverse_step_px=30)
    assert wide.inverse_step == (30, 30) and wide.segment_first_column.size == 4
    rng = np.random.default_rng(11)
    img = (rng.random((400, 400)) * 200).astype(np.float32)
    img = with_nan(img, rng.random((400, 400)) > 0.002)
    whole, ok = resample_2a(img, None, wide, method)
    cols = [
        resample_2a(img, None, wide, method, cols=slice(j, j + 1))
        for j in range(wide.map_grid.n_cols)
    ]
    assert np.array_equal(whole, np.hstack([c[0] for c in cols]))
    assert np.array_equal(ok, np.hstack([c[1] for c in cols]))
    assert 0.4 < ok.mean() < 0.9


@pytest.mark.parametrize("interpolation", ["nearest", "cubic"])
def test_1b_pixel_is_valid_when_every_raw_pixel_it_reads_is(geometry, interpolation) -> None:
    """The mask of 1B, against the raw pixels each output pixel reads by INPE's f, g, h
    (one raw line, ``f(I)`` rounded; one column, or Keys' four, edge columns replicated);
    and the same bytes whether the kernel is given the mask or the NaN image."""
    g1, _g2 = geometry
    rng = np.random.default_rng(2)
    img = (rng.random((400, 400)) * 200).astype(np.float32)
    valid = rng.random((400, 400)) > 0.02
    out, ok = resample_1b(img, valid, g1, interpolation, lines="nearest")
    i, j = np.mgrid[0 : g1.n_rows, 0 : g1.n_cols]
    line, col = g1.raw_of(i.ravel(), j.ravel())
    li = np.floor(line + 0.5).astype(int)
    inside = (li >= 0) & (li < 400) & (col >= -0.5) & (col <= 399.5)
    if interpolation == "cubic":
        first = np.floor(col).astype(int) - 1
        taps = np.clip(first[:, None] + np.arange(4), 0, 399)
    else:
        taps = np.clip(np.floor(col + 0.5).astype(int), 0, 399)[:, None]
    reads_valid = valid[np.clip(li, 0, 399)[:, None], taps].all(axis=1)
    expected = (inside & reads_valid).reshape(ok.shape)
    assert np.array_equal(ok, expected)
    # 2 % of the raw pixels are invalid: at least as many 1B pixels (more with Keys' 4 taps)
    assert 0.3 < ok.mean() < 1.0 - 0.015 and not out[~ok].any()
    again = resample_1b(with_nan(img, valid), None, g1, interpolation, lines="nearest")
    assert np.array_equal(again[0], out) and np.array_equal(again[1], ok)


def test_1b_along_the_track_too_sits_on_the_continuous_line(geometry) -> None:
    """``lines = "cubic"`` (the default): each row Keys' four lines about ``f(I)``, not the
    nearest one; a ramp along the track is reproduced on the continuous line (within a
    count's rounding), where INPE's nearest line is off by up to half a line's step."""
    g1, _g2 = geometry
    img = _ramp(400, 400)
    valid = np.ones(img.shape, bool)
    out, ok = resample_1b(img, valid, g1, "cubic")
    i, j = np.nonzero(ok)
    line, col = g1.raw_of(i, j)
    inner = (col >= 1.0) & (col < 398.0) & (line >= 1.0) & (line < 398.0)
    on_line = 20.0 + 0.3 * line + 0.2 * col
    assert np.abs(out[i, j] - on_line)[inner].max() <= 0.5 + FLOAT32_COUNTS
    nearest, _ = resample_1b(img, valid, g1, "cubic", lines="nearest")
    assert np.abs(nearest[i, j] - on_line)[inner].max() > 0.5 + 0.1  # the half line's step
    tile, tok = resample_1b(img, valid, g1, "cubic", slice(50, 150), slice(100, 300))
    assert np.array_equal(tile, out[50:150, 100:300]) and np.array_equal(tok, ok[50:150, 100:300])


@pytest.mark.parametrize("interpolation", ["nearest", "cubic"])
def test_1b_kernel(geometry, interpolation) -> None:
    g1, _g2 = geometry
    img = _ramp(400, 400)
    valid = np.ones(img.shape, bool)
    out, ok = resample_1b(img, valid, g1, interpolation, lines="nearest")
    i, j = np.nonzero(ok)
    line, col = g1.raw_of(i, j)
    expected = (
        20.0 + 0.3 * np.rint(line) + 0.2 * (col if interpolation == "cubic" else np.rint(col))
    )
    # Keys' cubic reproduces the ramp where its four columns are inside; in the first and
    # last column and a half it reads replicated edge columns, off by up to one column's
    # step of the ramp (0.2 counts): with the Earth-rotation skew, every line has such pixels
    inner = (col >= 1.0) & (col < 398.0) if interpolation == "cubic" else np.ones(col.size, bool)
    assert np.abs(out[i, j] - expected)[inner].max() <= 0.5 + FLOAT32_COUNTS
    assert np.abs(out[i, j] - expected).max() <= 0.5 + 0.2 + FLOAT32_COUNTS
    tile, tok = resample_1b(
        img, valid, g1, interpolation, slice(50, 150), slice(100, 300), lines="nearest"
    )
    assert np.array_equal(tile, out[50:150, 100:300]) and np.array_equal(tok, ok[50:150, 100:300])
    # left skew: h(I) black, invalid pixels start each line, up to where g meets column −½
    rows = np.arange(g1.n_rows, dtype=float)
    j_left = g1.g.solve(np.full(rows.size, -0.5), np.zeros(rows.size)) + g1.h(rows)
    line_inside = (np.rint(g1.f(rows)) >= 0) & (np.rint(g1.f(rows)) < 400)
    for r in np.flatnonzero(line_inside)[::17]:
        black = int(np.floor(j_left[r]))
        assert not ok[r, : max(black, 0)].any()
        assert ok[r, black + 1 : black + 5].all()


def test_image_shift_is_measured_to_a_hundredth_of_a_pixel() -> None:
    """The phase correlation behind the RPC warp's check, on a smooth random scene moved by
    a known sub-pixel shift (scipy's spline shift as the outside reference)."""
    from scipy import ndimage

    from levels.quality import image_shift_px

    rng = np.random.default_rng(11)
    scene = ndimage.gaussian_filter(rng.normal(0, 50, (256, 300)), 2.0) + 100.0
    moved = ndimage.shift(scene, (0.3, -1.7), order=3, mode="nearest")
    mask = np.zeros(scene.shape, dtype=bool)
    mask[10:-10, 10:-10] = True
    dr, dc = image_shift_px(moved, scene, mask)
    assert dr == pytest.approx(0.3, abs=0.01) and dc == pytest.approx(-1.7, abs=0.01)
