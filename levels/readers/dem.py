"""DEMs as users have them, for level 3: any GDAL-readable file, in any CRS.

:func:`read_dem` opens a GeoTIFF, an SRTM ``.hgt`` tile, a DTED cell or anything else GDAL
reads (through rasterio), keeps its CRS and geotransform, and turns its no-data value into
NaN. The vertical datum is declared by the user (:mod:`levels.geometry.dem`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from levels.errors import DemError
from levels.geometry.dem import VERTICAL_DATUMS, Dem, egm96_grid_installed, geoid_to_ellipsoid

__all__ = [
    "EARTH_HEIGHTS_M",
    "VERTICAL_DATUMS",
    "Dem",
    "DemError",
    "egm96_grid_installed",
    "geoid_to_ellipsoid",
    "read_dem",
]


#: Heights on Earth, metres above the ellipsoid: below the Dead Sea's shore (−430 m, the
#: geoid there about +20 m) to above Everest (8849 m), with margin. A DEM's heights outside
#: are not metres of this planet (feet, centimetres, a no-data value not declared).
EARTH_HEIGHTS_M = (-600.0, 9500.0)


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
    return Dem(heights, tuple(float(v) for v in gt), crs_wkt, vertical, str(p))  # type: ignore[arg-type]
