"""A DEM grid for level 3, and its heights at geodetic points (no I/O: the file is read by
:func:`levels.readers.dem.read_dem`).

Voids are NaN: a void stays a void, and the pixels over it come out invalid, never given a
made-up height. The vertical datum is declared by the user, because a file rarely says it:

* ``"ellipsoid"``: heights above the WGS84 ellipsoid (what the emulator exports);
* ``"egm96"``: heights above the EGM96 geoid (SRTM, DTED), turned into ellipsoidal heights
  through PROJ's EGM96 grid (``us_nga_egm96_15.tif``). When the grid is not installed PROJ
  would silently apply a "ballpark" null correction, up to 100 m off: :class:`DemError`
  says so and how to install it instead.

:meth:`Dem.heights` samples it bilinearly at geodetic points (NaN where a cell corner is a
void or outside the file).
"""

from __future__ import annotations

import functools
import warnings
from dataclasses import dataclass

import numpy as np
import pyproj
from numpy.typing import ArrayLike, NDArray

from levels.errors import DemError

__all__ = [
    "VERTICAL_DATUMS",
    "Dem",
    "bilinear_surface",
    "egm96_grid_installed",
    "geoid_to_ellipsoid",
]

VERTICAL_DATUMS = ("ellipsoid", "egm96")
_EGM96 = "EPSG:4326+5773"  # WGS84 with EGM96 heights
_ELLIPSOIDAL = "EPSG:4979"  # WGS84 3-D: ellipsoidal heights


@dataclass(frozen=True, eq=False)
class Dem:
    """A DEM grid: heights (NaN at voids) on a north-up or rotated GDAL geotransform in its
    CRS, and the vertical datum they are given in."""

    height_m: NDArray[np.float64]
    geotransform: tuple[float, float, float, float, float, float]
    crs_wkt: str
    vertical: str
    source: str = ""

    def __post_init__(self) -> None:
        if self.vertical not in VERTICAL_DATUMS:
            raise DemError(f"vertical datum {self.vertical!r}: expected one of {VERTICAL_DATUMS}")
        if self.height_m.ndim != 2 or min(self.height_m.shape) < 2:
            raise DemError(f"{self.source or 'DEM'}: needs at least 2 × 2 heights")

    @property
    def spacing(self) -> tuple[float, float]:
        """Pixel size along x and y, in the CRS's units."""
        g = self.geotransform
        return float(np.hypot(g[1], g[4])), float(np.hypot(g[2], g[5]))

    @functools.cached_property
    def _wraps(self) -> bool:
        """Longitudes wrap in this grid: a geographic CRS, north-up, columns eastward."""
        g = self.geotransform
        crs = pyproj.CRS.from_wkt(self.crs_wkt)
        return bool(crs.is_geographic and g[1] > 0 and g[2] == 0 and g[4] == 0)

    @property
    def void_fraction(self) -> float:
        return float(np.mean(np.isnan(self.height_m)))

    def heights(self, lat_rad: ArrayLike, lon_rad: ArrayLike) -> NDArray[np.float64]:
        """Ellipsoidal height (m) at geodetic points, bilinear; NaN on voids and outside."""
        lat, lon = np.broadcast_arrays(
            np.asarray(lat_rad, dtype=np.float64), np.asarray(lon_rad, dtype=np.float64)
        )
        to_dem = pyproj.Transformer.from_crs(
            "EPSG:4326", pyproj.CRS.from_wkt(self.crs_wkt), always_xy=True
        )
        x, y = to_dem.transform(np.degrees(lon.ravel()), np.degrees(lat.ravel()))
        row, col = self.pixel_of(np.asarray(x), np.asarray(y))
        h = self.sample(row, col)
        if self.vertical == "egm96":
            h = geoid_to_ellipsoid(lat.ravel(), lon.ravel(), h)
        return h.reshape(lat.shape)

    def pixel_of(
        self, x: NDArray[np.float64], y: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Fractional (row, column) of CRS coordinates, 0 at the centre of the first pixel.
        In a geographic CRS a longitude is taken on the turn of the grid (a grid from
        179.5° to 180.5° holds −179.8° as 180.2°: a DEM across the antimeridian)."""
        g = self.geotransform
        if self._wraps:
            x = g[0] + np.mod(x - g[0], 360.0)
        det = g[1] * g[5] - g[2] * g[4]
        dx, dy = x - g[0], y - g[3]
        col = (g[5] * dx - g[2] * dy) / det - 0.5
        row = (-g[4] * dx + g[1] * dy) / det - 0.5
        return row, col

    def window(self, rows: slice, cols: slice) -> Dem:
        """The part of the grid in ``rows`` and ``cols`` (clipped to it), georeferenced."""
        r0, r1, _ = rows.indices(self.height_m.shape[0])
        c0, c1, _ = cols.indices(self.height_m.shape[1])
        if r1 - r0 < 2 or c1 - c0 < 2:
            raise DemError(f"{self.source or 'DEM'}: window {rows}, {cols} leaves under 2 × 2")
        g = self.geotransform
        gt = (g[0] + c0 * g[1] + r0 * g[2], g[1], g[2], g[3] + c0 * g[4] + r0 * g[5], g[4], g[5])
        return Dem(self.height_m[r0:r1, c0:c1], gt, self.crs_wkt, self.vertical, self.source)

    def xy_of(
        self, row: NDArray[np.float64], col: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """CRS coordinates of fractional (row, column): the inverse of :meth:`pixel_of`."""
        g = self.geotransform
        return (
            g[0] + (col + 0.5) * g[1] + (row + 0.5) * g[2],
            g[3] + (col + 0.5) * g[4] + (row + 0.5) * g[5],
        )

    def sample(self, row: NDArray[np.float64], col: NDArray[np.float64]) -> NDArray[np.float64]:
        """Heights in the file's datum at fractional pixels, bilinear (NaN if a corner is
        a void or the point is outside the grid)."""
        return bilinear_surface(self.height_m, row, col)


def bilinear_surface(z: NDArray[np.float64], row: ArrayLike, col: ArrayLike) -> NDArray[np.float64]:
    """A grid's bilinear surface at fractional (row, column): NaN outside it or where a
    corner is a void. The arithmetic of the level 3 kernel (``levels.cor.resample``), so
    that the geometry and the image agree to the last bit."""
    row, col = np.asarray(row, dtype=np.float64), np.asarray(col, dtype=np.float64)
    nr, nc = z.shape
    inside = (row >= 0) & (row <= nr - 1) & (col >= 0) & (col <= nc - 1)
    p0 = np.clip(np.floor(np.nan_to_num(row)).astype(np.int64), 0, nr - 2)
    q0 = np.clip(np.floor(np.nan_to_num(col)).astype(np.int64), 0, nc - 2)
    s, t = row - p0, col - q0
    h = (1 - s) * ((1 - t) * z[p0, q0] + t * z[p0, q0 + 1]) + s * (
        (1 - t) * z[p0 + 1, q0] + t * z[p0 + 1, q0 + 1]
    )
    return np.where(inside, h, np.nan)


def _egm96_transformers() -> list[pyproj.Transformer]:
    with warnings.catch_warnings():  # pyproj warns of the missing grid: we say it better
        warnings.simplefilter("ignore", UserWarning)
        group = pyproj.transformer.TransformerGroup(_EGM96, _ELLIPSOIDAL, always_xy=True)
    return [t for t in group.transformers if "ballpark" not in t.description.lower()]


def egm96_grid_installed() -> bool:
    """Whether PROJ has the EGM96 geoid grid (EGM96 heights can be used)."""
    return bool(_egm96_transformers())


def geoid_to_ellipsoid(
    lat_rad: NDArray[np.float64], lon_rad: NDArray[np.float64], h_m: NDArray[np.float64]
) -> NDArray[np.float64]:
    """EGM96 heights to WGS84 ellipsoidal heights through PROJ's EGM96 grid; :class:`DemError`
    when the grid is not installed (PROJ would fall back to a null "ballpark" shift)."""
    exact = _egm96_transformers()
    if not exact:
        raise DemError(
            "EGM96 heights need PROJ's EGM96 geoid grid (us_nga_egm96_15.tif), which is not "
            f"installed in {pyproj.datadir.get_data_dir()}: install it (`projsync --file "
            "us_nga_egm96_15.tif`, or PROJ_NETWORK=ON), or declare the DEM's heights "
            "ellipsoidal"
        )
    _x, _y, h = exact[0].transform(np.degrees(lon_rad), np.degrees(lat_rad), h_m)
    return np.asarray(h, dtype=np.float64)
