"""The choices of the processing centre, each declared once as an enum, lowest in the tree.

Every module that takes one of these choices (the options, GEO, COR, the driver) imports it
from here, so a choice is spelled in one place. The enums are :class:`enum.StrEnum`: a member
is its TOML and product spelling (``Resampling.CUBIC == "cubic"``), so options read from a
file, products written by earlier versions and JSON reports need no conversion.

:class:`Level` names the levels this processing centre makes itself, in processing order
(paper ``004_…`` §2: 1A, 1B, 2A; level 2 with control points; level 3 over a DEM). More
levels can be registered (:mod:`levels.registry`): a level's name is a string, and the
built-in ones are these members.
"""

from __future__ import annotations

from enum import StrEnum

__all__ = [
    "AdjustmentScope",
    "DemVertical",
    "GridColumns",
    "GridRows",
    "Interpolation1B",
    "InverseMethod",
    "Level",
    "Resampling",
    "RobustLoss",
]


class Level(StrEnum):
    """The built-in levels, in processing order."""

    L1A = "1A"  # calibrated raw image (COR)
    L1B = "1B"  # 1A resampled along the 1B polynomials f, g, h (INPE eqs. 1-3)
    L2A = "2A"  # system-corrected, map-projected through the 61 × 61 grid and its inverse
    L2 = "2"  # 2A on the model refined with control points (Westin)
    L3 = "3"  # ortho-image: relief displacement removed over a DEM


class Interpolation1B(StrEnum):
    """The column interpolation of 1B resampling (INPE's cubic convolution, or nearest)."""

    NEAREST = "nearest"
    CUBIC = "cubic"


class Resampling(StrEnum):
    """The resampling of the map levels (2A, 2, 3); the kernels take the member's index."""

    NEAREST = "nearest"
    BILINEAR = "bilinear"
    CUBIC = "cubic"


class InverseMethod(StrEnum):
    """How the map levels find the raw pixel of an output pixel (:mod:`levels.geo.level2a`):
    the four nearest direct-grid points (INPE), or polynomials of degree 3 to 5."""

    NEAREST4 = "nearest4"
    POLY3 = "poly3"
    POLY4 = "poly4"
    POLY5 = "poly5"


class GridRows(StrEnum):
    """Rows of the 2A direct grid: at the attitude samples, or INPE's regular 61."""

    ATTITUDE = "attitude"
    REGULAR = "regular"


class GridColumns(StrEnum):
    """Columns of the 2A direct grid: INPE's 61 plus both sides of each CCD butting, or
    INPE's regular 61 only."""

    BUTTING = "butting"
    REGULAR = "regular"


class AdjustmentScope(StrEnum):
    """Level 2's adjustment: the whole pass (Westin), each scene alone, both HRVs of a
    twin pass together, or every pass of a block together, tied by their tie points."""

    PASS = "pass"
    SCENE = "scene"
    TWIN = "twin"
    BLOCK = "block"


class RobustLoss(StrEnum):
    """The loss of level 2's first fit, before blunders are rejected (scipy's names)."""

    LINEAR = "linear"
    SOFT_L1 = "soft_l1"
    HUBER = "huber"
    CAUCHY = "cauchy"


class DemVertical(StrEnum):
    """The datum of a DEM's heights."""

    ELLIPSOID = "ellipsoid"
    EGM96 = "egm96"
