"""How far a geometry's approximation is from the rigorous model: the statistics of its
line and column errors at check points, in pixels (the 1B polynomials', the 2A and level 3
grids'), as every product's quality keeps them."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["raw_error_stats"]


def raw_error_stats(dl: NDArray[np.float64], dc: NDArray[np.float64]) -> dict[str, float]:
    """Max and RMS of line, column and total errors (pixels), and how many points."""
    d = np.hypot(dl, dc)
    if d.size == 0:
        return {"n_points": 0}
    return {
        "n_points": int(d.size),
        "max_px": float(d.max()),
        "rms_px": float(np.sqrt(np.mean(d * d))),
        "max_line_px": float(np.abs(dl).max()),
        "max_column_px": float(np.abs(dc).max()),
    }
