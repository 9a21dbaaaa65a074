"""Locate the frame of a real SPOT scene from its DIMAP metadata and compare with the producer.

This is the check a photogrammetrist runs before trusting the model: the four
``Dataset_Frame`` corners and the scene centre, predicted on the ellipsoid (height 0) by the
rigorous model of ``levels.geometry``, against the producer's own coordinates.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from pyproj import Geod

from levels.readers.dimap import AttitudeChoice, read_dimap

__all__ = ["FrameCheck", "check_frame"]

_GEOD = Geod(ellps="WGS84")


@dataclass(frozen=True)
class FrameCheck:
    """Producer's and predicted frame points (4 corners then the centre), and their distance."""

    scene: str
    attitude: str
    row: np.ndarray
    col: np.ndarray
    lat_deg: np.ndarray
    lon_deg: np.ndarray
    predicted_lat_deg: np.ndarray
    predicted_lon_deg: np.ndarray
    error_m: np.ndarray
    roundtrip_px: np.ndarray

    def as_dict(self) -> dict:
        return {
            "scene": self.scene,
            "attitude": self.attitude,
            "points": [
                {
                    "row": int(r),
                    "col": int(c),
                    "lat_deg": float(la),
                    "lon_deg": float(lo),
                    "predicted_lat_deg": float(pla),
                    "predicted_lon_deg": float(plo),
                    "error_m": float(e),
                    "roundtrip_px": float(rt),
                }
                for r, c, la, lo, pla, plo, e, rt in zip(
                    self.row,
                    self.col,
                    self.lat_deg,
                    self.lon_deg,
                    self.predicted_lat_deg,
                    self.predicted_lon_deg,
                    self.error_m,
                    self.roundtrip_px,
                    strict=True,
                )
            ],
            "max_error_m": float(np.max(self.error_m)),
        }


def check_frame(path: str | Path, attitude: AttitudeChoice = "auto") -> FrameCheck:
    """Predict the Dataset_Frame corners and centre of a DIMAP scene and measure the misses.

    ``roundtrip_px`` is the image → ground → image closure at each point (pixels).
    """
    scene = read_dimap(path)
    model = scene.model(attitude=attitude)
    row = np.append(scene.frame_row, scene.center_row)
    col = np.append(scene.frame_col, scene.center_col)
    lat = np.append(scene.frame_lat_deg, scene.center_lat_deg)
    lon = np.append(scene.frame_lon_deg, scene.center_lon_deg)
    ground = model.image_to_ground(row - 1.0, col - 1.0, 0.0)  # DIMAP is 1-based
    plat, plon = np.degrees(ground.lat_rad), np.degrees(ground.lon_rad)
    _, _, dist = _GEOD.inv(lon, lat, plon, plat)
    back = model.ground_to_image(ground.lat_rad, ground.lon_rad, 0.0)
    roundtrip = np.hypot(back.line - (row - 1.0), back.column - (col - 1.0))
    return FrameCheck(scene.name, attitude, row, col, lat, lon, plat, plon, dist, roundtrip)
