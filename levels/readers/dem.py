"""DEMs as users have them, for level 3: any GDAL-readable file, in any CRS.

:func:`read_dem` opens a GeoTIFF, an SRTM ``.hgt`` tile, a DTED cell or anything else GDAL
reads (through rasterio), keeps its CRS and geotransform, and turns its no-data value into
NaN. The vertical datum is declared by the user (:mod:`levels.geometry.dem`).
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from levels.errors import DemError
from levels.geometry.dem import VERTICAL_DATUMS, Dem, egm96_grid_installed, geoid_to_ellipsoid

_log = logging.getLogger(__name__)

__all__ = [
    "EARTH_HEIGHTS_M",
    "VERTICAL_DATUMS",
    "Dem",
    "DemError",
    "egm96_grid_installed",
    "geoid_to_ellipsoid",
    "read_dem",
]


#: Heights on Earth, metres above the ellipsoid or the geoid: the deepest sea floor
#: (Challenger Deep, −10 935 m: a bathymetric DEM such as ETOPO1 holds it) to above Everest
#: (8849 m), with the geoid's ±110 m as margin. A DEM's heights outside are not metres of
#: this planet (feet, centimetres, an undeclared no-data value).
EARTH_HEIGHTS_M = (-11_100.0, 9_000.0)


def read_dem(path: str | Path, vertical: str) -> Dem:
    """A DEM file (GeoTIFF, SRTM ``.hgt``, DTED, any GDAL raster) with its declared vertical
    datum (``"ellipsoid"`` or ``"egm96"``); the first band, no-data as NaN."""
    import rasterio
    from rasterio.errors import RasterioIOError

    p = Path(path)
    if vertical not in VERTICAL_DATUMS:
        raise DemError(f"{p}: vertical datum {vertical!r}: expected one of {VERTICAL_DATUMS}")
    if not p.is_file():
        raise DemError(f"DEM file {p} not found")
    try:
        with rasterio.open(p) as ds:
            if ds.crs is None:
                raise DemError(f"{p}: no CRS; a DEM must say where it is")
            band = ds.read(1, masked=True)
            heights = np.ma.filled(band.astype(np.float64), np.nan)
            gt = ds.transform.to_gdal()
            crs_wkt = ds.crs.to_wkt()
    except RasterioIOError as exc:
        raise DemError(f"{p}: not a raster GDAL can read ({exc})") from None
    heights[~np.isfinite(heights)] = np.nan
    _check_heights(p, heights)
    return Dem(heights, tuple(float(v) for v in gt), crs_wkt, vertical, str(p))  # type: ignore[arg-type]


def _check_heights(path: Path, heights: NDArray[np.float64]) -> None:
    """:class:`DemError` when the DEM has no height or heights off the Earth
    (``EARTH_HEIGHTS_M``); a warning when they look like kilometres (every height within
    ±9 and not whole numbers: a low plain in metres, or a mountain range in km)."""
    finite = heights[np.isfinite(heights)]
    if not finite.size:
        raise DemError(f"{path}: no height at all (every cell no-data)")
    lo, hi = float(finite.min()), float(finite.max())
    a, b = EARTH_HEIGHTS_M
    if lo < a or hi > b:
        raise DemError(
            f"{path}: heights from {lo:g} to {hi:g}: not metres on Earth ({a:g} to {b:g} m); "
            "in feet or centimetres, or an undeclared no-data value?"
        )
    if max(abs(lo), abs(hi)) <= 9.0 and hi - lo > 0.01 and np.any(finite != np.round(finite)):
        _log.warning(
            "%s: every height within ±9 (from %g to %g): kilometres rather than metres?",
            path,
            lo,
            hi,
        )
