"""The exported scene's model against the product's: what the DIMAP export tests hold it to."""

from __future__ import annotations

import numpy as np

from levels.geo.scenes import models_of_tree
from levels.products import Product
from levels.readers.dimap import DimapScene
from levels.writers.dimap import BAND_INDEX

#: The issue's bar: the exported scene's model against the product's, at 1000 points.
EXPORT_MODEL_PX = 0.01


def model_gap_px(product: Product, scene: DimapScene, n: int = 1000) -> float:
    """The largest image distance, over every band at ``n`` random points and heights,
    between the product's model and the scene's (read with INPE's attitude rule, the
    station's own)."""
    _, models = models_of_tree(product.geometry)
    rng = np.random.default_rng(35)
    gap = 0.0
    for name, ours in models.items():
        theirs = scene.model(band=BAND_INDEX[name], attitude="integrated_zeroed")
        line = rng.uniform(0, ours.n_lines - 1, n)
        col = rng.uniform(0, ours.n_columns - 1, n)
        h = rng.uniform(-100.0, 2000.0, n)
        g = ours.image_to_ground(line, col, h)
        assert g.ok.all()
        i = theirs.ground_to_image(g.lat_rad, g.lon_rad, h)
        gap = max(gap, float(np.hypot(i.line - line, i.column - col).max()))
    return gap
