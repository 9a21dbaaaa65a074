"""The truth behind a processed pass: where each raw pixel truly looks, and what it sees.

Checkpoints are a lattice of raw pixels of a scene. For each, two truths:

* the **line of sight**: the truth orbit, attitude and look angles, met with the product's
  own reference surface (the 1B tangent plane, or the ellipsoid raised by the reference
  height for 2A). The product's position of the pixel minus this is the error of the
  geometric chain (ephemeris, attitude, look angles, clock, approximations) alone;
* the **ground**: the point of the world's terrain the pixel truly sees. The product's
  position minus this adds the relief displacement ``(h − h_ref)·tan θ`` that only a DEM
  (level 3) removes.

The truth is measured in the emulator's own time base and line numbering; L0 rows are
matched to emulator lines by their time (the line clock is good to well under a line).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pyproj
from numpy.typing import NDArray

from levels.geo.level1b import Level1BGeometry
from levels.geo.level2a import Level2AGeometry
from levels.geo.level3 import Level3Geometry
from levels.geo.scenes import SceneGeometry
from levels.geometry.frames import apply, enu_from_ecef
from levels.geometry.model import PushbroomModel
from levels.quality import error_stats
from levels.readers.l0 import L0Archive
from station.errors import ScenarioError
from station.scenario import Scenario
from station.spacecraft.emulator import Acquisition, emulate, truth_model
from station.spacecraft.imaging import trace_pixels

__all__ = [
    "Truth",
    "checkpoints_1b",
    "checkpoints_2a",
    "checkpoints_3",
    "true_tie_points",
    "truth_for",
]


@dataclass(eq=False)
class Truth:
    """An acquisition and how the L0 archive's rows map onto its lines."""

    acq: Acquisition
    row_offset: int
    _models: dict[int, PushbroomModel] = field(default_factory=dict)

    @classmethod
    def of(cls, acq: Acquisition, archive: L0Archive) -> Truth:
        t0 = archive.line_t_s[0] + float(acq.epoch.seconds(archive.epoch.t0_utc))  # row 0,
        # in the emulator's time base
        offset = int(np.rint((t0 - acq.line_times_s[0]) / acq.hrv.line_period_s))
        return cls(acq, offset)

    def level_1b(
        self, scene: SceneGeometry, geometry: Level1BGeometry, band_index: int, per_side: int
    ) -> dict:
        """:func:`checkpoints_1b` (the :class:`levels.quality.CheckpointSource` protocol)."""
        return checkpoints_1b(self, scene, geometry, band_index, per_side)

    def level_2a(
        self, scene: SceneGeometry, geometry: Level2AGeometry, band_index: int, per_side: int
    ) -> dict:
        """:func:`checkpoints_2a` (the :class:`levels.quality.CheckpointSource` protocol)."""
        return checkpoints_2a(self, scene, geometry, band_index, per_side)

    def level_3(
        self, scene: SceneGeometry, geometry: Level3Geometry, band_index: int, per_side: int
    ) -> dict:
        """:func:`checkpoints_3` (the :class:`levels.quality.CheckpointSource` protocol)."""
        return checkpoints_3(self, scene, geometry, band_index, per_side)

    def model(self, band: int) -> PushbroomModel:
        if band not in self._models:
            self._models[band] = truth_model(self.acq, band)
        return self._models[band]

    def lattice(
        self, scene: SceneGeometry, per_side: int
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Checkpoint lines (scene numbering) and columns: whole pixels, as a real
        checkpoint is measured (a fractional column may fall between two butted CCDs)."""
        line, col = np.meshgrid(
            np.rint(np.linspace(0, scene.cut.n_lines - 1, per_side)),
            np.rint(np.linspace(0, scene.model.n_columns - 1, per_side)),
            indexing="ij",
        )
        return line.ravel(), col.ravel()

    def model_error_en(
        self, scene: SceneGeometry, per_side: int = 11
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """East and north error (m) of the scene's model against the truth's line of sight
        on the scene's reference surface, at the checkpoint lattice: the error of the
        geometry alone, before any grid or resampling (level 2 studies)."""
        line, col = self.lattice(scene, per_side)
        h = scene.reference_height_m
        p = scene.model.image_to_ground(line, col, h)
        q = self.model(0).image_to_ground(self.truth_lines(scene, line), col, h)
        ell = self.model(0).ellipsoid
        d = ell.to_ecef(p.lat_rad, p.lon_rad, p.h_m) - ell.to_ecef(q.lat_rad, q.lon_rad, q.h_m)
        enu = apply(enu_from_ecef(q.lat_rad, q.lon_rad), d)
        return enu[:, 0], enu[:, 1]

    def truth_lines(self, scene: SceneGeometry, line: NDArray[np.float64]) -> NDArray:
        return line + scene.cut.first_line + self.row_offset

    def ground(
        self, band: int, lines: NDArray[np.float64], col: NDArray[np.float64]
    ) -> NDArray[np.float64]:
        """ECEF points of the terrain truly seen (NaN where the ray missed), (N, 3)."""
        acq = self.acq
        t = acq.line_times_s[0] + lines * acq.hrv.line_period_s
        pts, ok = trace_pixels(acq.orbit, acq.attitude, acq.hrv.bands[band], acq.world, t, col)
        g = self.model(band).ellipsoid.to_ecef(pts[:, 0], pts[:, 1], pts[:, 2])
        g[~ok] = np.nan
        return g


def checkpoints_1b(
    truth: Truth, scene: SceneGeometry, geom: Level1BGeometry, band: int, per_side: int
) -> dict:
    """Checkpoint errors of a 1B product on its tangent plane (X south, Y east)."""
    line, col = truth.lattice(scene, per_side)
    i, j = geom.corrected_of(line, col)
    x, y = geom.plane_xy(i, j)
    tl = truth.truth_lines(scene, line)
    r, los = truth.model(band).sight(tl, col)
    xt, yt = geom.plane.intersect(r, los)
    g = truth.ground(band, tl, col) - geom.plane.origin_ecef_m
    xg, yg = g @ geom.plane.x_axis, g @ geom.plane.y_axis
    res = geom.pixel_size_m
    return {
        "axes": "1: X (south), 2: Y (east) of the tangent plane",
        "line_of_sight": error_stats(x - xt, y - yt, res),
        "ground": error_stats(x - xg, y - yg, res),
        "raw_line": line,
        "raw_column": col,
        "output_row": i,
        "output_col": j,
        "error_x_m": x - xt,
        "error_y_m": y - yt,
    }


def _to_map(crs_wkt: str) -> Callable[[NDArray, NDArray], tuple[NDArray, NDArray]]:
    """(latitude, longitude) in radians → the map's (easting, northing) in metres."""
    to_map = pyproj.Transformer.from_crs("EPSG:4326", pyproj.CRS.from_wkt(crs_wkt), always_xy=True)

    def en(lat: NDArray, lon: NDArray) -> tuple[NDArray, NDArray]:
        e, n = to_map.transform(np.degrees(lon), np.degrees(lat))
        return np.asarray(e), np.asarray(n)

    return en


def checkpoints_2a(
    truth: Truth, scene: SceneGeometry, geom: Level2AGeometry, band: int, per_side: int
) -> dict:
    """Checkpoint errors of a 2A product in its map (easting, northing)."""
    line, col = truth.lattice(scene, per_side)
    h_ref = scene.reference_height_m
    en = _to_map(geom.map_grid.crs_wkt)
    model = scene.models[list(scene.models)[band]]
    p = model.image_to_ground(line, col, h_ref)
    i0, j0 = geom.map_grid.ij_of_map(*en(p.lat_rad, p.lon_rad))
    i, j = geom.output_of(line, col, (i0, j0))
    e, n = geom.map_grid.map_of(i, j)
    tl = truth.truth_lines(scene, line)
    t = truth.model(band).image_to_ground(tl, col, h_ref)
    et, nt = en(t.lat_rad, t.lon_rad)
    g = truth.ground(band, tl, col)
    lat, lon, _h = truth.model(band).ellipsoid.to_geodetic(g)
    eg, ng = en(lat, lon)
    res = geom.map_grid.pixel_size_m
    return {
        "axes": "1: easting, 2: northing of the map",
        "line_of_sight": error_stats(e - et, n - nt, res),
        "ground": error_stats(e - eg, n - ng, res),
        "raw_line": line,
        "raw_column": col,
        "output_row": i,
        "output_col": j,
        "error_e_m": e - et,
        "error_n_m": n - nt,
    }


def checkpoints_3(
    truth: Truth, scene: SceneGeometry, geom: Level3Geometry, band: int, per_side: int
) -> dict:
    """Checkpoint errors of a level 3 product in its map: where it puts each checkpoint's raw
    pixel against where that pixel truly looked on the terrain (``ground``), and beside it
    where a product at the scene's reference height (2A) puts the same pixels
    (``ground_2a``: the relief displacement level 3 removed), and the DEM's height error
    under them (``dem_error``). Pixels whose ray missed the terrain, or that fall on a void
    of the DEM, are left out."""
    line, col = truth.lattice(scene, per_side)
    tl = truth.truth_lines(scene, line)
    g = truth.ground(band, tl, col)
    ok = np.all(np.isfinite(g), axis=1)
    lat, lon, h_true = truth.model(band).ellipsoid.to_geodetic(g[ok])
    en = _to_map(geom.map_grid.crs_wkt)
    eg, ng = en(lat, lon)
    ij_true = geom.map_grid.ij_of_map(eg, ng)
    i, j = geom.output_of(line[ok], col[ok], ij_true)
    e, n = geom.map_grid.map_of(i, j)
    fine = np.isfinite(e) & np.isfinite(n)
    model = scene.models[list(scene.models)[band]]
    flat = model.image_to_ground(line[ok], col[ok], scene.reference_height_m)
    e2, n2 = en(flat.lat_rad, flat.lon_rad)
    dh = (geom.height_at(*ij_true) - h_true)[fine]
    # each pixel's ground point moves by k metres per metre of height along the view:
    # a DEM error δh moves level 3 by k·δh (k = tan θ on flat ground)
    up = model.image_to_ground(line[ok], col[ok], scene.reference_height_m + 1.0)
    e3, n3 = en(up.lat_rad, up.lon_rad)
    k = np.hypot(e3 - e2, n3 - n2)[fine]
    res = geom.map_grid.pixel_size_m
    some = bool(fine.any())
    return {
        "axes": "1: easting, 2: northing of the map",
        "ground": error_stats((e - eg)[fine], (n - ng)[fine], res),
        "ground_2a": error_stats((e2 - eg)[fine], (n2 - ng)[fine], res),
        "dem_error": {
            "rms_m": float(np.sqrt(np.mean(dh**2))) if some else None,
            "max_m": float(np.max(np.abs(dh))) if some else None,
            "tan_view_angle": float(np.median(k)) if some else None,
            "predicted_ground_rms_m": float(np.sqrt(np.mean((k * dh) ** 2))) if some else None,
        },
        "raw_line": line[ok][fine],
        "raw_column": col[ok][fine],
        "output_row": i[fine],
        "output_col": j[fine],
        "error_e_m": (e - eg)[fine],
        "error_n_m": (n - ng)[fine],
    }


def true_tie_points(
    acq_a: Acquisition,
    acq_b: Acquisition,
    per_side: int,
    sigma_px: float,
    rng: np.random.Generator,
    approximate_h_m: float = 0.0,
    approximate_error_m: float = 300.0,
) -> tuple[Any, Any]:
    """Tie points between two acquisitions as a perfect matcher with image noise
    ``sigma_px`` would give them (the geometry studies of block adjustment, without
    images): a lattice of ``per_side`` × ``per_side`` pixels of ``a`` (emulator lines), the
    ground each truly sees projected into ``b`` by its true model, those inside ``b`` kept.
    Their approximate ground, what a block starts from and solves: the true one moved by
    ``approximate_error_m`` (1σ east and north, as a system model misplaces it) at
    ``approximate_h_m`` — never the truth itself, which a weakly determined solution would
    otherwise keep. Two control-point sets of kind ``tie`` (lines in each acquisition's
    own numbering)."""
    from levels.geometry.ellipsoid import WGS84
    from levels.readers.gcp import ControlPointSet

    n_a = acq_a.line_times_s.size
    line, col = (
        v.ravel()
        for v in np.meshgrid(
            np.linspace(0.02, 0.98, per_side) * (n_a - 1),
            np.linspace(0.02, 0.98, per_side) * (acq_a.hrv.n_columns - 1),
            indexing="ij",
        )
    )
    lat, lon, h = WGS84.to_geodetic(Truth(acq_a, 0).ground(0, line, col))
    back = truth_model(acq_b).ground_to_image(lat, lon, h)
    inside = (
        back.converged
        & (back.line >= 0)
        & (back.line <= acq_b.line_times_s.size - 1)
        & (back.column >= 0)
        & (back.column <= acq_b.hrv.n_columns - 1)
        & np.isfinite(h)
    )
    n = int(inside.sum())
    ids = tuple(f"tie{k:04d}" for k in range(n))
    east, north = approximate_error_m * rng.standard_normal((2, n))
    lat0 = lat[inside] + north / WGS84.a_m
    lon0 = lon[inside] + east / (WGS84.a_m * np.cos(lat[inside]))

    def measured(ln: NDArray, cl: NDArray, hrv: int) -> ControlPointSet:
        return ControlPointSet(
            ids,
            lon0,
            lat0,
            np.full(n, approximate_h_m),
            ln + sigma_px * rng.standard_normal(n),
            cl + sigma_px * rng.standard_normal(n),
            np.full(n, 1e4),
            np.full(n, 1e3),
            np.full(n, sigma_px),
            np.full(n, hrv, dtype=np.int64),
            np.ones(n, dtype=bool),
        )

    return (
        measured(line[inside], col[inside], acq_a.hrv.number),
        measured(back.line[inside], back.column[inside], acq_b.hrv.number),
    )


def truth_for(scn: Scenario, archive: L0Archive) -> Truth:
    """The truth behind ``archive``, emulated again from the scenario that made it.

    The scenario must be the archive's (same name and, when both are known, the same
    SHA-256 of its file) and must image the archive's HRV.
    """
    prov = archive.provenance
    if prov.get("scenario", scn.name) != scn.name or (
        prov.get("scenario_sha256")
        and scn.source_sha256
        and prov["scenario_sha256"] != scn.source_sha256
    ):
        raise ScenarioError(
            f"{archive.path} was recorded from scenario {prov.get('scenario')!r} "
            f"(sha256 {str(prov.get('scenario_sha256', '?'))[:12]}…), not from {scn.source} "
            f"({scn.name!r}, {scn.source_sha256[:12]}…); give the scenario that made it"
        )
    numbers = [i.hrv for i in scn.instruments]
    if archive.hrv not in numbers:
        raise ScenarioError(
            f"{archive.path} holds HRV{archive.hrv}; scenario {scn.name!r} images with HRV{numbers}"
        )
    # geometry only: the truth of a checkpoint is where its pixel looks, not what it saw;
    # emulated once per scenario and HRV (a block run asks for it at each of its stages)
    key = (scn.name, scn.source_sha256, scn.seed, archive.hrv)
    if scn.source_sha256 and key in _TRUTHS:
        acq = _TRUTHS[key]
    else:
        acq = emulate(scn, render=False, instrument=numbers.index(archive.hrv))
        if scn.source_sha256:
            _TRUTHS[key] = acq
            while len(_TRUTHS) > _TRUTHS_KEPT:
                _TRUTHS.pop(next(iter(_TRUTHS)))
    return Truth.of(acq, archive)


#: Geometry-only acquisitions emulated for the truth, by scenario (its file's SHA-256) and
#: HRV; the last few kept (a full pass's geometry is a few MB).
_TRUTHS: dict[tuple[str, str, int, int], Any] = {}
_TRUTHS_KEPT = 8
