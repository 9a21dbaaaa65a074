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

import numba as nb
import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from levels.threads import over_blocks

__all__ = [
    "calibrate",
    "counts_in_place",
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
    out = np.empty(counts.shape, dtype=np.float32)
    over_blocks(
        _calibrate,
        counts.shape[0],
        np.ascontiguousarray(counts),
        np.ascontiguousarray(valid),
        offset_counts.astype(np.float32),
        (1.0 / gain).astype(np.float32),
        out,
    )
    return out


def to_counts(image: NDArray[np.floating]) -> NDArray[np.uint8]:
    """8-bit product counts: rounded to the nearest integer and clipped to 0..255 (in one
    temporary: each fresh 144 MB array of a full P scene costs its page faults)."""
    work = np.rint(image)
    np.clip(work, 0, 255, out=work)
    return work.astype(np.uint8)


def counts_in_place(image: NDArray[np.floating]) -> NDArray[np.floating]:
    """``image`` rounded and clipped to the 8-bit counts :func:`to_counts` writes, in place
    and in its own type: the level-1A counts as a float image, what every resampled level
    reads (``levels.process``)."""
    np.rint(image, out=image)
    np.clip(image, 0, 255, out=image)
    return image


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
    nu = np.fft.rfftfreq(n_fft).astype(np.float64, copy=False)
    h = mtf(nu, psf_fwhm_px)
    r = h / (h * h + noise_to_signal)
    kernel = np.fft.fftshift(np.fft.irfft(r, n_fft))
    c, half = n_fft // 2, n_taps // 2
    taps = kernel[c - half : c + half + 1] * np.hanning(n_taps + 2)[1:-1]
    return taps / taps.sum()


@nb.njit(cache=True, nogil=True)
def _fir_along_lines(lo, hi, src, w, out):
    """``out = src ∗ w`` along each line (axis 1), edges replicated. The symmetric form and
    its order of operations in double precision are those of ``scipy.ndimage.convolve1d``:
    the same bytes, on every core."""
    m = src.shape[1]
    half = w.size // 2
    for i in range(lo, hi):
        row = src[i]
        for j in range(m):
            acc = np.float64(row[j]) * w[half]
            for d in range(half, 0, -1):
                acc += (np.float64(row[max(j - d, 0)]) + np.float64(row[min(j + d, m - 1)])) * w[
                    half - d
                ]
            out[i, j] = acc


@nb.njit(cache=True, nogil=True)
def _fir_along_columns(lo, hi, src, w, out):
    """``out = src ∗ w`` along each column (axis 0), edges replicated, a line at a time
    (contiguous rows, where scipy walks the columns with a stride): the same operations
    per pixel as :func:`_fir_along_lines`."""
    n, m = src.shape
    half = w.size // 2
    for i in range(lo, hi):
        acc = np.empty(m)
        for j in range(m):
            acc[j] = np.float64(src[i, j]) * w[half]
        for d in range(half, 0, -1):
            lo, hi = max(i - d, 0), min(i + d, n - 1)
            for j in range(m):
                acc[j] += (np.float64(src[lo, j]) + np.float64(src[hi, j])) * w[half - d]
        for j in range(m):
            out[i, j] = acc[j]


@nb.njit(cache=True, nogil=True)
def _valid_across(lo, hi, valid, half, across):
    """Per line, whether every pixel within ``half`` columns is valid (edges replicated):
    the run of valid pixels across the window, a line at a time."""
    m = valid.shape[1]
    for i in range(lo, hi):
        bad = 0  # invalid pixels in the window [j − half, j + half], clipped
        for j in range(min(half, m - 1) + 1):
            bad += not valid[i, j]
        for j in range(m):
            across[i, j] = bad == 0
            if j + half + 1 < m:
                bad += not valid[i, j + half + 1]
            if j - half >= 0:
                bad -= not valid[i, j - half]


@nb.njit(cache=True, nogil=True)
def _valid_after(lo, hi, across, half, out):
    """A pixel is valid after the FIR when every pixel within ``half`` lines and columns
    of it was: :func:`_valid_across` of the ``2·half + 1`` lines around it."""
    n, m = across.shape
    for i in range(lo, hi):
        for j in range(m):
            out[i, j] = True
        for ii in range(max(i - half, 0), min(i + half, n - 1) + 1):
            for j in range(m):
                out[i, j] &= across[ii, j]


@nb.njit(cache=True, nogil=True)
def _calibrate(lo, hi, counts, valid, offset, inv_gain, out):
    m = counts.shape[1]
    for i in range(lo, hi):
        for j in range(m):
            out[i, j] = (np.float32(counts[i, j]) - offset[j]) * inv_gain[j] if valid[i, j] else 0


#: Columns per block of :func:`_column_sums`.
_SUM_BLOCK = 256


@nb.njit(cache=True, nogil=True)
def _column_sums(lo, hi, image, valid, sums, count):
    """Per column of blocks ``lo … hi − 1`` (of ``_SUM_BLOCK`` columns), the sum (float64)
    and the number of valid pixels, line after line in order (numpy's ``sum(axis=0)``
    arithmetic: the same figures)."""
    n, m = image.shape
    for blk in range(lo, hi):
        j0, j1 = blk * _SUM_BLOCK, min(blk * _SUM_BLOCK + _SUM_BLOCK, m)
        for i in range(n):
            for j in range(j0, j1):
                if valid[i, j]:
                    sums[j] += np.float64(image[i, j])
                    count[j] += 1


def deconvolve(
    image: NDArray[np.float32], valid: NDArray[np.bool_], taps: NDArray[np.float64]
) -> tuple[NDArray[np.float32], NDArray[np.bool_]]:
    """The separable FIR along lines then columns, and the validity it leaves (float32
    between the passes, as ``scipy.ndimage.convolve1d`` into a float32 array would)."""
    w = np.asarray(taps, dtype=np.float32).astype(np.float64)  # the FIR applied: float32
    if w.ndim != 1 or w.size % 2 == 0 or not np.array_equal(w, w[::-1]):
        raise ValueError(f"deconvolution: need a symmetric FIR of odd length, got {taps}")
    src = np.ascontiguousarray(image, dtype=np.float32)
    along = np.empty(src.shape, dtype=np.float32)
    over_blocks(_fir_along_lines, src.shape[0], src, w, along)
    out = np.empty(src.shape, dtype=np.float32)
    over_blocks(_fir_along_columns, src.shape[0], along, w, out)
    ok = np.empty(src.shape, dtype=bool)
    across = np.empty(src.shape, dtype=bool)
    over_blocks(_valid_across, src.shape[0], np.ascontiguousarray(valid), w.size // 2, across)
    over_blocks(_valid_after, src.shape[0], across, w.size // 2, ok)
    return out, ok


def stripe_level(
    image: NDArray[np.floating] | NDArray[np.uint8], valid: NDArray[np.bool_]
) -> float:
    """RMS stripe level of an image (counts; module docstring)."""
    sums, n = np.zeros(image.shape[1]), np.zeros(image.shape[1], dtype=np.int64)
    n_blocks = -(-image.shape[1] // _SUM_BLOCK)
    over_blocks(
        _column_sums, n_blocks, np.ascontiguousarray(image), np.ascontiguousarray(valid), sums, n
    )
    with np.errstate(invalid="ignore", divide="ignore"):
        means = sums / n
    keep = n > 0
    if keep.sum() < _STRIPE_WINDOW:
        return float("nan")
    m = means[keep]
    resid = m - ndimage.median_filter(m, _STRIPE_WINDOW, mode="nearest")
    return float(np.sqrt(np.mean(resid * resid)))
