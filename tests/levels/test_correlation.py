"""Phase correlation (:func:`levels.reference.phase_shifts`), what control points on a
reference are measured with: a known sub-pixel shift of a synthetic texture found."""

from __future__ import annotations

import numpy as np
from scipy.ndimage import gaussian_filter

from levels.reference import phase_shifts

#: Phase correlation's shift on a synthetic texture moved by a known sub-pixel amount,
#: at the shifts the loop ends with (a few tenths of a pixel): the Hann window, the same on
#: both windows, pulls a shift towards 0 by 10-20 % of it (measured 0.04 px at 0.23 px,
#: 0.11 px at 1.62 px), which the loop removes as the model converges.
SHIFT_PX = 0.05


def test_phase_correlation_finds_a_sub_pixel_shift() -> None:
    """A texture and itself moved by (0.17, −0.23) px (in Fourier): ``b(p) = a(p + s)``;
    and a larger shift found in its direction, shorter (the loop's reason)."""
    rng = np.random.default_rng(0)
    big = rng.standard_normal((96, 96))
    big = gaussian_filter(big, 1.5)
    fy, fx = np.meshgrid(np.fft.fftfreq(96), np.fft.fftfreq(96), indexing="ij")
    for s, tol in ((np.array([0.17, -0.23]), SHIFT_PX), (np.array([0.37, -1.62]), 0.2)):
        phase = np.exp(2j * np.pi * (fy * s[0] + fx * s[1]))
        moved = np.fft.ifft2(np.fft.fft2(big) * phase).real
        shift, peak = phase_shifts(big[32:64, 32:64][None], moved[32:64, 32:64][None])
        assert np.allclose(shift[0], s, atol=tol) and peak[0] > 0.5, (s, shift)
