"""What a level product holds, at a glance (``station inspect``)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pyproj

from levels.kinds import Inspection
from levels.products import Product
from levels.quality import scalar_figures
from levels.registry import kind_of

__all__ = ["product_summary", "summary_text"]


def product_summary(product: Product, path: str | Path) -> dict[str, Any]:
    """A JSON-able summary: attributes, bands (shape, valid fraction, statistics), scene
    centre and corners, map grid, what its kind says of it (:class:`levels.kinds.Inspection`:
    a title, its own sections, lines of text), headline quality and provenance."""
    p = Path(path)
    bands = {}
    for name, b in product.bands.items():
        v = b.image[b.valid]
        number = float if v.dtype.kind == "f" else int  # a DEM's heights, or counts
        bands[name] = {
            "shape": list(b.image.shape),
            "dtype": str(b.image.dtype),
            "valid_fraction": round(float(b.valid.mean()), 6),
            "min": number(v.min()) if v.size else None,
            "max": number(v.max()) if v.size else None,
            "mean": round(float(v.mean()), 3) if v.size else None,
        }
    known = kind_of(product)
    said = (
        known.inspect(product)
        if known is not None
        else Inspection(f"level {product.level} of {product.attrs.get('name')}")
    )
    out: dict[str, Any] = {
        "file": p.name,
        "size_mb": round(p.stat().st_size / 1e6, 3),
        "title": said.title,
        "attrs": {
            k: v.item() if isinstance(v, np.generic) else v for k, v in product.attrs.items()
        },
        "bands": bands,
    }
    scene = product.geometry.get("scene")
    if scene:
        out["scene"] = {
            "centre_lat_lon_deg": [float(scene["centre_lat_deg"]), float(scene["centre_lon_deg"])],
            "corners_lat_lon_deg": np.column_stack(
                [scene["corners_lat_deg"], scene["corners_lon_deg"]]
            ).tolist(),
            "first_line": int(scene["first_line"]),
            "n_lines": int(scene["n_lines"]),
        }
    grid = product.map_grid
    if grid is not None:
        crs = pyproj.CRS.from_wkt(grid.crs_wkt)
        out["map"] = {
            "crs": crs.name,
            "epsg": crs.to_epsg(),
            "geotransform": list(grid.geotransform),
            "inverse_method": product.geometry.get("level_2a", {}).get("inverse_method"),
        }
    out.update(said.sections)
    out["kind_lines"] = list(said.lines)
    out["quality"] = scalar_figures(product.quality)
    figures = (known.figures, known.notes(out["quality"])) if known else ((), ())
    out["headline"] = {f.label: f.value(out["quality"]) for f in figures[0]}
    out["notes"] = list(figures[1])
    out["provenance"] = dict(product.provenance)
    return out


def summary_text(s: dict[str, Any]) -> str:
    """The summary (:func:`product_summary`) as lines of text."""
    lines = [f"{s['file']} ({s['size_mb']:.1f} MB): {s['title']}"]
    for name, b in s["bands"].items():
        what = "values" if b["dtype"].startswith("float") else "counts"
        span = f"{b['min']:.6g}–{b['max']:.6g}" if b["min"] is not None else "none valid"
        lines.append(
            f"  band {name}: {b['shape'][0]} × {b['shape'][1]} {b['dtype']}, valid "
            f"{b['valid_fraction']:.3f}, {what} {span} (mean {b['mean']})"
        )
    if "scene" in s:
        c = s["scene"]["centre_lat_lon_deg"]
        lines.append(
            f"  scene centre {c[0]:.5f}°, {c[1]:.5f}°; raw lines "
            f"{s['scene']['first_line']}–"
            f"{s['scene']['first_line'] + s['scene']['n_lines'] - 1}"
        )
    if "map" in s:
        m = s["map"]
        gt = m["geotransform"]
        lines.append(
            f"  map: {m['crs']}, origin ({gt[0]:.1f}, {gt[3]:.1f}) m, pixel "
            f"{gt[1]:g} m" + (f"; inverse {m['inverse_method']}" if m["inverse_method"] else "")
        )
    lines += s["kind_lines"]
    shown = [f"{k} {v:.4g}" for k, v in s["headline"].items() if v is not None]
    if shown:
        lines.append("  headline: " + ", ".join(shown))
    lines += [f"  {n}" for n in s["notes"]]
    prov = s["provenance"]
    known = [f"{k} {prov[k]}" for k in ("scenario", "seed") if prov.get(k) is not None]
    lines.append(
        f"  made by {prov.get('software')} from {prov.get('inputs')}"
        + (f" ({', '.join(known)})" if known else "")
    )
    return "\n".join(lines)
