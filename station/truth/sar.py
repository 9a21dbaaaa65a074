"""The truth of a SAR frame's products (issue 38): where a geocoded frame puts terrain
points against where they are, its relief displacement on the ellipsoid against
Δh / tan θ, its layover and shadow against the truth's, and γ⁰ against the world's own
reflectance. The emulator's frame (:mod:`station.spacecraft.sar`) is the truth; the
products are :mod:`levels.frame`'s.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
import pyproj

from levels.registry import kind

if TYPE_CHECKING:
    import numpy as np
    from numpy.typing import NDArray

    from levels.sar import SarImage
    from levels.sar.geocoding import Geocoded
    from station.spacecraft.sar import SarTruth

__all__ = [
    "CHECKPOINTS",
    "TRUTH_MASK_OVERSAMPLE",
    "checkpoint_errors",
    "flattening_figures",
    "frame_truth",
    "mask_figures",
]

#: Checkpoints drawn across a product (the inner part: 5 % margin each side).
CHECKPOINTS = 200
#: Truth's terrain nodes per output pixel, each way, for the masks (converged at 4: 6
#: gives the same pixels on the tests' worlds).
TRUTH_MASK_OVERSAMPLE = 4


def checkpoint_errors(
    g: Geocoded, truth: SarTruth, n: int = CHECKPOINTS, seed: int = 1
) -> dict[str, Any]:
    """Where a geocoded frame puts terrain points against where they are: ``n`` points drawn
    over the inner output grid, each at the world's height, the truth's (line, column) of
    it taken back onto the output grid through the product's per-pixel (line, column)
    (Newton). Returns the errors (rows, columns: output pixels), the points' heights and
    incidence, and the summary figures."""
    from levels.geo.inverse_grid import bilinear_grid, invert_by_newton

    rng = np.random.default_rng(seed)
    grid = g.grid
    i = rng.uniform(0.05, 0.95, n) * (grid.n_rows - 1)
    j = rng.uniform(0.05, 0.95, n) * (grid.n_cols - 1)
    x, y = grid.map_of(i, j)
    lon, lat = pyproj.Transformer.from_crs(grid.crs_wkt, "EPSG:4326", always_xy=True).transform(
        x, y
    )
    lat, lon = np.radians(lat), np.radians(lon)
    h, _, _ = truth.world.height(lat, lon)
    lt, ct = truth.image_of(lat, lon, h)
    n_l, n_s = truth.annotation.shape
    ok = (lt > 1) & (lt < n_l - 2) & (ct > 1) & (ct < n_s - 2) & np.isfinite(h)
    rows = np.arange(grid.n_rows, dtype=np.float64)
    cols = np.arange(grid.n_cols, dtype=np.float64)

    def raw_of(ii: np.ndarray, jj: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return bilinear_grid(rows, cols, g.line, ii, jj), bilinear_grid(
            rows, cols, g.column, ii, jj
        )

    gi, gj = invert_by_newton(raw_of, lt[ok], ct[ok], (i[ok], j[ok]), 8)
    di, dj = gi - i[ok], gj - j[ok]
    inc = truth.annotation.incidence(lat[ok], lon[ok], h[ok])
    px = grid.pixel_size_m
    e = np.hypot(di, dj)
    e = e[np.isfinite(e)]
    figures = {
        "points": int(e.size),
        "rms_px": float(np.sqrt(np.mean(e**2))) if e.size else float("nan"),
        "max_px": float(np.max(e)) if e.size else float("nan"),
        "rms_m": float(np.sqrt(np.mean(e**2)) * px) if e.size else float("nan"),
        # in map axes: easting (columns), northing (rows, down the grid)
        "rms_east_m": float(np.sqrt(np.nanmean(dj**2)) * px) if e.size else float("nan"),
        "rms_north_m": float(np.sqrt(np.nanmean(di**2)) * px) if e.size else float("nan"),
    }
    return {"di": di, "dj": dj, "height_m": h[ok], "incidence_rad": inc, "figures": figures}


def flattening_figures(
    g: Geocoded, gamma0: NDArray[np.float32], image: SarImage, truth: SarTruth
) -> dict[str, Any]:
    """γ⁰ (:func:`levels.sar.terrain_flattening`) against the world's own reflectance ρ at
    each pixel, outside layover and shadow: under the ``gamma`` law γ⁰ is ρ whatever the
    slope. By sixths of the flattening's correction (γ⁰ over σ⁰ / cos θ on the ellipsoid),
    the mean of γ⁰ / ρ and of σ⁰ / (ρ cos θ) (means: speckle's median is not its mean):
    flat, and not, across the slopes."""
    grid, ann = g.grid, image.annotation
    ok = np.isfinite(gamma0) & np.isfinite(g.intensity) & ~g.layover & ~g.shadow
    x, y = grid.map_of(*np.nonzero(ok))
    to_geo = pyproj.Transformer.from_crs(grid.crs_wkt, "EPSG:4326", always_xy=True)
    lat, lon = (np.radians(a) for a in to_geo.transform(x, y)[::-1])
    rho = truth.world.reflectance(lat, lon, "P")
    on_ellipsoid = g.intensity[ok] / np.cos(ann.incidence(lat, lon, g.height_m[ok]))
    flat, plain = gamma0[ok] / rho, on_ellipsoid / rho
    correction = np.log(gamma0[ok] / on_ellipsoid)
    edges = np.quantile(correction, np.linspace(0.0, 1.0, 7)) if ok.any() else np.zeros(7)
    sixth = np.clip(np.searchsorted(edges, correction, side="right") - 1, 0, 5)

    def by_sixth(v: np.ndarray) -> list[float]:
        return [round(float(np.mean(v[sixth == k])), 4) for k in range(6)]

    return {
        "pixels": int(ok.sum()),
        "mean_to_truth": float(np.mean(flat)) if ok.any() else float("nan"),
        "correction_5_95": [
            round(float(np.exp(q)), 4) for q in np.quantile(correction, [0.05, 0.95])
        ]
        if ok.any()
        else [],
        "by_correction": by_sixth(flat) if ok.any() else [],
        "unflattened_by_correction": by_sixth(plain) if ok.any() else [],
    }


def mask_figures(g: Geocoded, truth: SarTruth) -> dict[str, Any]:
    """Layover and shadow against the truth's, over the frame (its valid pixels' box)."""
    from levels.geo.maps import MapGrid

    valid = np.isfinite(g.intensity)
    if not valid.any():
        return {}
    ii, jj = np.nonzero(valid)
    i0, i1, j0, j1 = ii.min(), ii.max() + 1, jj.min(), jj.max() + 1
    grid = g.grid
    x0, y1 = grid.map_of(i0 - 0.5, j0 - 0.5)
    crop = MapGrid.north_up(
        grid.crs_wkt, float(x0), float(y1), grid.pixel_size_m, int(i1 - i0), int(j1 - j0)
    )
    true = truth.masks(crop, oversample=TRUTH_MASK_OVERSAMPLE)
    inside = valid[i0:i1, j0:j1]
    out: dict[str, Any] = {}
    for name, ours, theirs in (
        ("layover", g.layover[i0:i1, j0:j1], true[0]),
        ("shadow", g.shadow[i0:i1, j0:j1], true[1]),
    ):
        a, b = ours & inside, theirs & inside
        union = int((a | b).sum())
        out[name] = {
            "pixels": int(a.sum()),
            "truth_pixels": int(b.sum()),
            "iou": float((a & b).sum() / union) if union else None,
        }
    return out


def frame_truth(
    level: str,
    g: Geocoded,
    gamma0: NDArray[np.float32] | None,
    image: SarImage,
    truth: SarTruth,
    reference_height_m: float,
    backscatter: str,
) -> dict[str, Any]:
    """A geocoded frame against the truth: its checkpoints; GEC's displacement by relief
    against Δh / tan θ; a product's masks against the truth's; γ⁰ against the world's
    reflectance where the emulator's law makes it so (``backscatter = "gamma"``); a GEC
    made at ``reference_height_m``."""
    ref, pixel = reference_height_m, g.grid.pixel_size_m
    cp = checkpoint_errors(g, truth)
    quality: dict[str, object] = {"checkpoints": cp["figures"]}
    if "dem" not in kind(level).needs:  # on the ellipsoid: moved by the relief
        moved = np.hypot(cp["di"], cp["dj"]) * pixel
        predicted = np.abs(cp["height_m"] - ref) / np.tan(cp["incidence_rad"])
        big = predicted > 2.0 * pixel
        quality["relief_displacement"] = {
            "points": int(big.sum()),
            "predicted_rms_m": float(np.sqrt(np.mean(predicted**2))) if predicted.size else 0.0,
            "worst_ratio_error": float(np.max(np.abs(moved[big] / predicted[big] - 1.0)))
            if big.any()
            else None,
        }
    else:
        quality["masks"] = mask_figures(g, truth)
        if gamma0 is not None and backscatter == "gamma":
            # against the truth where γ⁰ is the reflectance (levels.frame gives the rest
            # their valid share)
            quality["gamma0"] = flattening_figures(g, gamma0, image, truth)
    return quality
