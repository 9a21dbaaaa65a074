"""SRTM ``.hgt`` tiles read as the emulated world's terrain.

An SRTM tile ``NxxEyyy.hgt`` is a square grid of big-endian int16 heights (m above the EGM96
geoid, which the emulator takes as ellipsoidal: the world only has to be *a* terrain),
1201 × 1201 at 3 arc-seconds or 3601 × 3601 at 1 arc-second, rows from north to south,
covering the 1° × 1° cell whose south-west corner is in the name; edge rows and columns are
shared with the neighbouring tiles. Voids (−32768) become NaN: rays that land there are
flagged by the imaging kernel, never given a made-up height.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from station.errors import StationError
from station.spacecraft.world import DemGrid

__all__ = ["DemError", "read_hgt"]

_VOID = -32768
_NAME = re.compile(r"^([NS])(\d{2})([EW])(\d{3})\.hgt$", re.IGNORECASE)


class DemError(StationError, ValueError):
    """A DEM file that cannot be read as what its name says."""


def read_hgt(path: str | Path) -> DemGrid:
    """An SRTM tile as a :class:`DemGrid` (latitude increasing with the row)."""
    p = Path(path)
    if not p.is_file():
        raise DemError(f"DEM file {p} not found")
    m = _NAME.match(p.name)
    if not m:
        raise DemError(f"{p.name}: an SRTM tile is named like N00E010.hgt")
    lat0 = int(m.group(2)) * (1 if m.group(1).upper() == "N" else -1)
    lon0 = int(m.group(4)) * (1 if m.group(3).upper() == "E" else -1)
    try:
        raw = np.fromfile(p, dtype=">i2")
    except FileNotFoundError:
        raise DemError(f"DEM file {p} not found") from None
    side = int(np.rint(np.sqrt(raw.size)))
    if side * side != raw.size or side not in (1201, 3601):
        raise DemError(
            f"{p}: {raw.size * 2} bytes is not a 1201² or 3601² grid of int16 (truncated?)"
        )
    heights = raw.reshape(side, side)[::-1].astype(np.float64)  # south → north
    heights[heights == _VOID] = np.nan
    step = np.radians(1.0 / (side - 1))
    lat = np.radians(lat0) + step * np.arange(side)
    lon = np.radians(lon0) + step * np.arange(side)
    return DemGrid(lat, lon, heights, error_rms_m=0.0)
