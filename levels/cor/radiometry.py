"""COR's radiometric steps: level 1A calibration, the deconvolution of 1B, the stripe level.

Level 1A (paper ``004_…`` §2.2) is "a normalization of detector responses in each spectral
band". The HRV detector ``j`` answers ``DN = g_j · A · L + o_j`` (counts, ``A`` the band's
absolute gain, ``L`` the radiance); with the calibration table's ``ĝ_j``, ``ô_j``::

    DN_1A = (DN − ô_j) / ĝ_j

so that every detector answers ``A · L``: the vertical stripes of unequal detectors go.
Residual stripes are those of the table's errors.

Level 1B adds "radiometric deconvolutions along lines and columns". The raw pixel's response
is the detector's 1-px box (across track; the integration time along track) convolved with
the optics' PSF, modelled Gaussian: the system MTF per axis is
``H(ν) = sinc(ν) · exp(−2π²σ²ν²)`` (ν in cycles per pixel). The restoration filter is the
Wiener filter ``R = H / (H² + k)`` with ``k`` the noise-to-signal power ratio, normalised to
unit gain at ν = 0 and cut to a short symmetric FIR, applied separably: along lines, then
along columns. Its ringing reaches ``taps // 2`` pixels: pixels that close to an invalid one
are not valid after it.

The stripe level of an image is the RMS, over detectors, of each detector's mean over the
valid lines minus the running median of those means over 15 detectors: what a flat field
would show of unequal detectors, with the scene's own across-track variation taken out.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

__all__ = [
    "calibrate",
    "deconvolution_taps",
    "deconvolve",
    "fir_response",
    "mtf",
    "stripe_level",
    "to_counts",
]

#: Detectors in the running median of the stripe metric.
_STRIPE_WINDOW = 15


def calibrate(
    counts: NDArray[np.uint8],
    valid: NDArray[np.bool_],
    gain: NDArray[np.float64],
    offset_counts: NDArray[np.float64],
) -> NDArray[np.float32]:
    """Level 1A: each detector's counts normalised by the calibration table (float32, 0 where
    not valid)."""
    out = (counts.astype(np.float32) - offset_counts.astype(np.float32)) * (1.0 / gain).astype(
        np.float32
    )
    out[~valid] = 0.0
    return out


def to_counts(image: NDArray[np.floating]) -> NDArray[np.uint8]:
    """8-bit product counts: rounded to the nearest integer and clipped to 0..255."""
    return np.clip(np.rint(image), 0, 255).astype(np.uint8)


def mtf(nu: NDArray[np.float64], psf_fwhm_px: float) -> NDArray[np.float64]:
    """System MTF along one axis: pixel box × Gaussian PSF (``ν`` in cycles per pixel)."""
    sigma = psf_fwhm_px / (2.0 * np.sqrt(2.0 * np.log(2.0)))
    return np.sinc(nu) * np.exp(-2.0 * (np.pi * sigma * nu) ** 2)


def fir_response(taps: NDArray[np.float64], nu: NDArray[np.float64]) -> NDArray[np.float64]:
    """Frequency response of a symmetric FIR at ``ν`` (cycles per pixel)."""
    k = np.arange(taps.size) - taps.size // 2
    return np.cos(2.0 * np.pi * np.outer(np.asarray(nu, dtype=np.float64), k)) @ taps


def deconvolution_taps(
    psf_fwhm_px: float, noise_to_signal: float = 0.05, n_taps: int = 7
) -> NDArray[np.float64]:
    """Symmetric FIR approximating the Wiener restoration ``H / (H² + k)`` (module docstring),
    Hann-windowed, unit DC gain."""
    if n_taps < 1 or n_taps % 2 == 0:
        raise ValueError(f"n_taps={n_taps}: need an odd number of taps")
    n_fft = 1024
    nu = np.fft.rfftfreq(n_fft)
    h = mtf(nu, psf_fwhm_px)
    r = h / (h * h + noise_to_signal)
    kernel = np.fft.fftshift(np.fft.irfft(r, n_fft))
    c, half = n_fft // 2, n_taps // 2
    taps = kernel[c - half : c + half + 1] * np.hanning(n_taps + 2)[1:-1]
    return taps / taps.sum()


def deconvolve(
    image: NDArray[np.float32], valid: NDArray[np.bool_], taps: NDArray[np.float64]
) -> tuple[NDArray[np.float32], NDArray[np.bool_]]:
    """The separable FIR along lines then columns, and the validity it leaves."""
    w = taps.astype(np.float32)
    out = ndimage.convolve1d(image, w, axis=1, mode="nearest")
    ndimage.convolve1d(out, w, axis=0, mode="nearest", output=out)
    reach = taps.size
    ok = ndimage.minimum_filter1d(valid.view(np.uint8), reach, axis=1, mode="nearest")
    ndimage.minimum_filter1d(ok, reach, axis=0, mode="nearest", output=ok)
    return out, ok.view(bool)


def stripe_level(image: NDArray[np.floating], valid: NDArray[np.bool_]) -> float:
    """RMS stripe level of an image (counts; module docstring)."""
    n = valid.sum(axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        means = np.where(valid, image, 0).sum(axis=0, dtype=np.float64) / n
    keep = n > 0
    if keep.sum() < _STRIPE_WINDOW:
        return float("nan")
    m = means[keep]
    resid = m - ndimage.median_filter(m, _STRIPE_WINDOW, mode="nearest")
    return float(np.sqrt(np.mean(resid * resid)))
