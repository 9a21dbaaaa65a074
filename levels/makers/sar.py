"""An ERS SAR frame geocoded (:mod:`levels.sar`, ADRIN §5): on the ellipsoid at a reference
height (GEC) or over a DEM (GTC, with layover and shadow masks and γ⁰), declared once.

Their products carry the frame's annotation (``geometry/sar``: state vectors, line time,
range sampling, Doppler) and their headline figures are the checkpoints against the truth
(RMS in pixels and metres east and north) and, for GTC, the masks' agreement with the
truth's (IoU), when the station measured them.
"""

from __future__ import annotations

import datetime as dt
from collections.abc import Mapping
from typing import Any

import numpy as np
from numpy.typing import NDArray

from levels import __version__
from levels.kinds import (
    BandSpec,
    Browse,
    Export,
    Figure,
    Inspection,
    ProductKind,
    Unit,
    flag_band,
    headline,
)
from levels.products import BandImage, Product
from levels.quality import FrameHeadline
from levels.sar import ANCHOR_STEP_PX, SarImage
from levels.sar.geocoding import Geocoded

__all__ = ["GEC", "GTC", "sar_product"]


def _inspect(product: Product) -> Inspection:
    a, sar = product.attrs, product.geometry["sar"]
    section = {
        "kind": str(sar["kind"]),
        "image_shape": np.asarray(sar["image_shape"]).tolist(),
        "range_spacing_m": float(sar["range_spacing_m"]),
        "line_interval_s": float(sar["line_interval_s"]),
        "height_range_m": np.asarray(sar["height_range_m"]).tolist(),
        "dem_source": str(sar.get("dem_source", "")),
    }
    shape, heights = section["image_shape"], section["height_range_m"]
    where = f"over the DEM {section['dem_source']}" if section["dem_source"] else "on the ellipsoid"
    title = (
        f"level {a.get('level')} of {a.get('instrument')} frame {a.get('name')} ({shape[0]} "
        f"lines × {shape[1]} samples of {section['range_spacing_m']:.1f} m), "
        f"{a.get('n_rows')} × {a.get('n_cols')} px of {a.get('pixel_size_m'):g} m, {where} "
        f"({heights[0]:.0f}–{heights[1]:.0f} m)"
    )
    return Inspection(title, {"sar": section})


def _stac(product: Product) -> dict[str, object]:
    """A frame's Item: one instant, its middle line's."""
    t = dt.datetime.fromisoformat(str(product.attrs["time_utc"])[:26]).replace(tzinfo=dt.UTC)
    return {
        "datetime": t,
        "start_datetime": t,
        "end_datetime": t,
        "constellation": "ers",
        "instruments": ["sar"],
        "processing:level": str(product.level),
        "title": str(product.attrs.get("name", "")),
        "description": "an ERS-1 SAR frame, geocoded",
    }


_BANDS = (
    BandSpec("intensity", "SAR backscattered intensity, linear (the image's calibration)"),
    flag_band("layover", "pixel in SAR layover", ("not_layover", "layover")),
    flag_band("shadow", "pixel in SAR shadow", ("not_shadow", "shadow")),
)
#: γ⁰ by radiometric terrain flattening (``[sar] flatten``, :func:`levels.sar.terrain_flattening`)
_GAMMA0 = BandSpec(
    "gamma0", "SAR backscatter gamma0 by radiometric terrain flattening, linear", optional=True
)
_CHECKPOINTS = (
    Figure("checkpoints rms px", "19.3f", headline(FrameHeadline.of, "checkpoints_rms_px")),
    Figure("E rms m", "8.1f", headline(FrameHeadline.of, "checkpoints_rms_east_m")),
    Figure("N rms m", "8.1f", headline(FrameHeadline.of, "checkpoints_rms_north_m")),
)


def _mask_notes(figures: Mapping[str, Any]) -> tuple[str, ...]:
    """What the console says of a GTC beside its figures: its masks' pixels against the
    truth's, γ⁰ across slopes beside σ⁰ on the ellipsoid."""
    masks = [
        f"{m} {figures[f'masks/{m}/pixels']} px (truth {figures[f'masks/{m}/truth_pixels']})"
        for m in ("layover", "shadow")
        if f"masks/{m}/pixels" in figures
    ]
    by, plain = figures.get("gamma0/by_correction"), figures.get("gamma0/unflattened_by_correction")
    gamma = (
        [
            f"γ⁰ / truth {min(by):.3f}–{max(by):.3f} across slopes (σ⁰ on the ellipsoid "
            f"{min(plain):.2f}–{max(plain):.2f})"
        ]
        if isinstance(by, list) and by and isinstance(plain, list) and plain
        else []
    )
    return ("; ".join(masks + gamma),) if masks or gamma else ()


_COMMON: dict[str, Any] = {
    "unit": Unit.FRAME,
    "on_map": True,
    "geometry_trees": ("sar",),
    "export": Export.MAP,
    "inspect": _inspect,
    "browse": Browse("intensity", "gray", "backscattered intensity (dB)"),
    "stac": _stac,
}

GEC = ProductKind(
    name="GEC",
    doc="a SAR frame geocoded on the ellipsoid at a reference height",
    bands=_BANDS,
    figures=(
        *_CHECKPOINTS,
        Figure("relief ratio error", "19.4f", headline(FrameHeadline.of, "relief_ratio_error")),
    ),
    **_COMMON,
)
GTC = ProductKind(
    name="GTC",
    doc="a SAR frame geocoded over a DEM, with layover and shadow masks (and γ⁰)",
    bands=(*_BANDS, _GAMMA0),
    needs=frozenset({"dem"}),
    figures=(
        *_CHECKPOINTS,
        Figure("layover IoU", "12.3f", headline(FrameHeadline.of, "layover_iou")),
        Figure("shadow IoU", "11.3f", headline(FrameHeadline.of, "shadow_iou")),
        Figure("γ⁰/truth", "9.3f", headline(FrameHeadline.of, "gamma0_to_truth")),
    ),
    notes=_mask_notes,
    **_COMMON,
)


def sar_product(
    geocoded: Geocoded,
    image: SarImage,
    name: str,
    quality: dict[str, Any] | None = None,
    dem_source: str = "",
    provenance: dict[str, Any] | None = None,
    gamma0: NDArray[np.float32] | None = None,
    instrument: str = "ERS-1 AMI SAR",
) -> Product:
    """A geocoded frame as a map product of the house format (level ``GEC`` or ``GTC``):
    bands ``intensity``, ``layover`` and ``shadow`` (1 or 0), and ``gamma0`` when given
    (:func:`terrain_flattening`), float32, NaN outside the frame; the annotation and the
    anchors' error in ``geometry/sar``; ``quality``."""
    g, ann = geocoded, image.annotation
    valid = np.isfinite(g.intensity)
    bands = {
        "intensity": BandImage(g.intensity, valid),
        "layover": BandImage(np.where(valid, g.layover, 255).astype(np.uint8), valid),
        "shadow": BandImage(np.where(valid, g.shadow, 255).astype(np.uint8), valid),
    }
    if gamma0 is not None:
        bands["gamma0"] = BandImage(gamma0.astype(np.float32), np.isfinite(gamma0))
    t_mid = ann.first_line_s + 0.5 * ann.shape[0] * ann.line_interval_s
    sar = {
        "kind": g.kind,
        "epoch_utc": str(ann.epoch.t0_utc),
        "state_t_s": np.asarray(ann.state_t_s),
        "state_r_m": np.asarray(ann.state_r_m),
        "state_v_m_per_s": np.asarray(ann.state_v_m_per_s),
        "first_line_s": ann.first_line_s,
        "line_interval_s": ann.line_interval_s,
        "near_range_m": ann.near_range_m,
        "range_spacing_m": ann.range_spacing_m,
        "wavelength_m": ann.wavelength_m,
        "doppler_hz": np.asarray(ann.doppler_hz, dtype=np.float64),
        "image_shape": np.asarray(ann.shape),
        "looks": ann.looks,
        "right_looking": int(ann.right_looking),
        "anchor_step_px": ANCHOR_STEP_PX,
        "height_range_m": np.array([np.nanmin(g.height_m), np.nanmax(g.height_m)]),
        "dem_source": dem_source,
    }
    return Product(
        attrs={
            "level": g.kind,
            "name": name,
            "instrument": instrument,
            "time_utc": str(ann.epoch.utc(np.array([t_mid]))[0]),
            "n_rows": g.grid.n_rows,
            "n_cols": g.grid.n_cols,
            "pixel_size_m": float(g.grid.geotransform[1]),
        },
        bands=bands,
        geometry={"sar": sar},
        quality={
            "anchor_error_px": dict(g.anchor_error),
            "valid_fraction": float(valid.mean()),
            "layover_fraction": float(g.layover[valid].mean()) if valid.any() else 0.0,
            "shadow_fraction": float(g.shadow[valid].mean()) if valid.any() else 0.0,
            **(quality or {}),
        },
        provenance={"software": f"levels {__version__}", **(provenance or {})},
        map_grid=g.grid,
    )
