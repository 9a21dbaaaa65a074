"""COR: each scene at each level (INPE paper ``004_…`` §2.2, §3): radiometric calibration
(1A), deconvolution, and resampling into 1B and 2A. Numerical only, no file I/O."""

from levels.cor.radiometry import (
    calibrate,
    deconvolution_taps,
    deconvolve,
    fir_response,
    mtf,
    stripe_level,
    to_counts,
)
from levels.cor.resample import INTERPOLATIONS_1B, RESAMPLINGS_2A, resample_1b, resample_2a

__all__ = [
    "INTERPOLATIONS_1B",
    "RESAMPLINGS_2A",
    "calibrate",
    "deconvolution_taps",
    "deconvolve",
    "fir_response",
    "mtf",
    "resample_1b",
    "resample_2a",
    "stripe_level",
    "to_counts",
]
