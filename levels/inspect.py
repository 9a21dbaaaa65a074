"""What a level product holds, at a glance (``station inspect``)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pyproj

from levels.products import Product
from levels.quality import scalar_figures

__all__ = ["product_summary", "summary_text"]

#: Quality figures shown in the text summary (the rest are in the JSON).
_HEADLINE_SUFFIXES = (
    "line_of_sight/rms_m",
    "line_of_sight/max_m",
    "ground/rms_m",
    "polynomials_vs_model/max_px",
    "raw_counts",
    "level_1a_counts",
    "checkpoints/rms_m",
    "checkpoints/rms_px",
    "/iou",
)


def product_summary(product: Product, path: str | Path) -> dict[str, Any]:
    """A JSON-able summary: attributes, bands (shape, valid fraction, statistics), scene
    centre and corners, map grid, headline quality and provenance."""
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
    out: dict[str, Any] = {
        "file": p.name,
        "size_mb": round(p.stat().st_size / 1e6, 3),
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
    g3 = product.geometry.get("level_3")
    if g3:
        dem = g3.get("dem", {})
        out["dem"] = {
            "source": Path(str(dem.get("source", ""))).name,
            "vertical": dem.get("vertical"),
            "spacing_m": float(dem.get("spacing_m", np.nan)),
            "anchor_heights_m": np.asarray(g3.get("heights_m", [])).tolist(),
            "anchor_error_max_px": max(
                (float(e.get("max_px", np.nan)) for e in g3.get("anchor_error_px", {}).values()),
                default=None,
            ),
        }
    pair = product.geometry.get("stereo")
    if pair:  # a stereo pair's DEM (levels.stereo)
        out["stereo"] = {
            "views": [str(pair["view_a"]), str(pair["view_b"])],
            "base_to_height": round(float(pair["base_to_height"]), 4),
            "epipolar_error_px": round(float(pair["epipolar_error_px"]), 4),
            "cell_m": float(product.geometry.get("dem", {}).get("cell_m", np.nan)),
        }
    rpcs = product.geometry.get("rpc")
    if rpcs:
        out["rpc"] = {
            band: {k: float(v) for k, v in tree.get("fit_error_px", {}).items()}
            for band, tree in rpcs.items()
        }
    g1b = product.geometry.get("level_1b")
    if g1b:
        out["plane"] = {
            "pixel_size_m": float(g1b["pixel_size_m"]),
            "origin_ecef_m": np.asarray(g1b["plane_ecef_m"])[0].tolist(),
        }
    sar = product.geometry.get("sar")
    if sar:
        shape = np.asarray(sar["image_shape"]).tolist()
        out["sar"] = {
            "kind": str(sar["kind"]),
            "image_shape": shape,
            "range_spacing_m": float(sar["range_spacing_m"]),
            "line_interval_s": float(sar["line_interval_s"]),
            "height_range_m": np.asarray(sar["height_range_m"]).tolist(),
            "dem_source": str(sar.get("dem_source", "")),
        }
    out["quality"] = scalar_figures(product.quality)
    out["provenance"] = dict(product.provenance)
    return out


def summary_text(s: dict[str, Any]) -> str:
    a = s["attrs"]
    if "stereo" in s:
        st = s["stereo"]
        lines = [
            f"{s['file']} ({s['size_mb']:.1f} MB): level {a.get('level')} of the pair "
            f"{' + '.join(st['views'])}, B/H {st['base_to_height']:.2f}, epipolar error "
            f"{st['epipolar_error_px']:.3f} px, {a.get('n_rows')} × {a.get('n_cols')} cells "
            f"of {st['cell_m']:g} m, heights above the {a.get('vertical', 'ellipsoid')}"
        ]
    elif "sar" in s:
        r = s["sar"]
        lines = [
            f"{s['file']} ({s['size_mb']:.1f} MB): level {a.get('level')} of "
            f"{a.get('instrument')} frame {a.get('name')} ({r['image_shape'][0]} lines × "
            f"{r['image_shape'][1]} samples of {r['range_spacing_m']:.1f} m), "
            f"{a.get('n_rows')} × {a.get('n_cols')} px of {a.get('pixel_size_m'):g} m, "
            + (f"over the DEM {r['dem_source']}" if r["kind"] == "GTC" else "on the ellipsoid")
            + f" ({r['height_range_m'][0]:.0f}–{r['height_range_m'][1]:.0f} m)"
        ]
    else:
        lines = [
            f"{s['file']} ({s['size_mb']:.1f} MB): level {a.get('level')} of "
            f"{a.get('name')} scene {a.get('scene_index')}, HRV{a.get('hrv')} {a.get('mode')}, "
            f"mirror step {a.get('mirror_step')}, {a.get('n_rows')} × {a.get('n_cols')} px"
            + (f" of {a['pixel_size_m']:g} m" if a.get("pixel_size_m") else "")
        ]
    for name, b in s["bands"].items():
        what = "values" if b["dtype"].startswith("float") else "counts"
        lines.append(
            f"  band {name}: {b['shape'][0]} × {b['shape'][1]} {b['dtype']}, valid "
            f"{b['valid_fraction']:.3f}, {what} {b['min']:.6g}–{b['max']:.6g} (mean "
            f"{b['mean']})"
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
    if "dem" in s:
        d = s["dem"]
        lines.append(
            f"  DEM {d['source']} ({d['vertical']}, {d['spacing_m']:.0f} m), anchor grids at "
            + ", ".join(f"{h:.0f}" for h in d["anchor_heights_m"])
            + f" m, their error ≤ {d['anchor_error_max_px']:.4f} px"
        )
    for band, e in s.get("rpc", {}).items():
        lines.append(
            f"  RPC {band}: against the rigorous model RMS {e['rms_px']:.4f} px, max "
            f"{e['max_px']:.4f} px over {e['height_min_m']:.0f}–{e['height_max_m']:.0f} m"
        )
    q = {k: v for k, v in s["quality"].items() if k.endswith(_HEADLINE_SUFFIXES)}
    for k, v in q.items():
        lines.append(f"  quality {k} = {v:.4g}" if isinstance(v, float) else f"  quality {k} = {v}")
    prov = s["provenance"]
    lines.append(
        f"  made by {prov.get('software')} from {prov.get('inputs')} (scenario "
        f"{prov.get('scenario')}, seed {prov.get('seed')})"
    )
    return "\n".join(lines)
