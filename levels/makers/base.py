"""What a level declares, and the scene's workspace it is made in.

A level is a :class:`LevelMaker`: plain functions of a :class:`SceneWork`, the workspace of
one scene in one task. The workspace holds what every level of the scene shares (the pass
context, the scene's geometry, the images made so far) and the results of the *steps*
(functions of the workspace decorated with :func:`scene_step`): a step is computed the first
time a level asks for it and kept for the others, so the 2A grids made for level 2A also
serve level 2's "before" checkpoints, and level 2's refined model also serves level 3.
Every step and stage is timed by :meth:`SceneWork.timed`, exclusive of the steps it calls,
so the timings of a scene add up to its wall time.

The driver (:func:`levels.process.make_scene`) does the same for every level:

1. ``prepare(work)``: the level's geometry, before any pixel is read (timed apart);
2. per band, ``image(work, band, pixels)``: with the calibrated pixels for levels that
   read them (``Reads.CALIBRATED``: 1A), then with the deconvolved ones, NaN where invalid
   (``Reads.DECONVOLVED``: every resampled level); INPE's "the raw image read only once"
   (paper ``004_…`` §2.2): the raw counts are read, calibrated and deconvolved once per
   band for all levels;
3. ``quality(work)`` and ``geometry_tree(work)``, ``map_grid(work)``: the product.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from enum import StrEnum
from functools import wraps
from pathlib import Path
from typing import Any, TypeVar

import numpy as np
from numpy.typing import NDArray

from levels.adjust import Adjustment
from levels.geo.scenes import PassGeometry, SceneGeometry
from levels.geometry.dem import Dem
from levels.options import ProcessingOptions
from levels.products import BandImage, MapGrid
from levels.quality import CheckpointSource
from levels.readers.l0 import L0Archive

__all__ = [
    "BandPixels",
    "LevelMaker",
    "Need",
    "PassContext",
    "Reads",
    "SceneWork",
    "no_map_grid",
    "per_band",
    "scene_step",
]

T = TypeVar("T")


class Need(StrEnum):
    """What a level needs of the whole pass, made once before its scenes."""

    ADJUSTMENT = "adjustment"  # the model refined on control points (levels.adjust)
    DEM = "dem"  # a DEM under the pass (levels.readers.dem)


class Reads(StrEnum):
    """Which pixels a level's image is made from."""

    CALIBRATED = "calibrated"  # the raw counts calibrated (level 1A's own pixels)
    DECONVOLVED = "deconvolved"  # calibrated, deconvolved, NaN where invalid (resampling)


@dataclass(frozen=True, eq=False)
class PassContext:
    """What every scene of a pass shares: the archive, GEO's pass set-up, the options and
    what follows from them, and the levels to make (``makers``, in processing order): those
    the options ask for are written, the others are made for them; ``given``: levels of
    the options made already by an earlier step, whose model the others are made on
    (:attr:`levels.process.ProcessingRequest.given`)."""

    archive: L0Archive
    pg: PassGeometry
    options: ProcessingOptions
    pixel_size_m: float
    taps: NDArray[np.float64]
    out: Path
    name: str
    checkpoints: CheckpointSource | None
    provenance: dict[str, object]
    adjustment: Adjustment | None
    dem: Dem | None
    makers: tuple[LevelMaker, ...]
    given: frozenset[str] = frozenset()


@dataclass(frozen=True, eq=False)
class BandPixels:
    """One band of the scene as a level's image reads it: the raw ``counts`` and their
    ``valid`` mask (rows × detectors), and ``values``: calibrated radiances for
    ``Reads.CALIBRATED``, deconvolved with NaN where invalid for ``Reads.DECONVOLVED``."""

    counts: NDArray[np.uint8]
    valid: NDArray[np.bool_]
    values: NDArray[np.floating]


class SceneWork:
    """One scene's workspace (module docstring): its pass context and geometry, the images
    made so far per level and band, per-band figures the images leave for the quality
    (``figures[key][band]``), the cached steps and the timings."""

    def __init__(self, ctx: PassContext, scene: SceneGeometry) -> None:
        self.ctx = ctx
        self.scene = scene
        self.images: dict[str, dict[str, BandImage]] = {m.name: {} for m in ctx.makers}
        self.figures: dict[str, dict[str, object]] = {}
        self.timings_s: dict[str, float] = {}
        self._steps: dict[Callable[..., Any], Any] = {}
        self._inner_s: list[float] = []  # time spent in nested timed blocks, per level

    @property
    def options(self) -> ProcessingOptions:
        return self.ctx.options

    @property
    def bands(self) -> list[str]:
        """The scene's bands, the first one's output grid shared by the others."""
        return list(self.scene.models)

    def makes(self, level: str) -> bool:
        """Whether ``level`` is made for this scene (asked, or needed by a level asked), or
        was made by an earlier step (:attr:`PassContext.given`)."""
        return level in self.ctx.given or any(m.name == level for m in self.ctx.makers)

    @contextmanager
    def timed(self, name: str) -> Iterator[None]:
        """Add the block's wall time to ``timings_s[name]``, less the time of the timed
        blocks and steps nested in it (they have their own entries)."""
        t0 = time.perf_counter()
        self._inner_s.append(0.0)
        try:
            yield
        finally:
            inner = self._inner_s.pop()
            elapsed = time.perf_counter() - t0
            self.timings_s[name] = self.timings_s.get(name, 0.0) + elapsed - inner
            if self._inner_s:
                self._inner_s[-1] += elapsed

    def step(self, fn: Callable[[SceneWork], T]) -> T:
        """``fn(self)``, computed once per scene and timed under its name."""
        if fn not in self._steps:
            with self.timed(fn.__name__):
                self._steps[fn] = fn(self)
        value: T = self._steps[fn]
        return value


def scene_step(fn: Callable[[SceneWork], T]) -> Callable[[SceneWork], T]:
    """A step of a scene (module docstring): ``step(work)`` computes ``fn(work)`` the first
    time it is asked for in a scene, and gives the same object afterwards."""

    @wraps(fn)
    def cached(work: SceneWork) -> T:
        return work.step(fn)

    return cached


def per_band(scene: SceneGeometry, make: Callable[[str, T | None], T]) -> dict[str, T]:
    """A geometry per band, every band made ``like`` the first one (on its output grid), so
    that the bands of a product are registered."""
    first, *others = scene.models
    out = {first: make(first, None)}
    for b in others:
        out[b] = make(b, out[first])
    return out


def no_map_grid(work: SceneWork) -> MapGrid | None:
    """The map grid of a level in the raw image's geometry: none."""
    return None


@dataclass(frozen=True)
class LevelMaker:
    """A level, declared once (module docstring).

    Attributes
    ----------
    name
        The level's name: ``[processing] levels`` and product names use it.
    doc
        One line: what the level is.
    image
        ``image(work, band, pixels) -> BandImage``: one band of the level's image.
    quality
        ``quality(work) -> tree``: the level's quality group (after every band's image).
    geometry_tree
        ``geometry_tree(work) -> tree``: the product's ``geometry`` group.
    prepare
        ``prepare(work)``: the geometry the images need, made before any pixel is read.
    map_grid
        ``map_grid(work)``: the output grid of a map-projected level, else None.
    reads
        Which pixels ``image`` reads (:class:`Reads`).
    needs
        What the level needs of the whole pass (:class:`Need`): the driver makes it once.
    requires
        Levels whose images this one reads (``work.images[level][band]``): made before it,
        and made for it when not asked (then not written).
    raw_geometry
        The image is in the raw image's geometry (1A): its product has no pixel size.
    """

    name: str
    doc: str
    image: Callable[[SceneWork, str, BandPixels], BandImage]
    quality: Callable[[SceneWork], dict[str, object]]
    geometry_tree: Callable[[SceneWork], dict[str, object]]
    prepare: Callable[[SceneWork], object] | None = None
    map_grid: Callable[[SceneWork], MapGrid | None] = no_map_grid
    reads: Reads = Reads.DECONVOLVED
    needs: frozenset[Need] = frozenset()
    requires: tuple[str, ...] = ()
    raw_geometry: bool = False
