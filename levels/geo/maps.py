"""The map of level 2A products: UTM, the SPOT orbit's Space Oblique Mercator, or any CRS."""

from __future__ import annotations

import numpy as np
import pyproj

from levels.errors import GeometryError
from levels.geometry.ephemeris import Ephemeris
from levels.spot import ORBIT_INCLINATION_DEG, ORBIT_PERIOD_MIN

__all__ = ["ascending_node_lon_rad", "map_crs"]


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
