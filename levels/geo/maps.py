"""The map of level 2A products: UTM, the SPOT orbit's Space Oblique Mercator, or any CRS."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pyproj
from numpy.typing import ArrayLike, NDArray

from levels.errors import GeometryError
from levels.geometry.ephemeris import Ephemeris
from levels.spot import ORBIT_INCLINATION_DEG, ORBIT_PERIOD_MIN

__all__ = ["MapGrid", "ascending_node_lon_rad", "map_crs"]


@dataclass(frozen=True)
class MapGrid:
    """The output grid of a map-projected product, as pyresample's ``AreaDefinition``: its
    CRS (WKT), its GDAL geotransform ``(x_min, res, 0, y_max, 0, −res)`` (north up, square
    pixels) and its shape. Pixel ``(I, J)`` has its centre at ``x = x_min + (J + ½)·res``,
    ``y = y_max − (I + ½)·res``. Every map geometry (2A, 2, 3) holds one; products write it
    as their ``crs`` variable and coordinates.

    The geotransform and shape are checked here; the CRS where a grid is read from outside
    (:meth:`check_crs`: parsing a WKT costs a millisecond, GEO makes thousands of grids).
    """

    crs_wkt: str
    geotransform: tuple[float, ...]  # six numbers, checked
    n_rows: int
    n_cols: int

    def __post_init__(self) -> None:
        gt = tuple(float(v) for v in self.geotransform)
        if len(gt) != 6 or gt[2] != 0.0 or gt[4] != 0.0 or not gt[1] > 0 or gt[5] != -gt[1]:
            raise GeometryError(
                f"map grid geotransform {gt}: expected a north-up grid "
                "(x_min, res, 0, y_max, 0, -res)"
            )
        if int(self.n_rows) < 1 or int(self.n_cols) < 1:
            raise GeometryError(f"map grid of {self.n_rows} × {self.n_cols} pixels: none")
        object.__setattr__(self, "geotransform", gt)
        object.__setattr__(self, "n_rows", int(self.n_rows))
        object.__setattr__(self, "n_cols", int(self.n_cols))

    @classmethod
    def north_up(
        cls,
        crs_wkt: str,
        x_min_m: float,
        y_max_m: float,
        pixel_size_m: float,
        n_rows: int,
        n_cols: int,
    ) -> MapGrid:
        """The grid whose upper-left pixel corner is at (``x_min_m``, ``y_max_m``)."""
        res = float(pixel_size_m)
        return cls(crs_wkt, (float(x_min_m), res, 0.0, float(y_max_m), 0.0, -res), n_rows, n_cols)

    def check_crs(self) -> MapGrid:
        """The grid, once its CRS is known to be a WKT PROJ reads; :class:`GeometryError`."""
        try:
            pyproj.CRS.from_wkt(self.crs_wkt)
        except pyproj.exceptions.CRSError as exc:
            raise GeometryError(f"map grid CRS is not a valid WKT ({exc})") from None
        return self

    @property
    def pixel_size_m(self) -> float:
        return self.geotransform[1]

    @property
    def x_min_m(self) -> float:
        """Easting of the grid's left edge."""
        return self.geotransform[0]

    @property
    def y_max_m(self) -> float:
        """Northing of the grid's top edge."""
        return self.geotransform[3]

    @property
    def shape(self) -> tuple[int, int]:
        return self.n_rows, self.n_cols

    def x_m(self) -> NDArray[np.float64]:
        """Easting of the centres of the columns."""
        return np.asarray(self.x_min_m + (np.arange(self.n_cols) + 0.5) * self.pixel_size_m)

    def y_m(self) -> NDArray[np.float64]:
        """Northing of the centres of the rows."""
        return np.asarray(self.y_max_m - (np.arange(self.n_rows) + 0.5) * self.pixel_size_m)

    def map_of(self, i: ArrayLike, j: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Map coordinates (E, N) of output pixel coordinates."""
        return (
            self.x_min_m + (np.asarray(j, dtype=np.float64) + 0.5) * self.pixel_size_m,
            self.y_max_m - (np.asarray(i, dtype=np.float64) + 0.5) * self.pixel_size_m,
        )

    def ij_of_map(
        self, e_m: ArrayLike, n_m: ArrayLike
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Output pixel coordinates of map coordinates."""
        return (
            (self.y_max_m - np.asarray(n_m, dtype=np.float64)) / self.pixel_size_m - 0.5,
            (np.asarray(e_m, dtype=np.float64) - self.x_min_m) / self.pixel_size_m - 0.5,
        )


def map_crs(
    kind: str,
    centre_lat_rad: float,
    centre_lon_rad: float,
    ascending_node_lon_rad: float | None = None,
) -> pyproj.CRS:
    """The map projection of a product.

    ``"utm"``: the UTM zone of the scene centre (WGS84, north or south); ``"som"``: the Space
    Oblique Mercator of the SPOT orbit (needs the longitude of the ascending node); anything
    else is handed to :meth:`pyproj.CRS.from_user_input` (``"EPSG:32721"``, a WKT …).
    """
    if kind == "utm":
        zone = int((np.degrees(centre_lon_rad) + 180.0) // 6.0) % 60 + 1
        return pyproj.CRS.from_epsg((32700 if centre_lat_rad < 0 else 32600) + zone)
    if kind == "som":
        if ascending_node_lon_rad is None:
            raise GeometryError("SOM needs the longitude of the ascending node")
        return pyproj.CRS.from_proj4(
            f"+proj=som +inc_angle={ORBIT_INCLINATION_DEG} +ps_rev={ORBIT_PERIOD_MIN / 1440.0:.9f} "
            f"+asc_lon={np.degrees(ascending_node_lon_rad):.9f} +ellps=WGS84 +units=m +no_defs"
        )
    try:
        return pyproj.CRS.from_user_input(kind)
    except pyproj.exceptions.CRSError as exc:
        raise GeometryError(
            f"map CRS {kind!r}: {exc}; use 'utm', 'som', an EPSG code or a WKT"
        ) from None


def ascending_node_lon_rad(ephemeris: Ephemeris) -> float:
    """Longitude of the orbit's ascending node, from the middle of the ephemeris (for the
    SOM): the node is where the orbit's plane, normal ``r × v``, meets the equator."""
    r = ephemeris.r_ecef_m
    v = ephemeris.v_ecef_m_per_s
    k = len(r) // 2
    h = np.cross(r[k], v[k])
    node = np.cross([0.0, 0.0, 1.0], h)
    return float(np.arctan2(node[1], node[0]))
