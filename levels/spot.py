"""SPOT 1–4 facts, one table: the HRV's two modes and the orbit's nominal figures.

Sources: ``../shared/DESIGN.md`` ("Facts to emulate"), the SPOT Geometry Handbook and the
seeds (paper ``004_…``: 6000 P detectors of 10 m, 3000 XS of 20 m, 60 km scenes). Every
module that needs a mode's detector count, line period, band names or nominal pixel takes
it from :data:`MODES`; the emulator's scenario defaults, the instrument model, the
processing centre and the capacity calibration agree by construction.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = [
    "MODES",
    "ORBIT_ALTITUDE_M",
    "ORBIT_INCLINATION_DEG",
    "ORBIT_PERIOD_MIN",
    "SERVICE_UTC",
    "SPECTRAL_BANDS",
    "HrvMode",
    "band_description",
]

#: The days SPOT 1–4 imaged: SPOT 1 launched on 22 February 1986; SPOT 4, the last of
#: them, ended its mission on 11 January 2013 (CNES). A pass outside them is emulated, and
#: said to be so.
SERVICE_UTC = ("1986-02-22", "2013-01-11")

#: Mean altitude at the equator, inclination and nodal period of the SPOT 1–4 orbit.
ORBIT_ALTITUDE_M = 822e3
ORBIT_INCLINATION_DEG = 98.7
ORBIT_PERIOD_MIN = 101.4


@dataclass(frozen=True)
class HrvMode:
    """One HRV mode: its bands, full detector count, line period and nominal pixel."""

    name: str
    bands: tuple[str, ...]
    detectors: int
    line_period_s: float
    pixel_size_m: float

    @property
    def pixels_per_scene(self) -> int:
        """Pixels of a full scene, every band: as many lines as detectors (60 km)."""
        return len(self.bands) * self.detectors * self.detectors


MODES: dict[str, HrvMode] = {
    "P": HrvMode("P", ("P",), 6000, 1.504e-3, 10.0),
    "XS": HrvMode("XS", ("XS1", "XS2", "XS3"), 3000, 3.008e-3, 20.0),
}


#: The HRV's (and SPOT 4 HRVIR's) spectral bands: what each sees and its range (µm), as
#: SPOT Image's handbook gives them. XS1, XS2, XS3 are green, red and near-infrared, not
#: red, green and blue: a viewer is told so (:func:`band_description`).
SPECTRAL_BANDS: dict[str, tuple[str, float, float]] = {
    "P": ("panchromatic", 0.51, 0.73),
    "XS1": ("green", 0.50, 0.59),
    "XS2": ("red", 0.61, 0.68),
    "XS3": ("near-infrared", 0.79, 0.89),
    "SWIR": ("short-wave infrared", 1.58, 1.75),
}


def band_description(name: str) -> str:
    """A band's name with what it sees: ``"XS1 (green, 0.50–0.59 µm)"``; the name alone
    for a band SPOT has not (a DEM's, a SAR frame's)."""
    if name not in SPECTRAL_BANDS:
        return name
    what, lo, hi = SPECTRAL_BANDS[name]
    return f"{name} ({what}, {lo:.2f}–{hi:.2f} µm)"
