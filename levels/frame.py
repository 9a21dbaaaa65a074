"""A SAR frame's driver: a frame read through any reader (:class:`levels.readers.sar.
SarFrame`) → its geocoded products (the kinds of :attr:`levels.kinds.Unit.FRAME`: GEC, GTC).

:func:`process_frame` makes each kind asked, in order: the frame's map grid (UTM, the
frame's footprint at the reference height widened by the relief's reach), the geocoding
(:func:`levels.sar.geocode`: on the ellipsoid raised to the reference height for GEC, over
the DEM for GTC, with layover and shadow), γ⁰ by terrain flattening when asked (GTC), the
product (:func:`levels.makers.sar.sar_product`) written as ``<name>_<kind>.nc``. What a
product is held to is the caller's (``measure``: the station's truth, or nothing): the
emulator is not needed, and ``station process FRAME --levels GEC,GTC --dem DEM`` runs it on
a frame file alone.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from levels.errors import DemError, OptionsError
from levels.geo.maps import MapGrid
from levels.geometry.dem import Dem
from levels.kinds import Unit
from levels.products import Product, write_product
from levels.readers.sar import SarFrame
from levels.registry import kind, kind_names
from levels.sar import frame_grid
from levels.sar.geocoding import Geocoded, geocode
from levels.sar.radiometry import terrain_flattening

_log = logging.getLogger(__name__)

__all__ = ["FrameMade", "FrameOptions", "Measure", "margin_of_dem", "process_frame"]

#: ERS's steepest incidence across its swath (the near range's, about 19.5°): where relief
#: moves a pixel farthest on the ellipsoid (Δh / tan θ), so a grid's margin for it.
STEEPEST_INCIDENCE_RAD = math.radians(19.5)


@dataclass(frozen=True)
class FrameOptions:
    """How a frame is geocoded.

    Attributes
    ----------
    levels
        The kinds to make (GEC, GTC), in order.
    pixel_size_m
        The output pixel (UTM).
    reference_height_m
        GEC's height above the ellipsoid, and the frame grid's.
    margin_m
        How far the grid reaches beyond the footprint at the reference height, each side:
        the relief's displacement (:func:`margin_of_dem`).
    flatten
        GTC: γ⁰ by radiometric terrain flattening too (Small 2011).
    """

    levels: tuple[str, ...] = ("GEC",)
    pixel_size_m: float = 25.0
    reference_height_m: float = 0.0
    margin_m: float = 0.0
    flatten: bool = False

    def __post_init__(self) -> None:
        known = kind_names(Unit.FRAME)
        bad = [lv for lv in self.levels if lv not in known]
        if bad or not self.levels:
            raise OptionsError(f"levels {list(self.levels)}: a SAR frame makes {', '.join(known)}")
        if not (self.pixel_size_m > 0 and math.isfinite(self.reference_height_m)):
            raise OptionsError(
                f"pixel_size_m {self.pixel_size_m} and reference_height_m "
                f"{self.reference_height_m}: expected a positive pixel and a finite height"
            )


@dataclass(frozen=True, eq=False)
class FrameMade:
    """A frame's product made: its kind, path, the product, the geocoding behind it and
    the wall times of its stages."""

    level: str
    path: Path
    product: Product
    geocoded: Geocoded
    timings_s: dict[str, float] = field(default_factory=dict)


#: ``measure(level, geocoded, gamma0) -> quality``: what a frame's product is held to (the
#: station's truth), from its geocoding and its γ⁰ (None when not flattened).
Measure = Callable[[str, Geocoded, NDArray[np.float32] | None], dict[str, object]]


def margin_of_dem(dem: Dem, reference_height_m: float) -> float:
    """How far relief moves a pixel on the ellipsoid at most: the DEM's greatest height off
    the reference over the tangent of the steepest incidence (m)."""
    h = np.asarray(dem.height_m, dtype=np.float64)
    off = np.nanmax(np.abs(h - reference_height_m)) if np.isfinite(h).any() else 0.0
    return float(off / math.tan(STEEPEST_INCIDENCE_RAD))


def process_frame(
    frame: SarFrame,
    options: FrameOptions,
    out: Path,
    dem: Dem | None = None,
    dem_source: str = "",
    measure: Measure | None = None,
    provenance: dict[str, object] | None = None,
    grid: MapGrid | None = None,
) -> list[FrameMade]:
    """Every kind ``options`` asks of ``frame`` into ``out`` (module docstring); ``dem`` for
    GTC (``dem_source``: its file, as the products name it); ``provenance`` added to the
    products', whose ``inputs`` name the frame and the DEM they were made from; ``grid``
    the frame's grid when already laid (:func:`levels.sar.frame_grid` of the options: a
    caller that checked its memory first)."""
    from levels.makers.sar import sar_product

    image = frame.image()
    ann = image.annotation
    ref = options.reference_height_m
    made = []
    # one grid for every kind: the footprint at the reference height and the relief's reach
    if grid is None:
        grid = frame_grid(ann, options.pixel_size_m, ref, options.margin_m)
    for level in options.levels:
        over_dem = "dem" in kind(level).needs
        if over_dem and dem is None:
            raise DemError(f"{level} geocodes over terrain: give the DEM under the frame")
        timings: dict[str, float] = {}
        t = time.perf_counter()
        g = geocode(image, grid, dem=dem if over_dem else None, reference_height_m=ref)
        timings["geocode"] = time.perf_counter() - t
        _log.info("%s of %s geocoded in %.1f s", level, frame.name, timings["geocode"])
        gamma0 = None
        if over_dem and options.flatten:
            t = time.perf_counter()
            gamma0 = terrain_flattening(g, image)
            timings["flatten"] = time.perf_counter() - t
        quality = dict(measure(level, g, gamma0)) if measure is not None else {}
        if gamma0 is not None and "gamma0" not in quality:
            quality["gamma0"] = {"valid_fraction": float(np.isfinite(gamma0).mean())}
        inputs = [frame.path.name if frame.path else frame.name]
        inputs += [dem_source] if over_dem and dem_source else []
        product = sar_product(
            g,
            image,
            f"{frame.name}_{level}",
            quality=quality,
            dem_source=dem_source if over_dem else "",
            provenance={
                **(provenance or {}),
                "inputs": ", ".join(inputs),
                "route": frame.product_type,  # the format it was read from
            },
            gamma0=gamma0,
            instrument=frame.instrument,
        )
        path = write_product(out / f"{frame.name}_{level}.nc", product)
        made.append(FrameMade(level, path, product, g, timings))
    return made
