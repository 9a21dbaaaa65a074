"""The station's truth as the one :class:`levels.work.Measure` of a request: each archive's
checkpoints (:mod:`station.truth.optical`), a stereo pair's DEM against the terrain
(:mod:`station.truth.stereo`) and a SAR frame's products (:mod:`station.truth.sar`), for
every unit of work alike."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING

from levels.quality import CheckpointSource
from station.truth.optical import Truth

if TYPE_CHECKING:
    import numpy as np
    from numpy.typing import NDArray

    from levels.sar.geocoding import Geocoded
    from levels.stereo import StereoDem

__all__ = ["StationTruth"]


class StationTruth:
    """The truth of a request (module docstring): ``truths`` per archive name (None: that
    archive's scenario is not known); a pair is measured when the request's first two
    passes both have their truth; ``frame`` a frame's measure
    (:func:`station.run_sar.frame_quality`), or None."""

    def __init__(
        self,
        truths: Mapping[str, Truth | None],
        pair_of: Sequence[str] = (),
        frame: Callable[..., dict[str, object]] | None = None,
    ) -> None:
        self._truths = dict(truths)
        self._pair = [self._truths.get(n) for n in pair_of[:2]]
        self._frame = frame

    def checkpoints(self, name: str) -> CheckpointSource | None:
        return self._truths.get(name)

    def pair(self, made: StereoDem) -> dict[str, object]:
        from station.truth.stereo import StereoTruth, stereo_quality

        a, b = [*self._pair, None, None][:2]
        if a is None or b is None:
            return {}
        truth = StereoTruth(a, b)
        return stereo_quality(made, truth, truth.a.acq.world)

    def frame(
        self, level: str, geocoded: Geocoded, gamma0: NDArray[np.float32] | None
    ) -> dict[str, object]:
        return self._frame(level, geocoded, gamma0) if self._frame is not None else {}
