"""One emulated pass made into levels by two routes, and how far apart they land.

The **L0 route** is the station's own: the pass emulated, downlinked, recorded as an L0
archive and processed (:func:`station.reprocess.process_scenario`). The **DIMAP route** is
a SPOT World Heritage user's: the L0 route's level 1A written as the zip SWH delivers
(:func:`station.benchmark_pack.zip_pack`), then processed from that zip
(:mod:`levels.readers.scene1a`) with the same options, control points and DEM. Both are
measured against the same truth. The pass is processed as one scene (``scene_lines`` =
its lines), so that level 2's adjustment sees the same control points in both routes.

:func:`compare_routes` says, level by level: the share of identical counts and the largest
difference, the largest difference between the two products' geometry (their inverse
grids and anchor grids: where each output pixel samples the raw image, in raw pixels),
and each route's checkpoint errors against the truth. ``tools/dimap_route.py`` prints it;
``tests/test_scene1a.py`` holds it to its tolerances.
"""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path
from typing import Any

import numpy as np

from levels.choices import Level
from levels.products import Product, read_product
from levels.spot import MODES
from station.scenario import Scenario

__all__ = ["compare_routes", "geometry_difference_px", "one_scene"]


def one_scene(scn: Scenario, levels: tuple[str, ...]) -> Scenario:
    """``scn`` processed as a single scene of all its lines, making ``levels``."""
    ins = scn.instruments[0]
    lines = ins.n_lines or ins.n_detectors or MODES[ins.mode].detectors
    opts = dataclasses.replace(
        scn.processing, scene_lines=lines, overlap_lines=0, levels=tuple(levels)
    )
    return dataclasses.replace(scn, processing=opts)


def _grids(tree: Any, prefix: str = "") -> dict[str, np.ndarray]:
    """Every array of a geometry tree that says where output pixels sample the raw image
    (``inverse_grid`` and ``anchor`` grids' ``line`` and ``column``), by path."""
    out: dict[str, np.ndarray] = {}
    for key, value in tree.items():
        path = f"{prefix}/{key}"
        if isinstance(value, dict):
            out.update(_grids(value, path))
        elif key in ("line", "column") and ("inverse_grid" in path or "anchor" in path):
            out[path] = np.asarray(value, dtype=np.float64)
    return out


def geometry_difference_px(a: Product, b: Product) -> float:
    """The largest difference between two products' sampling grids (raw pixels); for
    products in the raw geometry (1A), between their models at a 21 × 21 lattice of pixels
    (ground at the reference height, back through the other's model). NaN if the grids do
    not match in shape (the products are not of one output grid)."""
    if a.map_grid is None:
        from levels.geo.scenes import models_of_tree

        ma = next(iter(models_of_tree(a.geometry)[1].values()))
        mb = next(iter(models_of_tree(b.geometry)[1].values()))
        line, col = np.meshgrid(
            np.linspace(0, ma.n_lines - 1, 21), np.linspace(0, ma.n_columns - 1, 21)
        )
        h = float(a.geometry.get("reference_height_m", 0.0))
        g = ma.image_to_ground(line.ravel(), col.ravel(), h)
        back = mb.ground_to_image(g.lat_rad, g.lon_rad, h)
        return float(
            max(np.abs(back.line - line.ravel()).max(), np.abs(back.column - col.ravel()).max())
        )
    if b.map_grid is None or not np.allclose(
        a.map_grid.geotransform, b.map_grid.geotransform, rtol=0, atol=1e-6
    ):
        return float("nan")
    ga, gb = _grids(a.geometry), _grids(b.geometry)
    worst = 0.0
    for key, x in ga.items():
        y = gb.get(key)
        if y is None or y.shape != x.shape:
            return float("nan")
        both = np.isfinite(x) & np.isfinite(y)
        if both.any():
            worst = max(worst, float(np.abs(x[both] - y[both]).max()))
    return worst


def _counts(a: Product, b: Product) -> tuple[float, int, int]:
    """Over every band: the share of pixels valid in both whose counts are the same, the
    largest difference there, and the pixels valid in one product only (the footprint's
    edge, where the geometries' difference moves a pixel across it)."""
    same = total = worst = edge = 0
    for name, x in a.bands.items():
        y = b.bands[name]
        if x.image.shape != y.image.shape:
            return 0.0, 255, x.image.size
        both = x.valid & y.valid
        d = np.abs(x.image.astype(np.int16) - y.image.astype(np.int16))[both]
        same += int((d == 0).sum())
        total += int(d.size)
        worst = max(worst, int(d.max()) if d.size else 0)
        edge += int(np.count_nonzero(x.valid != y.valid))
    return (same / total if total else 1.0), worst, edge


def _truth_rms_m(product: Product) -> float | None:
    """The product's checkpoint RMS against the truth (first band; m): the line of sight
    met on the product's own surface (1B, 2A, 2), else the ground truly seen (3)."""
    q = product.quality.get("checkpoints", {})
    first: Any = next(iter(q.values()), {}) if isinstance(q, dict) else {}
    for measure in ("line_of_sight", "ground"):
        value = first.get(measure, {}).get("rms_m") if isinstance(first, dict) else None
        if value is not None:
            return float(value)
    return None


def compare_routes(
    scn: Scenario,
    out: str | Path,
    levels: tuple[str, ...] = (Level.L1A, Level.L1B, Level.L2A),
) -> dict[str, object]:
    """Process ``scn``'s pass by the L0 route and by the DIMAP route into ``out``
    (``l0_route/``, ``<name>.zip``, ``dimap_route/``) and compare them (module
    docstring)."""
    from station.benchmark_pack import zip_pack
    from station.reprocess import process_scenario, reprocess_l0

    out = Path(out)
    one = one_scene(scn, levels)
    t0 = time.perf_counter()
    l0_made, l0 = process_scenario(one, out / "l0_route")
    t_l0 = time.perf_counter() - t0
    [scene] = l0_made.scenes
    pack = out / f"{scn.name}.zip"
    source = Path(scn.source) if scn.source else None  # a scenario from a file: its truth
    zip_pack(scene.paths[Level.L1A], pack, scenario=source if source and source.is_file() else None)
    options = one.processing
    dem = out / "l0_route" / f"{scn.name}.dem.tif"
    if not options.dem_path and dem.is_file():
        options = dataclasses.replace(options, dem_path=str(dem))
    t0 = time.perf_counter()
    dimap_made = reprocess_l0(
        pack,
        out / "dimap_route",
        options=options,
        scenario=one,
        name=scn.name,
        gcps=l0.with_name(f"{scn.name}.gcp.csv"),
    )
    t_dimap = time.perf_counter() - t0
    [again] = dimap_made.scenes
    rows = {}
    for level in levels:
        a, b = read_product(scene.paths[level]), read_product(again.paths[level])
        identical, worst, edge = _counts(a, b)
        rows[level] = {
            "counts_identical": identical,
            "counts_max_diff": worst,
            "valid_in_one_only": edge,
            "geometry_max_px": geometry_difference_px(a, b),
            "truth_rms_m_l0": _truth_rms_m(a),
            "truth_rms_m_dimap": _truth_rms_m(b),
        }
    return {
        "scenario": scn.name,
        "zip": str(pack),
        "levels": rows,
        "timings_s": {"l0_route": t_l0, "dimap_route": t_dimap},
    }
