"""Quality figures: statistics of checkpoint errors, the way every product reports them.

The emulator knows where every raw pixel truly looks; the station hands the truth to these
functions as arrays (``levels`` never imports the emulator), so the same figures could be
computed on a real scene from surveyed checkpoints.
"""

from __future__ import annotations

from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

__all__ = ["CheckpointSource", "error_stats", "raw_error_stats", "scalar_figures"]


def error_stats(
    d1_m: NDArray[np.float64], d2_m: NDArray[np.float64], pixel_size_m: float
) -> dict[str, float]:
    """Mean vector, mean, RMS and max of 2-D errors, in metres and pixels.

    ``d1_m``, ``d2_m`` are the two components (east and north on a map, X and Y on the 1B
    plane), product minus truth. NaNs (points not located) are left out and counted.
    """
    ok = np.isfinite(d1_m) & np.isfinite(d2_m)
    a, b = d1_m[ok], d2_m[ok]
    d = np.hypot(a, b)
    if d.size == 0:
        return {"n_points": 0, "n_missing": int(ok.size)}
    out = {
        "n_points": int(d.size),
        "n_missing": int(ok.size - d.size),
        "mean_1_m": float(a.mean()),
        "mean_2_m": float(b.mean()),
        "mean_m": float(d.mean()),
        "rms_m": float(np.sqrt(np.mean(d * d))),
        "max_m": float(d.max()),
    }
    for key in ("mean_m", "rms_m", "max_m"):
        out[key.replace("_m", "_px")] = out[key] / pixel_size_m
    return out


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


def scalar_figures(tree: dict[str, Any], prefix: str = "") -> dict[str, Any]:
    """The scalar figures of a quality tree, flattened with '/' and as Python numbers; the
    arrays behind them (checkpoint lattices, taps) are left out."""
    out: dict[str, Any] = {}
    for k, v in tree.items():
        key = f"{prefix}{k}"
        if isinstance(v, dict):
            out.update(scalar_figures(v, key + "/"))
        elif isinstance(v, np.ndarray) and v.ndim > 0:
            continue
        else:
            out[key] = v.item() if isinstance(v, np.ndarray | np.generic) else v
    return out


class CheckpointSource(Protocol):
    """Where checkpoints of a scene truly are, for the ``checkpoints`` quality figures.

    The processing driver (:func:`levels.process.process_l0`) asks it for the errors of
    each band's 1B and 2A geometry; the emulator's truth is one (``station.sipc.truth``),
    surveyed points of a real scene would be another. Each method returns a tree: the
    :func:`error_stats` of the line of sight and of the ground, and the lattice behind them.
    """

    def level_1b(
        self, scene: Any, geometry: Any, band_index: int, per_side: int
    ) -> dict[str, Any]: ...

    def level_2a(
        self, scene: Any, geometry: Any, band_index: int, per_side: int
    ) -> dict[str, Any]: ...

    def level_3(
        self, scene: Any, geometry: Any, band_index: int, per_side: int
    ) -> dict[str, Any]: ...
