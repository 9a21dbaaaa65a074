"""The processing centre's run over one pass: GEO once, COR once per scene and level.

:func:`process_l0` takes an L0 archive (:func:`levels.readers.l0.read_l0`) and the
scenario's ``[processing]`` section, and writes one product per scene and level
(:mod:`levels.products`). For each scene, the raw counts are read from the archive once,
calibrated once (level 1A), deconvolved once, and resampled into 1B and 2A: INPE's "all
operations executed by COR require the raw image to be read only once" (paper ``004_…``
§2.2).

Every product carries its quality: the approximation errors of its geometry against the
rigorous model (always), the stripe level before and after calibration (1A), and, when the
truth is at hand (:func:`process_scenario`), the checkpoint errors against it
(:mod:`station.sipc.truth`).

XS bands share one output geometry, computed on the first band (as SPOT's products do);
the bands' small registration offsets then show in each band's checkpoint errors.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, TypeVar

import numpy as np
from numpy.typing import NDArray

from levels.cor.radiometry import (
    calibrate,
    deconvolution_taps,
    deconvolve,
    fir_response,
    mtf,
    stripe_level,
    to_counts,
)
from levels.cor.resample import resample_1b, resample_2a, with_nan
from levels.errors import GeometryError
from levels.geo.level1b import Level1BGeometry, level1b_geometry
from levels.geo.level2a import INVERSE_METHODS, Level2AGeometry, level2a_geometry, map_crs
from levels.geo.scenes import PassGeometry, SceneGeometry, cut_scenes, pass_geometry
from levels.geometry.sensor import LookAngleTable
from levels.products import BandImage, Product, write_product
from levels.quality import scalar_figures
from levels.readers.l0 import L0Archive, read_l0
from station import __version__
from station.scenario import ProcessingConfig, Scenario
from station.sipc.truth import Truth, checkpoints_1b, checkpoints_2a

__all__ = ["PassProducts", "SceneProducts", "nominal_pixel_size_m", "process_l0",
           "process_scenario"]

#: SPOT 1–4 mean altitude, to turn the look-angle pitch into a nominal ground pixel.
_NOMINAL_ALTITUDE_M = 822e3


@dataclass(frozen=True)
class SceneProducts:
    """What was made of one scene: product paths and headline quality per level."""

    index: int
    first_line: int
    n_lines: int
    paths: dict[str, Path]
    quality: dict[str, dict[str, Any]]
    timings_s: dict[str, float]


@dataclass(frozen=True)
class SkippedScene:
    """A scene of the pass that could not be made, and why (lost in the downlink, or GEO
    could not place it: no attitude or ephemeris over it)."""

    index: int
    first_line: int
    n_lines: int
    reason: str


@dataclass(frozen=True)
class PassProducts:
    """All scenes of a pass, the rows left after the last whole scene, GEO's time."""

    scenes: list[SceneProducts]
    tail_lines: int
    timings_s: dict[str, float] = field(default_factory=dict)
    skipped: list[SkippedScene] = field(default_factory=list)


def nominal_pixel_size_m(look: LookAngleTable) -> float:
    """The nominal output pixel: the look table's angular pitch at 822 km, to 10 m (10 m
    for P, 20 m for XS, and proportionally more for a reduced detector count)."""
    pitch = float(np.median(np.abs(np.diff(look.psi_y_rad))))
    return max(10.0, 10.0 * round(pitch * _NOMINAL_ALTITUDE_M / 10.0))


def _geometry_common(pg: PassGeometry, scene: SceneGeometry) -> dict[str, Any]:
    att = scene.model.attitude
    t = att.t_s  # type: ignore[attr-defined]
    margin = 2.0
    keep = (t >= scene.model.clock.time_s(0) - margin) & \
        (t <= scene.model.clock.time_s(scene.cut.n_lines - 1) + margin)
    return {
        "epoch_utc": str(pg.epoch.t0_utc),
        "reference_height_m": scene.reference_height_m,
        "scene": {"first_line": scene.cut.first_line, "n_lines": scene.cut.n_lines,
                  "t_centre_s": scene.t_centre_s,
                  "centre_lat_deg": float(np.degrees(scene.centre_lat_rad)),
                  "centre_lon_deg": float(np.degrees(scene.centre_lon_rad)),
                  "corners_lat_deg": np.degrees(scene.corners_lat_rad),
                  "corners_lon_deg": np.degrees(scene.corners_lon_rad)},
        "clock": {"t_first_line_s": float(scene.model.clock.time_s(0)),
                  "line_period_s": scene.model.clock.period_s},
        "ephemeris": {"t_s": pg.ephemeris.t_s, "r_ecef_m": pg.ephemeris.r_ecef_m,
                      "v_ecef_m_per_s": pg.ephemeris.v_ecef_m_per_s,
                      "lagrange_points": pg.ephemeris.n_points},
        "attitude": {"t_s": t[keep], "angles_rad": att.angles_rad_samples[keep],  # type: ignore
                     "integrated_at_centre_rad": scene.attitude_at_centre_rad,
                     "note": "gyro rates integrated from a null first record, zeroed at the "
                             "scene centre (INPE)"},
        "look_angles": {name: {"column": m.look_angles.column,
                               "psi_x_rad": m.look_angles.psi_x_rad,
                               "psi_y_rad": m.look_angles.psi_y_rad}
                        for name, m in scene.models.items()},
    }


_G = TypeVar("_G", Level1BGeometry, Level2AGeometry)


def _per_band(scene: SceneGeometry, make: Callable[[str, _G | None], _G]) -> dict[str, _G]:
    """A geometry per band, every band on the first band's output grid."""
    first, *others = scene.models
    out = {first: make(first, None)}
    for b in others:
        out[b] = make(b, out[first])
    return out


def _geometry_1b(geoms: dict[str, Level1BGeometry]) -> dict[str, Any]:
    g = next(iter(geoms.values()))
    return {"pixel_size_m": g.pixel_size_m, "i_origin": g.i_origin, "j_origin": g.j_origin,
            "plane_ecef_m": g.plane.as_array(),
            "plane_note": "rows: origin, X (south), Y (east), normal (up); ECEF",
            "polynomial_note": "[centre, scale, c0..c3]: p(x) = sum c_k ((x - centre)/scale)^k;"
                               " L = f(I), C = g(J - h(I))",
            "breakpoints_note": "columns L, C, I, J",
            "bands": {b: {"f": g.f.as_array(), "g": g.g.as_array(), "h": g.h.as_array(),
                          "centre_column_breakpoints": g.centre_column_breakpoints,
                          "centre_line_breakpoints": g.centre_line_breakpoints}
                      for b, g in geoms.items()}}


def _geometry_2a(geoms: dict[str, Level2AGeometry]) -> dict[str, Any]:
    g = next(iter(geoms.values()))
    return {"crs_wkt": g.crs_wkt, "geotransform": np.asarray(g.geotransform),
            "pixel_size_m": g.pixel_size_m, "inverse_method": g.method,
            "bands": {b: _geometry_2a_band(g) for b, g in geoms.items()}}


def _geometry_2a_band(g: Level2AGeometry) -> dict[str, Any]:
    polys = {f"poly{o}": {"line": np.stack([p.as_array() for p in pl]), "column": pc.as_array()}
             for o, (pl, pc) in g.inverse_polynomials.items()}
    return {"direct_grid": {"line": g.grid_line, "column": g.grid_column, "i": g.grid_i,
                            "j": g.grid_j},
            "segment_first_column": g.segment_first_column,
            "inverse_grid": {"rows": g.inverse_rows, "cols": g.inverse_cols,
                             "line": g.inverse_line, "column": g.inverse_column},
            "inverse_polynomials": polys}


def process_l0(archive: L0Archive, cfg: ProcessingConfig, out_dir: str | Path, *,
               name: str = "pass", truth: Truth | None = None,
               provenance: dict[str, Any] | None = None,
               on_scene: Callable[[SceneProducts, int], None] | None = None) -> PassProducts:
    """GEO and COR over a pass (module docstring); products go to ``out_dir``.

    ``on_scene(done, n_scenes)`` is called after each scene (progress reporting).
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    clock = time.perf_counter
    t0 = clock()
    band_names = list(archive.bands)
    pg = pass_geometry(archive.epoch, archive.line_t_s, archive.line_period_s,
                       archive.ephemeris, archive.aux_t_s, archive.gyro_rates_rad_per_s,
                       {b: archive.bands[b].look for b in band_names})
    n_det = archive.bands[band_names[0]].counts.shape[1]
    scene_lines = cfg.scene_lines or n_det
    cuts = cut_scenes(archive.n_lines, scene_lines, cfg.overlap_lines)
    pixel_valid = {b: archive.bands[b].pixel_valid() for b in band_names}
    rows_seen = np.logical_or.reduce([v.any(axis=1) for v in pixel_valid.values()])
    scenes, skipped = [], []
    for c in cuts:
        if not rows_seen[c.first_line:c.first_line + c.n_lines].any():
            skipped.append(SkippedScene(c.index, c.first_line, c.n_lines,
                                        "no valid line: lost in the downlink"))
            continue
        try:
            scenes.append(pg.scene(c, cfg.reference_height_m))
        except GeometryError as exc:
            skipped.append(SkippedScene(c.index, c.first_line, c.n_lines,
                                        f"GEO could not place it: {exc}"))
    res = cfg.pixel_size_m or nominal_pixel_size_m(pg.look_angles[band_names[0]])
    t_geo = clock() - t0
    taps = deconvolution_taps(cfg.psf_fwhm_px, cfg.noise_to_signal) if cfg.deconvolution \
        else np.ones(1)
    prov = {"software": f"spot-station {__version__}", "inputs": Path(archive.path).name,
            "processing": json.dumps(asdict(cfg)), **(provenance or {})}
    results = []
    for scene in scenes:
        results.append(_process_scene(archive, pg, scene, cfg, res, taps, pixel_valid, out,
                                      name, truth, prov))
        if on_scene is not None:
            on_scene(results[-1], len(scenes))
    tail = pg.tail_lines(scene_lines, cfg.overlap_lines)
    return PassProducts(results, tail, {"geo": t_geo, "total": clock() - t0}, skipped)


def _process_scene(archive: L0Archive, pg: PassGeometry, scene: SceneGeometry,
                   cfg: ProcessingConfig, res: float, taps: NDArray[np.float64],
                   pixel_valid: dict[str, NDArray[np.bool_]], out: Path, name: str,
                   truth: Truth | None, prov: dict[str, Any]) -> SceneProducts:
    clock = time.perf_counter
    timings: dict[str, float] = {}
    t = clock()
    rows = slice(scene.cut.first_line, scene.cut.first_line + scene.cut.n_lines)
    g1b = g2a = None
    if "1B" in cfg.levels:
        g1b = _per_band(scene, lambda b, like: level1b_geometry(scene, res, band=b, like=like))
    if "2A" in cfg.levels:
        crs = map_crs(cfg.crs, scene.centre_lat_rad, scene.centre_lon_rad,
                      _ascending_node_lon(pg) if cfg.crs == "som" else None)
        g2a = _per_band(scene, lambda b, like: level2a_geometry(
            scene, res, crs, cfg.inverse_2a, grid_rows=cfg.grid_rows, band=b, like=like))
    timings["geometry"] = clock() - t
    images: dict[str, dict[str, BandImage]] = {lv: {} for lv in cfg.levels}
    stripes: dict[str, dict[str, float]] = {}
    for bname, band in archive.bands.items():
        t = clock()
        counts, valid = band.counts[rows], pixel_valid[bname][rows]
        cal = calibrate(counts, valid, band.gain, band.offset_counts)
        stripes[bname] = {"raw_counts": stripe_level(counts.astype(np.float32), valid),
                          "level_1a_counts": stripe_level(cal, valid)}
        if "1A" in cfg.levels:
            images["1A"][bname] = BandImage(to_counts(cal), valid)
        timings["1A"] = timings.get("1A", 0.0) + clock() - t
        if g1b is None and g2a is None:
            continue
        t = clock()
        dec, dvalid = deconvolve(cal, valid, taps) if taps.size > 1 else (cal, valid)
        timings["deconvolution"] = timings.get("deconvolution", 0.0) + clock() - t
        if g1b is not None:
            t = clock()
            images["1B"][bname] = BandImage(*resample_1b(dec, dvalid, g1b[bname],
                                                         cfg.interpolation_1b))
            timings["1B"] = timings.get("1B", 0.0) + clock() - t
        if g2a is not None:
            t = clock()
            images["2A"][bname] = BandImage(*resample_2a(with_nan(dec, dvalid), None,
                                                         g2a[bname], cfg.resampling_2a))
            timings["2A"] = timings.get("2A", 0.0) + clock() - t
    t = clock()
    quality = _quality(scene, cfg, g1b, g2a, stripes, taps, truth)
    timings["quality"] = clock() - t
    t = clock()
    common = _geometry_common(pg, scene)
    paths = {}
    for level in cfg.levels:
        geometry = dict(common)
        if level == "1B":
            geometry["level_1b"] = _geometry_1b(g1b)  # type: ignore[arg-type]
        if level == "2A":
            geometry["level_2a"] = _geometry_2a(g2a)  # type: ignore[arg-type]
        first = next(iter(images[level].values())).image
        attrs = {"level": level, "scene_index": scene.cut.index, "name": name,
                 "hrv": archive.hrv, "mode": archive.mode, "mirror_step": archive.mirror_step,
                 "n_rows": first.shape[0], "n_cols": first.shape[1],
                 "pixel_size_m": res if level != "1A" else 0.0}
        product = Product(attrs, images[level], geometry, quality[level],
                          {**prov, "level": level})
        paths[level] = write_product(out / f"{name}_s{scene.cut.index:03d}_{level}.h5", product)
    timings["write"] = clock() - t
    return SceneProducts(scene.cut.index, scene.cut.first_line, scene.cut.n_lines, paths,
                         {lv: scalar_figures(q) for lv, q in quality.items()}, timings)


def _quality(scene: SceneGeometry, cfg: ProcessingConfig,
             g1b: dict[str, Level1BGeometry] | None, g2a: dict[str, Level2AGeometry] | None,
             stripes: dict[str, dict[str, float]], taps: NDArray[np.float64],
             truth: Truth | None) -> dict[str, dict[str, Any]]:
    q: dict[str, dict[str, Any]] = {"1A": {"stripe_level": stripes}}
    nyquist = np.array([0.5])
    before = float(mtf(nyquist, cfg.psf_fwhm_px)[0])
    radiometry = {"deconvolution_taps": taps, "mtf_at_nyquist_before": before,
                  "mtf_at_nyquist_after": before * abs(float(fir_response(taps, nyquist)[0]))}
    per_side = cfg.checkpoints_per_side
    bands = list(scene.models)
    if g1b is not None:
        # the first band's figures: the others' fits are the same polynomials a few tenths
        # of a pixel apart, and their checkpoints below measure each band
        q["1B"] = {"radiometry": radiometry,
                   "polynomials_vs_model": g1b[bands[0]].approximation_error(scene.model)}
        if truth is not None:
            q["1B"]["checkpoints"] = {b: checkpoints_1b(truth, scene, g1b[b], k, per_side)
                                      for k, b in enumerate(bands)}
    if g2a is not None:
        g = g2a[bands[0]]
        approx = {m: g.approximation_error(scene.model, scene.reference_height_m, m)
                  for m in INVERSE_METHODS}
        q["2A"] = {"radiometry": radiometry, "inverse_vs_model": approx,
                   "inverse_method": g.method}
        if truth is not None:
            q["2A"]["checkpoints"] = {b: checkpoints_2a(truth, scene, g2a[b], k, per_side)
                                      for k, b in enumerate(bands)}
    return {lv: q[lv] for lv in cfg.levels}


def _ascending_node_lon(pg: PassGeometry) -> float:
    """Longitude of the orbit's ascending node, from the ephemeris (for the SOM)."""
    r = pg.ephemeris.r_ecef_m
    v = pg.ephemeris.v_ecef_m_per_s
    k = len(r) // 2
    h = np.cross(r[k], v[k])
    node = np.cross([0.0, 0.0, 1.0], h)
    return float(np.arctan2(node[1], node[0]))


def scenario_provenance(scn: Scenario) -> dict[str, Any]:
    """What a product records of the scenario it was made from."""
    return {"scenario": scn.name, "scenario_file": Path(scn.source).name,
            "scenario_sha256": scn.source_sha256, "seed": scn.seed}


def process_scenario(scn: Scenario, out_dir: str | Path, l0_path: str | Path | None = None
                     ) -> tuple[PassProducts, Path]:
    """Emulate, downlink, record and process a scenario; products measured against truth."""
    from station.spacecraft.emulator import emulate
    from station.srrs.session import downlink, record

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    acq = emulate(scn)
    result = downlink(acq)
    l0 = record(acq, result, l0_path or out / f"{scn.name}.l0.h5")
    archive = read_l0(l0)
    products = process_l0(archive, scn.processing, out, name=scn.name,
                          truth=Truth.of(acq, archive), provenance=scenario_provenance(scn))
    return products, l0
