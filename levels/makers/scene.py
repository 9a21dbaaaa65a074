"""What the scene levels (1A, 1B, 2A, 2, 3) declare alike: their headline figures, their
``inspect`` title and sections, their STAC properties; each level's module composes its
:class:`~levels.kinds.ProductKind` from these (:func:`scene_kind`)."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from levels.kinds import Export, Figure, Inspection, ProductKind, Unit, headline
from levels.makers.base import LevelMaker, no_map_grid
from levels.quality import Headline
from levels.registry import kind, kind_names, register_kind, unregister_kind

if TYPE_CHECKING:
    from levels.makers.base import LevelMaker
    from levels.products import Product

__all__ = [
    "SCENE_FIGURES",
    "Section",
    "adjustment_section",
    "dem_section",
    "level_maker",
    "plane_section",
    "register_level",
    "rpc_section",
    "scene_kind",
    "unregister_level",
]

#: A section of ``inspect``: its JSON sections and its lines of text.
Section = Callable[["Product"], tuple[dict[str, object], tuple[str, ...]]]


#: The scene levels' columns: checkpoint errors along the line of sight (RMS, max) and on
#: the ground (RMS), and the product's geometry against the rigorous model.
SCENE_FIGURES = (
    Figure(
        "LOS rms m",
        "10.1f",
        headline(Headline.of, "los_rms_m"),
        "LOS: the checkpoints' error along their line of sight, the model's own",
    ),
    Figure("LOS max m", "10.1f", headline(Headline.of, "los_max_m")),
    Figure(
        "ground rms m",
        "13.1f",
        headline(Headline.of, "ground_rms_m"),
        "ground: against where each pixel's ground truly is; on a map of one reference "
        "height (1B, 2A, 2) it carries the relief displacement, which only level 3 takes off",
    ),
    Figure(
        "approx max px",
        "14.4f",
        headline(Headline.of, "approx_max_px"),
        "approx: the product's geometry against the rigorous model",
    ),
)


def _title(product: Product) -> str:
    a = product.attrs
    return (
        f"level {a.get('level')} of {a.get('name')} scene {a.get('scene_index')}, "
        f"HRV{a.get('hrv')} {a.get('mode')}, mirror step {a.get('mirror_step')}, "
        f"{a.get('n_rows')} × {a.get('n_cols')} px"
        + (f" of {a['pixel_size_m']:g} m" if a.get("pixel_size_m") else "")
    )


def rpc_section(product: Product) -> tuple[dict[str, object], tuple[str, ...]]:
    """The RPCs an image-geometry product carries, and their fit to the rigorous model."""
    rpcs = product.geometry.get("rpc") or {}
    section = {
        band: {k: float(v) for k, v in tree.get("fit_error_px", {}).items()}
        for band, tree in rpcs.items()
    }
    lines = tuple(
        f"  RPC {band}: against the rigorous model RMS {e['rms_px']:.4f} px, max "
        f"{e['max_px']:.4f} px over {e['height_min_m']:.0f}–{e['height_max_m']:.0f} m"
        for band, e in section.items()
    )
    return ({"rpc": section} if section else {}), lines


def plane_section(product: Product) -> tuple[dict[str, object], tuple[str, ...]]:
    """A 1B's tangent plane (INPE's)."""
    g1b = product.geometry["level_1b"]
    plane = {
        "pixel_size_m": float(g1b["pixel_size_m"]),
        "origin_ecef_m": np.asarray(g1b["plane_ecef_m"])[0].tolist(),
    }
    return {"plane": plane}, ()


def dem_section(product: Product) -> tuple[dict[str, object], tuple[str, ...]]:
    """The DEM a level 3 was made over, and its anchor grids."""
    g3 = product.geometry["level_3"]
    dem = g3.get("dem", {})
    d = {
        "source": Path(str(dem.get("source", ""))).name,
        "vertical": dem.get("vertical"),
        "spacing_m": float(dem.get("spacing_m", np.nan)),
        "anchor_heights_m": np.asarray(g3.get("heights_m", [])).tolist(),
        "anchor_error_max_px": max(
            (float(e.get("max_px", np.nan)) for e in g3.get("anchor_error_px", {}).values()),
            default=None,
        ),
    }
    line = (
        f"  DEM {d['source']} ({d['vertical']}, {d['spacing_m']:.0f} m), anchor grids at "
        + ", ".join(f"{h:.0f}" for h in d["anchor_heights_m"])
        + f" m, their error ≤ {d['anchor_error_max_px']:.4f} px"
    )
    return {"dem": d}, (line,)


def adjustment_section(product: Product) -> tuple[dict[str, object], tuple[str, ...]]:
    """A level 2's adjustment: the accuracy it predicts, the control points it used and
    those it rejected as blunders (by id), their residuals."""
    import json

    adj = product.geometry["adjustment"]
    points = adj.get("points", {})
    ids = json.loads(points.get("id", "[]"))
    status = json.loads(points.get("status", "[]"))
    after = np.asarray(points.get("residual_after_px", np.zeros((0, 2))), dtype=np.float64)
    residual = np.hypot(after[:, 0], after[:, 1]) if after.size else np.zeros(0)
    used = [i for i, s in zip(ids, status, strict=True) if s == "used"]
    rejected = {
        i: float(r) for i, s, r in zip(ids, status, residual, strict=True) if s == "rejected"
    }
    sigma = {k: float(v) for k, v in adj.get("predicted_sigma_m", {}).items()}
    ok = residual[[s == "used" for s in status]] if residual.size else residual
    section = {
        "mode": str(adj.get("mode", "")),
        "predicted_sigma_m": sigma,
        "points_used": len(used),
        "points_rejected": sorted(rejected),
        "residual_rms_px": float(np.sqrt(np.mean(ok**2))) if ok.size else None,
    }
    lines = [
        f"  adjustment ({section['mode']}): {len(used)} control point(s) used"
        + (
            f", residual RMS {section['residual_rms_px']:.2f} px"
            if section["residual_rms_px"] is not None
            else ""
        )
        + (
            f"; predicted σ {sigma['horizontal']:.1f} m horizontal "
            f"({sigma.get('prior_horizontal', float('nan')):.1f} m before)"
            if "horizontal" in sigma
            else ""
        )
    ]
    lines += [f"  rejected {i}: residual {r:.1f} px" for i, r in sorted(rejected.items())]
    return {"adjustment": section}, tuple(lines)


def _inspection(*sections: Section) -> Callable[[Product], Inspection]:
    def inspect(product: Product) -> Inspection:
        found: dict[str, object] = {}
        lines: list[str] = []
        for s in sections:
            d, more = s(product)
            found.update(d)
            lines += more
        return Inspection(_title(product), found, tuple(lines))

    return inspect


def _control_notes(figures: Mapping[str, Any]) -> tuple[str, ...]:
    used = figures.get("control_points/used")
    if used is None:
        return ()
    sigma = figures.get("predicted_sigma_m/horizontal")
    return (
        f"{used} control point(s) used, {figures.get('control_points/rejected', 0)} rejected"
        + (f"; predicted σ {sigma:.1f} m horizontal" if sigma is not None else ""),
    )


def _stripe_notes(figures: Mapping[str, Any]) -> tuple[str, ...]:
    h = Headline.of(figures)
    if h.stripes_counts is None:
        return ()
    raw, cal = h.stripes_counts
    return (f"stripes raw → 1A {h.band} {raw:.2f} → {cal:.2f} counts",)


def _scene_stac(product: Product) -> dict[str, object]:
    return {"processing:level": f"L{product.level}"}


def scene_kind(
    maker: LevelMaker,
    export: Export,
    geometry_trees: tuple[str, ...],
    *sections: Section,
    stripes: bool = False,
    counts_fill: int | None = 0,
) -> ProductKind:
    """The kind of a scene level made by ``maker``: its export, the geometry trees its
    products carry, its ``inspect`` sections; its figures the scene levels'; its notes
    the stripes (``stripes``: 1A) or its control points (when its quality has them); 0
    its counts' fill where not valid (resampled levels: viewers mask their borders), or
    None (the raw counts of a 1A, every value data)."""
    return ProductKind(
        name=str(maker.name),
        doc=maker.doc,
        unit=Unit.SCENE,
        on_map=maker.map_grid is not no_map_grid,
        geometry_trees=geometry_trees,
        export=export,
        inspect=_inspection(*sections),
        requires=maker.requires,
        figures=SCENE_FIGURES,
        notes=_stripe_notes if stripes else _control_notes,
        stac=_scene_stac,
        maker=maker,
        counts_fill=counts_fill,
    )


def level_maker(name: str) -> LevelMaker:
    """The maker of scene level ``name``; :class:`KeyError` naming the known levels if
    none."""
    if name not in kind_names(Unit.SCENE):
        raise KeyError(f"no level {name!r}; known: {', '.join(kind_names(Unit.SCENE))}")
    maker: LevelMaker = kind(name).maker
    return maker


def _plain_inspection(product: Product) -> Inspection:
    a = product.attrs
    return Inspection(f"level {a.get('level')} of {a.get('name')} scene {a.get('scene_index')}")


def register_level(maker: LevelMaker) -> None:
    """Add a scene level made by ``maker`` (its ``name`` must be new): a kind of unit
    :attr:`Unit.SCENE`, not exported, its other declarations the defaults."""
    register_kind(
        ProductKind(
            name=maker.name,
            doc=maker.doc,
            unit=Unit.SCENE,
            on_map=maker.map_grid is not no_map_grid,
            geometry_trees=("scene",),
            export=Export.NONE,
            inspect=_plain_inspection,
            requires=maker.requires,
            maker=maker,
        )
    )


def unregister_level(name: str) -> None:
    """Remove a level added by :func:`register_level` (the built-in ones stay)."""
    unregister_kind(name)
