"""Geometry core: time, frames, ellipsoid, ephemeris, attitude, sensor, photogrammetric model.

Numerical only: no file I/O here. Conventions are stated once in
:mod:`levels.geometry.frames`.
"""

from levels.geometry.attitude import ConstantAttitude, SampledAttitude, integrate_rates
from levels.geometry.ellipsoid import WGS84, Ellipsoid
from levels.geometry.ephemeris import Ephemeris, EphemerisSpacingWarning
from levels.geometry.model import GroundPoints, ImagePoints, LineClock, PushbroomModel
from levels.geometry.sensor import LookAngleTable, mirror_angle_rad
from levels.geometry.times import Epoch, parse_utc

__all__ = [
    "WGS84",
    "ConstantAttitude",
    "Ellipsoid",
    "Ephemeris",
    "EphemerisSpacingWarning",
    "Epoch",
    "GroundPoints",
    "ImagePoints",
    "LineClock",
    "LookAngleTable",
    "PushbroomModel",
    "SampledAttitude",
    "integrate_rates",
    "mirror_angle_rad",
    "parse_utc",
]
