"""What a kind of pair declares (:attr:`levels.kinds.Unit.PAIR`): its maker, the sides it
is made of and what it returns; a leaf that the pair kinds (:mod:`levels.makers.dem`) and
the plan (:mod:`levels.work`) both import."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from levels.choices import Level
from levels.readers.gcp import ControlPointSet

__all__ = ["PairMade", "PairMaker", "PairMeasure", "PairScene"]


@dataclass(frozen=True)
class PairScene:
    """One side of a pair: a scene of a pass and its products by kind (``"2"``, ``"1A"``…)
    and the pass's tie points."""

    name: str
    scene: int
    products: dict[str, Path]
    ties: ControlPointSet


@dataclass(frozen=True)
class PairMade:
    """A pair product made: its path, its export (a GeoTIFF, or None), its quality and the
    wall times of its stages."""

    path: Path
    export: Path | None
    quality: dict[str, object]
    timings_s: dict[str, float]


#: ``measure(intermediate) -> quality``: what a pair product is held to (the station's
#: truth), from what its maker made on the way (a :class:`levels.stereo.StereoDem`).
PairMeasure = Callable[[Any], dict[str, object]]


@dataclass(frozen=True)
class PairMaker:
    """What makes a kind of pair (:attr:`levels.kinds.Unit.PAIR`).

    ``make(a, b, out, measure)`` makes the product of scenes ``a`` and ``b`` into ``out``
    (the product and its export), or returns None when the two do not overlap; ``needs``
    the kinds each scene's products must include."""

    make: Callable[[PairScene, PairScene, Path, PairMeasure | None], PairMade | None]
    needs: tuple[str, ...] = (Level.L1A, Level.L2)
