"""A product in memory: its bands (:class:`BandImage`) and its trees (:class:`Product`), the
objects every kind's declaration and maker speak of; written and read by
:mod:`levels.products` (the format), on which this leaf does not depend."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from levels.errors import ProductError
from levels.geo.maps import MapGrid

__all__ = ["BandImage", "Product"]


@dataclass(frozen=True, eq=False)
class BandImage:
    """One band of a product: its image (counts, uint8; or a quantity, as its kind's
    :class:`~levels.kinds.BandSpec` declares) and validity mask, same shape (rows, cols)."""

    image: NDArray[np.uint8] | NDArray[np.floating[Any]] | NDArray[np.unsignedinteger[Any]]
    valid: NDArray[np.bool_]

    def __post_init__(self) -> None:
        if self.image.shape != self.valid.shape or self.image.ndim != 2:
            raise ProductError(
                f"band image {self.image.shape} and mask {self.valid.shape} "
                "must be 2-D of the same shape"
            )


@dataclass(frozen=True, eq=False)
class Product:
    """A scene at a level (module docstring). ``attrs`` must hold ``level``; ``map_grid``
    is given for map-projected levels."""

    attrs: dict[str, Any]
    bands: dict[str, BandImage]
    geometry: dict[str, Any] = field(default_factory=dict)
    quality: dict[str, Any] = field(default_factory=dict)
    provenance: dict[str, Any] = field(default_factory=dict)
    map_grid: MapGrid | None = None

    def __post_init__(self) -> None:
        shapes = {b.image.shape for b in self.bands.values()}
        if len(shapes) > 1:
            raise ProductError(f"the bands of a product share one grid, got shapes {shapes}")
        if self.map_grid is not None and shapes != {self.map_grid.shape}:
            raise ProductError(
                f"bands of shape {shapes} on a map grid of {self.map_grid.shape}: the grid's "
                "shape is its images'"
            )
        reserved = {"x", "y", "row", "column", "crs"}
        bad = [n for n in self.bands if n in reserved or n.endswith("_valid") or "/" in n]
        if bad:
            raise ProductError(f"band name {bad[0]!r} is reserved by the product layout")

    @property
    def level(self) -> str:
        return str(self.attrs["level"])
