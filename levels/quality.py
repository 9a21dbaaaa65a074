"""Quality figures: statistics of checkpoint errors, the way every product reports them.

The emulator knows where every raw pixel truly looks; the station hands the truth to these
functions as arrays (``levels`` never imports the emulator), so the same figures could be
computed on a real scene from surveyed checkpoints.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

if TYPE_CHECKING:  # the geometries import this module's statistics
    from levels.geo.level1b import Level1BGeometry
    from levels.geo.level2a import Level2AGeometry
    from levels.geo.level3 import Level3Geometry
    from levels.geo.scenes import SceneGeometry

__all__ = [
    "CheckpointSource",
    "DemHeadline",
    "FrameHeadline",
    "Headline",
    "error_stats",
    "image_shift_px",
    "scalar_figures",
]


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


def scalar_figures(tree: dict[str, object], prefix: str = "") -> dict[str, object]:
    """The scalar figures of a quality tree, flattened with '/' and as Python numbers; the
    arrays behind them (checkpoint lattices, taps) are left out."""
    out: dict[str, object] = {}
    for k, v in tree.items():
        key = f"{prefix}{k}"
        if isinstance(v, dict):
            out.update(scalar_figures(v, key + "/"))
        elif isinstance(v, np.ndarray) and v.ndim > 0:
            continue
        else:
            out[key] = v.item() if isinstance(v, np.ndarray | np.generic) else v
    return out


@dataclass(frozen=True)
class Headline:
    """A product's headline figures, read back from its flattened quality
    (:func:`scalar_figures`) by the module that flattens it: what the tables of ``station
    run`` and ``station process`` show. None where the product has no such figure.

    Attributes
    ----------
    band
        The band the figures are of (the first with checkpoints or stripes; else None).
    los_rms_m, los_max_m, los_max_px
        Checkpoint errors along the line of sight (RMS and max, m; max, px).
    ground_rms_m
        Checkpoint errors on the ground (RMS, m).
    approx_max_px
        The product's geometry against the rigorous model: its 1B polynomials', its 2A
        inverse's (the method it was made with), or its level 3 anchor grid's (the worst
        band); None for 1A.
    stripes_counts
        The stripe level before and after 1A's calibration (1A only).
    """

    band: str | None
    los_rms_m: float | None
    los_max_m: float | None
    los_max_px: float | None
    ground_rms_m: float | None
    approx_max_px: float | None
    stripes_counts: tuple[float, float] | None

    @classmethod
    def of(cls, figures: Mapping[str, Any], band: str | None = None) -> Headline:
        """The headline of ``figures`` (a product's :func:`scalar_figures`), of ``band``
        (by default the first band that has checkpoints or stripes)."""
        band = band or _first_band(figures)
        cp = f"checkpoints/{band}"
        raw, cal = (
            figures.get(f"stripe_level/{band}/{k}") for k in ("raw_counts", "level_1a_counts")
        )
        return cls(
            band,
            figures.get(f"{cp}/line_of_sight/rms_m"),
            figures.get(f"{cp}/line_of_sight/max_m"),
            figures.get(f"{cp}/line_of_sight/max_px"),
            figures.get(f"{cp}/ground/rms_m"),
            _approximation_max_px(figures),
            (raw, cal) if raw is not None and cal is not None else None,
        )


def _first_band(figures: Mapping[str, Any]) -> str | None:
    for key in figures:
        parts = key.split("/")
        if parts[0] in ("stripe_level", "checkpoints") and len(parts) > 2:
            return parts[1]
    return None


def _approximation_max_px(figures: Mapping[str, Any]) -> float | None:
    anchors = [
        v for k, v in figures.items() if k.startswith("anchor_error_px/") and k.endswith("/max_px")
    ]
    if anchors:
        return float(max(anchors))
    value = figures.get(
        "polynomials_vs_model/max_px",
        figures.get(f"inverse_vs_model/{figures.get('inverse_method', '')}/max_px"),
    )
    return None if value is None else float(value)


def _number(figures: Mapping[str, Any], key: str) -> float | None:
    v = figures.get(key)
    return float(v) if isinstance(v, int | float) and not isinstance(v, bool) else None


@dataclass(frozen=True)
class DemHeadline:
    """A pair's DEM's headline figures, read back from its flattened quality (the truth's
    part, ``station.truth.stereo``): what the console shows. None where the product has
    no such figure (a DEM made without the truth).

    Attributes
    ----------
    rmse_m, nmad_m
        Its heights against the true terrain, as made (its datum from the control points).
    bias_m
        The datum's offset (the mean of the heights' error).
    less_datum_rmse_m
        Its own error, with the datum (offset and tilt) taken off.
    coverage
        The share of the cells both views see that it holds a height for.
    disparity_rms_px
        The dense matching's disparity against the exact one.
    """

    rmse_m: float | None
    bias_m: float | None
    less_datum_rmse_m: float | None
    nmad_m: float | None
    coverage: float | None
    disparity_rms_px: float | None

    @classmethod
    def of(cls, figures: Mapping[str, Any]) -> DemHeadline:
        """The headline of ``figures`` (a DEM product's :func:`scalar_figures`)."""
        return cls(
            _number(figures, "heights/rmse"),
            _number(figures, "heights/datum/bias_m"),
            _number(figures, "heights/datum_removed/rmse"),
            _number(figures, "heights/nmad"),
            _number(figures, "heights/coverage_of_seen"),
            _number(figures, "disparity/rms_px"),
        )


@dataclass(frozen=True)
class FrameHeadline:
    """A SAR frame product's headline figures, read back from its flattened quality (the
    truth's part, ``station.truth.sar``). None where the product has no such figure.

    Attributes
    ----------
    checkpoints_rms_px, checkpoints_rms_east_m, checkpoints_rms_north_m
        Terrain points where the product puts them against where they are.
    relief_ratio_error
        A GEC's: the worst relief displacement measured against ``Δh / tan θ``.
    layover_iou, shadow_iou
        A GTC's masks against the truth's (intersection over union).
    gamma0_to_truth
        γ⁰ by terrain flattening over the world's reflectance, on the mean.
    """

    checkpoints_rms_px: float | None
    checkpoints_rms_east_m: float | None
    checkpoints_rms_north_m: float | None
    relief_ratio_error: float | None
    layover_iou: float | None
    shadow_iou: float | None
    gamma0_to_truth: float | None

    @classmethod
    def of(cls, figures: Mapping[str, Any]) -> FrameHeadline:
        """The headline of ``figures`` (a frame product's :func:`scalar_figures`)."""
        return cls(
            _number(figures, "checkpoints/rms_px"),
            _number(figures, "checkpoints/rms_east_m"),
            _number(figures, "checkpoints/rms_north_m"),
            _number(figures, "relief_displacement/worst_ratio_error"),
            _number(figures, "masks/layover/iou"),
            _number(figures, "masks/shadow/iou"),
            _number(figures, "gamma0/mean_to_truth"),
        )


class CheckpointSource(Protocol):
    """Where checkpoints of a scene truly are, for the ``checkpoints`` quality figures.

    The processing driver (:func:`levels.process.make_scene`) asks it for the errors of
    each band's 1B and 2A geometry; the emulator's truth is one (``station.truth.optical``),
    surveyed points of a real scene would be another. Each method returns a tree: the
    :func:`error_stats` of the line of sight and of the ground, and the lattice behind them.
    """

    def level_1b(
        self, scene: SceneGeometry, geometry: Level1BGeometry, band_index: int, per_side: int
    ) -> dict[str, object]: ...

    def level_2a(
        self, scene: SceneGeometry, geometry: Level2AGeometry, band_index: int, per_side: int
    ) -> dict[str, object]: ...

    def level_3(
        self, scene: SceneGeometry, geometry: Level3Geometry, band_index: int, per_side: int
    ) -> dict[str, object]: ...


#: Width of the window's fall at the edges of the mask of :func:`image_shift_px` (pixels).
SHIFT_TAPER_PX = 16.0


def image_shift_px(
    a: NDArray[np.number], b: NDArray[np.number], mask: NDArray[np.bool_]
) -> tuple[float, float]:
    """Sub-pixel (rows, columns) shift ``s`` with ``a(x) ≈ b(x − s)`` over ``mask`` (where
    both are valid): the whole pixels from the peak of the phase correlation, the fraction
    from the slope of the cross-spectrum's phase once they are taken out (a weighted plane
    fit over the frequencies below a fifth of a cycle per pixel, where the scene has its
    power and the phase does not wrap), both images windowed alike with a fall of
    ``SHIFT_TAPER_PX`` at the mask's edges. A shift of whole images, such as another tool's
    warp of the same scene against ours."""
    # a window falling to 0 over SHIFT_TAPER_PX at the mask's edges: a hard edge common
    # to both images would pull the estimate toward no shift
    taper = np.clip(ndimage.distance_transform_edt(mask) / SHIFT_TAPER_PX, 0.0, 1.0)
    taper = np.sin(0.5 * np.pi * taper) ** 2
    a, b = (
        taper * (x - np.sum(taper * x) / np.sum(taper)) for x in (a.astype(float), b.astype(float))
    )
    cross = np.fft.rfft2(a) * np.conj(np.fft.rfft2(b))
    c = np.fft.irfft2(cross / (np.abs(cross) + 1e-12), a.shape)
    n0, n1 = c.shape
    i, j = np.unravel_index(np.argmax(c), c.shape)
    i, j = (i + n0 // 2) % n0 - n0 // 2, (j + n1 // 2) % n1 - n1 // 2
    fr = np.fft.fftfreq(n0)[:, None]
    fc = np.fft.rfftfreq(n1)[None, :]
    rest = cross * np.exp(2j * np.pi * (fr * i + fc * j))  # phase −2π(fr·δr + fc·δc)
    keep = (np.abs(fr) < 0.2) & (fc < 0.2) & ((fr != 0) | (fc != 0))
    w = np.abs(rest)[keep]
    phase = np.angle(rest[keep])
    design = -2.0 * np.pi * np.stack(np.broadcast_arrays(fr, fc), axis=-1)[keep]
    sw = np.sqrt(w)
    frac, *_ = np.linalg.lstsq(design * sw[:, None], phase * sw, rcond=None)
    return float(i + frac[0]), float(j + frac[1])
