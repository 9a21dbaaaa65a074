"""Where a DEM lies under the scenes: which points are on its grid, and the scenes none of
whose corners is (level 3 over a DEM that misses them would fail after the rest was made).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pyproj
from numpy.typing import ArrayLike, NDArray

from levels.errors import DemError
from levels.geo.scenes import SceneGeometry
from levels.geometry.dem import Dem

__all__ = ["check_coverage", "on_dem"]


def on_dem(dem: Dem, lat_rad: ArrayLike, lon_rad: ArrayLike) -> NDArray[np.bool_]:
    """Which geodetic points lie on the DEM's grid (voids or not)."""
    to_dem = pyproj.Transformer.from_crs(
        "EPSG:4326", pyproj.CRS.from_wkt(dem.crs_wkt), always_xy=True
    )
    x, y = to_dem.transform(np.degrees(lon_rad), np.degrees(lat_rad))
    row, col = dem.pixel_of(np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64))
    n_rows, n_cols = dem.height_m.shape
    return np.asarray((row >= -0.5) & (row <= n_rows - 0.5) & (col >= -0.5) & (col <= n_cols - 0.5))


def check_coverage(dem: Dem, scenes: Sequence[SceneGeometry]) -> None:
    """:class:`DemError` naming the first scene none of whose corners nor its centre lies
    on the DEM's grid: level 3 would fail there after everything else was made. A scene
    partly on it is made, its part off the DEM void."""
    if not scenes:
        return
    lat = np.array([np.append(s.corners_lat_rad, s.centre_lat_rad) for s in scenes])
    lon = np.array([np.append(s.corners_lon_rad, s.centre_lon_rad) for s in scenes])
    covered = np.asarray(on_dem(dem, lat, lon).any(axis=1), dtype=bool)  # all scenes at once
    for k, s in enumerate(scenes):
        if not covered[k]:
            raise DemError(
                f"the DEM {dem.source} does not cover scene {s.cut.index} (centre "
                f"{np.degrees(s.centre_lat_rad):.3f}°, {np.degrees(s.centre_lon_rad):.3f}°): "
                "give one over the pass"
            )
