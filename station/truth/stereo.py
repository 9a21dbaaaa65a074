"""The truth behind a stereo pair (:mod:`levels.stereo`): the exact disparity, the true
terrain under the DEM, and checkpoints measured in both images.

* **exact disparity**: for an epipolar pixel of the first view, the raw pixel it samples,
  the terrain that pixel truly sees (the emulator's ray tracing), where the second view's
  true geometry images that ground, and where that raw pixel lands on the epipolar grid
  (through the second view's adjusted model, as its image was resampled): the disparity a
  perfect matcher finds, and the ``v``-parallax it must tolerate;
* **the DEM against the terrain**: each valid cell's height minus the world's at the cell
  centre; NMAD and LE90 by slope class (the true terrain's slope); the cells both images
  see (the true terrain there imaged inside both raw images); the plane the error leans on
  (bias and tilt: the absolute orientation from the control points) and the error without
  it (the DEM's relative error, as a DEM comparison coregisters first);
* **checkpoints** (PHOTOMOD's Table 1): ground points of the terrain, their true image
  positions in both scenes with a pointing error, triangulated on the adjusted models.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import pyproj
from numpy.typing import NDArray

from levels.geometry.ellipsoid import WGS84
from levels.quality import error_stats
from levels.stereo import EpipolarPair, StereoDem, StereoView, triangulate_raw
from station.truth.optical import Truth

if TYPE_CHECKING:
    from station.spacecraft.world import World

__all__ = [
    "SLOPE_CLASSES_DEG",
    "StereoTruth",
    "checkpoints",
    "dem_errors",
    "exact_disparity",
    "robust_stats",
    "stereo_quality",
]

#: The slope classes of the DEM's statistics (degrees): < 10, 10–30, > 30.
SLOPE_CLASSES_DEG = ((0.0, 10.0), (10.0, 30.0), (30.0, 90.0))


@dataclass(frozen=True, eq=False)
class StereoTruth:
    """The truth behind each view of a pair."""

    a: Truth
    b: Truth

    def of(self, which: int) -> Truth:
        return (self.a, self.b)[which]


def _true_lines(truth: Truth, view: StereoView, line: NDArray) -> NDArray:
    return line + view.first_line + truth.row_offset


def _scene_lines(truth: Truth, view: StereoView, line: NDArray) -> NDArray:
    return line - view.first_line - truth.row_offset


def _inside(view: StereoView, line: NDArray, col: NDArray) -> NDArray[np.bool_]:
    n_l, n_c = view.image.shape
    return (line >= 0) & (line <= n_l - 1) & (col >= 0) & (col <= n_c - 1)


def exact_disparity(
    pair: EpipolarPair,
    truth: StereoTruth,
    step: int = 4,
    box: tuple[int, int, int, int] | None = None,
) -> dict[str, NDArray[np.float64]]:
    """The exact disparity and ``v``-parallax at every ``step``-th epipolar pixel that
    both raw images see (of rows ``box[0]:box[1]`` and columns ``box[2]:box[3]``, default
    all): ``u``, ``v`` (whole pixels), ``d`` and ``dv`` (module docstring)."""
    r0, r1, c0, c1 = box or (0, pair.frame.shape[0], 0, pair.frame.shape[1])
    v, u = (
        x.ravel().astype(np.float64)
        for x in np.meshgrid(np.arange(r0, r1, step), np.arange(c0, c1, step), indexing="ij")
    )
    la, ca = pair.raw_of(0, u, v)
    k = _inside(pair.a, la, ca)
    u, v, la, ca = u[k], v[k], la[k], ca[k]
    g = truth.a.ground(0, _true_lines(truth.a, pair.a, la), ca)
    lat, lon, h = WGS84.to_geodetic(g)
    img = truth.b.model(0).ground_to_image(lat, lon, h)
    lb, cb = _scene_lines(truth.b, pair.b, img.line), img.column
    on = pair.b.model.image_to_ground(lb, cb, pair.b.reference_height_m)
    to_map = pyproj.Transformer.from_crs(
        pyproj.CRS.from_epsg(4326), pyproj.CRS.from_wkt(pair.frame.crs_wkt), always_xy=True
    )
    x, y = to_map.transform(np.degrees(on.lon_rad), np.degrees(on.lat_rad))
    ub, vb = pair.frame.uv_of(np.asarray(x), np.asarray(y))
    ok = np.isfinite(h) & img.converged & _inside(pair.b, lb, cb) & np.isfinite(ub)
    return {"u": u[ok], "v": v[ok], "d": (ub - u)[ok], "dv": (vb - v)[ok], "h_m": h[ok]}


def disparity_errors(dem: StereoDem, exact: dict[str, NDArray]) -> dict[str, object]:
    """The matched disparity against the exact one on the valid pixels of the lattice."""
    iv, iu = exact["v"].astype(np.int64), exact["u"].astype(np.int64)
    d = dem.disparity.d[iv, iu].astype(np.float64)
    ok = np.isfinite(d)
    if not ok.any():
        return {"points": 0, "valid_fraction": 0.0}
    err = d[ok] - exact["d"][ok]
    sigma = dem.disparity.sigma[iv, iu][ok].astype(np.float64)
    return {
        "points": int(err.size),
        "valid_fraction": float(ok.mean()),
        "rms_px": float(np.sqrt(np.mean(err**2))),
        "mean_px": float(np.mean(err)),
        "nmad_px": robust_stats(err)["nmad"],
        "predicted_rms_px": float(np.sqrt(np.mean(sigma**2))),
        "beyond_1px_fraction": float(np.mean(np.abs(err) > 1.0)),
        "v_parallax_rms_px": float(np.sqrt(np.mean(exact["dv"] ** 2))),
    }


def robust_stats(err: NDArray[np.float64]) -> dict[str, float]:
    """Count, mean, RMSE, median, NMAD (1.4826 × the median absolute deviation from the
    median) and LE90 (the 90th percentile of the absolute error) of errors."""
    med = float(np.median(err))
    return {
        "count": int(err.size),
        "mean": float(np.mean(err)),
        "rmse": float(np.sqrt(np.mean(err**2))),
        "median": med,
        "nmad": float(1.4826 * np.median(np.abs(err - med))),
        "le90": float(np.percentile(np.abs(err), 90.0)),
    }


def true_heights(dem: StereoDem, world: World) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The world's terrain height (m) and slope (degrees) at the DEM's cell centres."""
    grid = dem.grid
    x, y = np.meshgrid(grid.x_m(), grid.y_m())
    lon, lat = pyproj.Transformer.from_crs(
        pyproj.CRS.from_wkt(grid.crs_wkt), pyproj.CRS.from_epsg(4326), always_xy=True
    ).transform(x.ravel(), y.ravel())
    h, gx, gy = world.height(np.radians(lat), np.radians(lon))
    slope = np.degrees(np.arctan(np.hypot(gx, gy)))
    return h.reshape(grid.shape), slope.reshape(grid.shape)


#: Cells of the coverage figure at most (a lattice of the DEM's): both true models are
#: inverted at each.
COVERAGE_CELLS = 250_000


def _seen_by_both(
    dem: StereoDem, truth: StereoTruth, h_true: NDArray, every: int
) -> NDArray[np.bool_]:
    """Of every ``every``-th cell each way, those whose true terrain both raw images see."""
    grid = dem.grid
    x, y = np.meshgrid(grid.x_m()[::every], grid.y_m()[::every])
    h_true = h_true[::every, ::every]
    lon, lat = pyproj.Transformer.from_crs(
        pyproj.CRS.from_wkt(grid.crs_wkt), pyproj.CRS.from_epsg(4326), always_xy=True
    ).transform(x.ravel(), y.ravel())
    lat, lon = np.radians(lat), np.radians(lon)
    seen = np.ones(lat.size, dtype=bool)
    for which, view in enumerate((dem.pair.a, dem.pair.b)):
        t = truth.of(which)
        img = t.model(0).ground_to_image(lat, lon, h_true.ravel())
        line = _scene_lines(t, view, img.line)
        # the epipolar images' cubic window needs two raw pixels on each side
        n_l, n_c = view.image.shape
        seen &= img.converged & (line >= 2) & (line <= n_l - 3)
        seen &= (img.column >= 2) & (img.column <= n_c - 3)
    return seen.reshape(x.shape)


def dem_errors(dem: StereoDem, truth: StereoTruth, world: World) -> dict[str, object]:
    """The DEM against the true terrain (module docstring)."""
    h_true, slope = true_heights(dem, world)
    err = dem.height_m.astype(np.float64) - h_true
    valid = np.isfinite(err)
    every = max(1, int(np.ceil(np.sqrt(h_true.size / COVERAGE_CELLS))))
    seen = _seen_by_both(dem, truth, h_true, every)
    by_slope = {}
    for lo, hi in SLOPE_CLASSES_DEG:
        k = valid & (slope >= lo) & (slope < hi)
        if k.any():
            by_slope[f"{lo:g}-{hi:g}deg"] = robust_stats(err[k])
    e = err[valid]
    sigma = dem.sigma_m[valid].astype(np.float64)
    stats = robust_stats(e)
    datum, rest = _datum_plane(dem, err, valid)
    return {
        **stats,
        "by_slope": by_slope,
        "coverage_of_seen": float(np.sum(valid[::every, ::every] & seen) / max(1, int(seen.sum()))),
        "coverage_lattice_every": every,
        "predicted_rms_m": float(np.sqrt(np.mean(sigma**2))),
        "predicted_median_m": float(np.median(sigma)),
        "std_m": float(np.std(e)),
        # the precision: each cell's error (the model's bias, the median, left out) in its
        # own predicted σ; their robust spread is 1 if every σ is right (blunders left out)
        "measured_over_predicted": float(1.4826 * np.median(np.abs((e - stats["median"]) / sigma))),
        "datum": datum,
        "datum_removed": {
            **robust_stats(rest),
            # the matching's own σ against what is left of the matching
            "measured_over_predicted": float(1.4826 * np.median(np.abs(rest / sigma))),
        },
    }


def _datum_plane(
    dem: StereoDem, err: NDArray[np.float64], valid: NDArray[np.bool_]
) -> tuple[dict[str, float], NDArray[np.float64]]:
    """The plane the DEM's error leans on (its bias at the centre, m, and its tilt east
    and north, m per km: the absolute orientation the control points gave the pair, the
    same under every cell) and the error without it (the DEM's own, the matching's): what
    a DEM comparison takes out first (demcompare and xdem coregister, bias and tilt)."""
    grid = dem.grid
    x = (grid.x_m() - np.mean(grid.x_m())) / 1000.0
    y = (grid.y_m() - np.mean(grid.y_m())) / 1000.0
    xx, yy = np.meshgrid(x, y)
    a = np.column_stack([np.ones(int(valid.sum())), xx[valid], yy[valid]])
    coef, *_ = np.linalg.lstsq(a, err[valid], rcond=None)
    plane = {
        "bias_m": float(coef[0]),
        "tilt_east_m_per_km": float(coef[1]),
        "tilt_north_m_per_km": float(coef[2]),
    }
    return plane, err[valid] - a @ coef


def checkpoints(
    pair: EpipolarPair,
    truth: StereoTruth,
    world: World,
    count: int = 25,
    pointing_px: float = 0.3,
    rng: np.random.Generator | None = None,
) -> dict[str, object]:
    """``count`` checkpoints spread over the pair's common footprint (PHOTOMOD had 23): the
    terrain there, its true image position in both scenes with a pointing error of
    ``pointing_px`` per axis, triangulated on the adjusted models; east, north, plan and
    height errors (m)."""
    rng = rng or np.random.default_rng(0)
    rows, cols = pair.frame.shape
    v, u = (
        x.ravel()
        for x in np.meshgrid(
            np.linspace(0.05, 0.95, 15) * (rows - 1),
            np.linspace(0.05, 0.95, 15) * (cols - 1),
            indexing="ij",
        )
    )
    la, ca = pair.raw_of(0, u, v)
    lb, cb = pair.raw_of(1, u, v)  # at the reference height: inside both, roughly
    k = np.flatnonzero(_inside(pair.a, la, ca) & _inside(pair.b, lb, cb))
    k = k[np.unique(np.linspace(0, k.size - 1, min(count, k.size)).astype(np.int64))]
    g = truth.a.ground(0, _true_lines(truth.a, pair.a, la[k]), ca[k])
    lat, lon, h = WGS84.to_geodetic(g)
    measured = []
    for which, view in enumerate((pair.a, pair.b)):
        t = truth.of(which)
        img = t.model(0).ground_to_image(lat, lon, h)
        line = _scene_lines(t, view, img.line) + pointing_px * rng.standard_normal(lat.size)
        col = img.column + pointing_px * rng.standard_normal(lat.size)
        measured.append((line, col, img.converged & _inside(view, line, col)))
    ok = measured[0][2] & measured[1][2] & np.isfinite(h)
    (la2, ca2, _), (lb2, cb2, _) = measured
    plat, plon, ph, miss = triangulate_raw(
        pair.a.model, pair.b.model, la2[ok], ca2[ok], lb2[ok], cb2[ok]
    )
    north = (plat - lat[ok]) * WGS84.a_m
    east = (plon - lon[ok]) * WGS84.a_m * np.cos(lat[ok])
    dh = ph - h[ok]
    out = error_stats(east, north, pair.frame.pixel_m)
    return {
        "points": int(ok.sum()),
        "pointing_px": pointing_px,
        "plan_rms_m": float(np.sqrt(np.mean(east**2 + north**2))),
        "east_rms_m": float(np.sqrt(np.mean(east**2))),
        "north_rms_m": float(np.sqrt(np.mean(north**2))),
        "height_rms_m": float(np.sqrt(np.mean(dh**2))),
        "height_mean_m": float(np.mean(dh)),
        "miss_rms_m": float(np.sqrt(np.mean(miss**2))),
        "stats": out,
    }


def stereo_quality(
    dem: StereoDem, truth: StereoTruth, world: World, exact_step: int = 4
) -> dict[str, object]:
    """A DEM's figures against the truth, as its product keeps them: the disparity against
    the exact one, the heights against the terrain (by slope class), the checkpoints."""
    exact = exact_disparity(dem.pair, truth, exact_step)
    errors = dem_errors(dem, truth, world)
    return {
        "disparity": disparity_errors(dem, exact),
        "heights": errors,
        "checkpoints": {
            k: v for k, v in checkpoints(dem.pair, truth, world).items() if k != "stats"
        },
    }
