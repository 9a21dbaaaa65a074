"""Several passes over one ground, as one request of :mod:`levels.work` (a thin face kept
for one release; the plan is :func:`levels.work.plan`).

A :class:`BlockRequest` holds the passes' L0 archives, each pass's control points, the
directories where each pass's scene levels already are (its 1A and 2A), the options and
where the block's products go. :func:`process_block` plans and makes them (tie points, the
block's level 2 on one adjustment, the kinds of a pair, level 3 over the pair's DEM; each
once) and returns what was made as :class:`BlockProducts`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from levels.errors import OptionsError
from levels.makers.pairs import PairMade, PairMaker, PairMeasure, PairScene
from levels.options import ProcessingOptions
from levels.process import PassProducts
from levels.quality import CheckpointSource
from levels.readers.gcp import ControlPointSet
from levels.readers.l0 import L0Archive
from levels.tasks import Runner
from levels.work import (
    LEVEL2,
    PAIRS,
    TIES,
    Pass,
    Request,
    Step,
    TiesFound,
    pair_kinds,
    pass_levels,
    plan,
    run,
    tie_points,
)

if TYPE_CHECKING:
    import numpy as np
    from numpy.typing import NDArray

    from levels.sar.geocoding import Geocoded
    from levels.stereo import StereoDem

__all__ = [
    "LEVEL2",
    "PAIRS",
    "TIES",
    "BlockProducts",
    "BlockRequest",
    "PairMade",
    "PairMaker",
    "PairScene",
    "pair_kinds",
    "pass_levels",
    "process_block",
    "tie_points",
]


@dataclass(frozen=True, eq=False)
class BlockRequest:
    """A block of passes to process (module docstring).

    Attributes
    ----------
    archives, names
        One L0 archive per pass (read lazily), and the name of its products.
    gcps
        Each pass's control points (level 2), without tie points.
    scene_dirs
        Where each pass's scene levels are (its 2A for the tie points, its 1A for a pair).
    options
        What to make (``levels``: 2, 3 and the kinds of a pair; ``stereo``: the pair's DEM
        too) and how; the adjustment is the block's.
    out_dir
        Where ``ties/``, ``block/`` and ``stereo/`` go.
    checkpoints
        Where checkpoints truly are, per archive (the emulator's truth); empty: none.
    ties_dir
        A directory of tie points already matched (``<name>.tie.csv``); None: matched here.
    provenance
        Added to each level 2 and 3 product's ``provenance``.
    """

    archives: tuple[L0Archive, ...]
    names: tuple[str, ...]
    gcps: tuple[ControlPointSet, ...]
    scene_dirs: tuple[Path, ...]
    options: ProcessingOptions
    out_dir: Path
    checkpoints: tuple[CheckpointSource | None, ...] = ()
    ties_dir: Path | None = None
    provenance: dict[str, object] = field(default_factory=dict)

    def __post_init__(self) -> None:
        n = len(self.archives)
        if n < 2:
            raise OptionsError(f"a block takes two passes or more, got {n}")
        for what in ("names", "gcps", "scene_dirs"):
            if len(getattr(self, what)) != n:
                raise ValueError(f"{n} archives but {len(getattr(self, what))} {what}")


@dataclass(frozen=True)
class BlockProducts:
    """What a block made: its tie points (per pair of scenes), every pass's level 2 and 3
    (:class:`levels.process.PassProducts`, in the archives' order) and its pair products."""

    ties: TiesFound
    passes: list[PassProducts]
    pairs: list[PairMade]


class _Given:
    """The block's truth as :class:`levels.work.Measure`: checkpoints per archive, a pair
    product's ``measure``."""

    def __init__(self, request: BlockRequest, measure: PairMeasure | None) -> None:
        cps = request.checkpoints or (None,) * len(request.names)
        self._checkpoints = dict(zip(request.names, cps, strict=True))
        self._measure = measure

    def checkpoints(self, name: str) -> CheckpointSource | None:
        return self._checkpoints.get(name)

    def pair(self, made: StereoDem) -> dict[str, object]:
        return self._measure(made) if self._measure is not None else {}

    def frame(
        self, level: str, geocoded: Geocoded, gamma0: NDArray[np.float32] | None
    ) -> dict[str, object]:
        return {}


def process_block(
    request: BlockRequest, runner: Runner | None = None, measure: PairMeasure | None = None
) -> BlockProducts:
    """Make what the block asks, in order and each once (:func:`levels.work.run`)."""
    passes = tuple(
        Pass((a,), (n,), (g,), made_in=d)
        for a, n, g, d in zip(
            request.archives, request.names, request.gcps, request.scene_dirs, strict=True
        )
    )
    work = Request(
        request.options,
        request.out_dir,
        passes,
        provenance=request.provenance,
        ties_dir=request.ties_dir,
    )
    result = run(plan(work), runner, _Given(request, measure))
    made = {d.name for d in result.passes if d.step is Step.LEVEL2}
    return BlockProducts(
        result.ties,
        [result.pass_products(n, Step.LEVEL2, Step.OVER_PAIR) for n in request.names if n in made],
        [
            PairMade(m.path, m.export, dict(m.quality), dict(m.timings_s))
            for m in result.of(Step.PAIR)
        ],
    )
