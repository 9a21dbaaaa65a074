"""The HRV instruments: look-angle tables with CCD butting and mirror, radiometric response.

Geometry (truth and nominal)
    A detector ``j`` of ``n`` across the swath looks across track at
    ``ψy = (j − (n−1)/2) · p · (N/n) + mirror + twin`` and along track at
    ``ψx = ψx0 + butting(CCD of j) + band offset``, where ``p`` is the detector pitch over
    the focal length (1.1987e-5 rad for P: 13 µm / 1082 mm, measured on the SPOT 2 HRV1 table
    in ``refdata``; twice that for XS), ``N`` the full count (6000 P, 3000 XS) and ``n`` the
    rendered count: fewer detectors see the same swath with a proportionally wider IFOV.
    The P line is four CCDs of 1728 elements butted optically into 6000 useful detectors,
    1500 from each; each CCD sits at its own along-track offset. The mirror turns the view
    across track in steps of 0.6° (step 48 at nadir); in the twin configuration the two HRVs
    look 3.926° apart (paper ``001_…``), HRV1 west of HRV2.
    The truth adds a smooth, unknown calibration error to both angles (a random quadratic
    across the line with ``calibration_error_rad`` RMS at the ends); the nominal table handed
    to the station is the truth without it.

Radiometry
    ``counts = clip(round(g_j · A · L + o_j + noise), 0, 255)``: detector gains ``g_j`` around
    1 (what level 1A equalises), dark offsets ``o_j``, read noise, 8-bit quantisation, with
    ``A = 900`` counts per unit radiance (a reflectance of 0.25 under a zenith Sun gives 225;
    SPOT P scenes of vegetated land sit around 60–100 counts).
    The calibration table handed to the station has its own small errors.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from levels.geometry.sensor import LookAngleTable, mirror_angle_rad
from levels.spot import MODES
from station.scenario import CalibrationConfig, InstrumentConfig

__all__ = [
    "COUNTS_PER_RADIANCE",
    "P_PITCH_RAD",
    "TWIN_SEPARATION_RAD",
    "BandModel",
    "Hrv",
    "build_hrv",
]

P_PITCH_RAD = 1.1987e-5
TWIN_SEPARATION_RAD = np.radians(3.926)
COUNTS_PER_RADIANCE = 900.0
_CCD_USEFUL = MODES["P"].detectors // 4  # useful P detectors per CCD (1500)
#: Along- and across-track offsets of XS bands 1..3 (rad): registration errors of about
#: 0.1–0.3 XS pixel between the bands' lines, as on the real focal plane.
_XS_BAND_OFFSETS_RAD = ((0.0, 0.0), (4.0e-6, -2.0e-6), (-6.0e-6, 3.0e-6))


@dataclass(frozen=True, eq=False)
class BandModel:
    """One band of the rendered HRV.

    ``look_true`` is what the emulator images with; ``look_nominal`` and the ``table_*``
    calibration are what the station is given. Gains and offsets per rendered detector.
    """

    name: str
    look_true: LookAngleTable
    look_nominal: LookAngleTable
    gain: NDArray[np.float64]
    offset_counts: NDArray[np.float64]
    table_gain: NDArray[np.float64]
    table_offset_counts: NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class Hrv:
    """The rendered HRV: mode, mirror, line period, bands, and what the sizes mean.

    ``detector_scale`` is N/n (1 at full resolution); ``first_detector`` is where the
    rendered window starts among the n detectors.
    """

    number: int
    mode: str
    mirror_step: int
    twin: bool
    line_period_s: float
    n_lines: int
    bands: tuple[BandModel, ...]
    n_detectors: int
    first_detector: int
    detector_scale: float
    noise_counts: float
    psf_fwhm_px: float
    psf_samples: int

    @property
    def n_columns(self) -> int:
        return self.bands[0].look_true.n_columns


def _smooth_error(n: int, rms_end: float, rng: np.random.Generator) -> NDArray[np.float64]:
    """A random quadratic across the line whose value at either end has RMS ``rms_end``."""
    x = np.linspace(-1.0, 1.0, n)
    c = rng.standard_normal(3) * rms_end / np.sqrt(3.0)
    return c[0] + c[1] * x + c[2] * (x * x)


def build_hrv(cfg: InstrumentConfig, cal: CalibrationConfig, rng: np.random.Generator) -> Hrv:
    """The HRV of a scenario: truth and nominal tables and radiometry (module docstring)."""
    mode = MODES[cfg.mode]
    full = mode.detectors
    n = cfg.n_detectors or full
    count = cfg.detector_count or n - cfg.first_detector
    scale = full / n
    pitch = P_PITCH_RAD * (1 if cfg.mode == "P" else 2) * scale
    j = np.arange(n, dtype=np.float64)
    psi_y0 = (j - (n - 1) / 2) * pitch + float(mirror_angle_rad(cfg.mirror_step))
    twin = cfg.twin
    if twin:
        psi_y0 += (-0.5 if cfg.hrv == 1 else 0.5) * TWIN_SEPARATION_RAD
    # full-resolution detector number of each rendered detector → its CCD (P: 4 × 1500)
    full_index = (j + 0.5) * scale
    ccd = np.minimum((full_index * (MODES["P"].detectors / full) // _CCD_USEFUL).astype(int), 3)
    butting = np.asarray(cfg.butting_offsets_rad)[ccd]
    window = slice(cfg.first_detector, cfg.first_detector + count)
    column = np.arange(count, dtype=np.float64)
    names = mode.bands
    bands = []
    for b, name in enumerate(names):
        dx, dy = (0.0, 0.0) if cfg.mode == "P" else _XS_BAND_OFFSETS_RAD[b]
        psi_x_nom = butting + dx
        psi_y_nom = psi_y0 + dy
        err_x = _smooth_error(n, cfg.calibration_error_rad, rng)
        err_y = _smooth_error(n, cfg.calibration_error_rad, rng)
        gain = 1.0 + cfg.gain_spread * rng.standard_normal(n)
        offset = 5.0 + cfg.offset_spread_counts * rng.standard_normal(n)
        bands.append(
            BandModel(
                name=name,
                look_true=LookAngleTable(
                    column, (psi_x_nom + err_x)[window], (psi_y_nom + err_y)[window], count
                ),
                look_nominal=LookAngleTable(column, psi_x_nom[window], psi_y_nom[window], count),
                gain=gain[window],
                offset_counts=offset[window],
                table_gain=(gain * (1 + cal.gain_error * rng.standard_normal(n)))[window],
                table_offset_counts=(offset + cal.offset_error_counts * rng.standard_normal(n))[
                    window
                ],
            )
        )
    period = mode.line_period_s
    n_lines = cfg.n_lines or n  # one 60 km scene: square, as many lines as detectors
    return Hrv(
        number=cfg.hrv,
        mode=cfg.mode,
        mirror_step=cfg.mirror_step,
        twin=twin,
        line_period_s=period * scale,
        n_lines=n_lines,
        bands=tuple(bands),
        n_detectors=n,
        first_detector=cfg.first_detector,
        detector_scale=scale,
        noise_counts=cfg.noise_counts,
        psf_fwhm_px=cfg.psf_fwhm_px,
        psf_samples=cfg.psf_samples,
    )
