"""Level 3 geometry: orthorectification over a DEM, the indirect method (Shu Ning, ``002_…``).

Levels 1B–2 put every pixel on a surface of constant height; relief then shifts it by about
``h · tan θ``. Level 3 puts each output pixel where the terrain is:

1. **Anchor grids at several heights.** The 2A chain (direct grid, inversion, inverse grid:
   :mod:`levels.geo.level2a`, with its care for the CCD buttings) is run at
   ``HEIGHT_LEVELS`` reference heights spanning the DEM over the scene, all on one map grid.
   Each gives, at every anchor of the output grid, the raw ``(L, C)`` that sees the map
   point *at that height*: a 3-D anchor grid over (row, column, height).
2. **The DEM per pixel.** The DEM (:mod:`levels.readers.dem`, any CRS and datum) keeps its
   own grid: every ``DEM_COORD_STEP`` output pixels, the fractional (row, column) of the
   DEM under the pixel is computed exactly through PROJ, and bilinearly between (the map
   → DEM mapping is smooth: micro-pixels over a few hundred metres); at every output pixel
   the DEM is then sampled bilinearly in its own grid, so the terrain height under a pixel
   is the DEM's own surface, however fine or coarse the DEM is against the pixel.
3. **Densification.** At each output pixel, each height level's grid is interpolated
   bilinearly (as in 2A), and the levels are combined by Lagrange interpolation in the
   pixel's height (quadratic through three levels: the raw position of a ground point moves
   almost linearly with its height, ``h · tan θ``, and the quadratic takes the rest).

The anchor grid's error is measured, never assumed: :meth:`Level3Geometry.anchor_error`
takes a lattice of output pixels to the ground at their DEM height and into the raw image
through the rigorous model, and compares with the grid. :func:`level3_geometry` halves the
anchor spacing until that error is at most ``ANCHOR_TOLERANCE_PX``.

Pixels hidden by the relief (behind a ridge at a steep view angle) are found by a z-buffer
in the raw image (:func:`levels.cor.resample.resample_3`): of the ground points that fall in
one raw pixel, the highest is the one seen (every line of sight descends), and a point more
than ``HIDDEN_TOLERANCE_PX`` raw pixels of line of sight below it is hidden. The terrain
between neighbouring output pixels that land raw pixels apart (a steep face toward the
sensor, a cliff, a wall) is drawn into the z-buffer too: it has no output pixel of its own,
but it hides the ground behind it. Voids of the DEM leave their pixels invalid.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pyproj
from numpy.typing import ArrayLike, NDArray

from levels.errors import DemError, GeometryError, ProductError
from levels.geo.inverse_grid import bilinear_grid, invert_by_newton
from levels.geo.level2a import Level2AGeometry, level2a_geometry
from levels.geo.maps import MapGrid
from levels.geo.misfit import raw_error_stats
from levels.geo.scenes import SceneGeometry
from levels.geometry.dem import Dem, bilinear_surface, geoid_to_ellipsoid
from levels.geometry.sensor import butting_columns
from levels.threads import one_blas_thread

if TYPE_CHECKING:
    from levels.geometry.model import PushbroomModel

__all__ = [
    "ANCHOR_TOLERANCE_PX",
    "HEIGHT_LEVELS",
    "Level3Geometry",
    "lagrange_weights",
    "level3_geometry",
]

#: Reference heights of the anchor grid (Lagrange in height through them).
HEIGHT_LEVELS = 3
#: The anchor grid's error against the rigorous model must not exceed this (raw pixels).
ANCHOR_TOLERANCE_PX = 0.05
#: Halving the anchor spacing goes on while it cuts the error to this share at least.
ANCHOR_GAIN = 0.9
#: Height margin (m) of the anchor levels beyond the DEM's range over the scene.
HEIGHT_MARGIN_M = 50.0
#: A ground point more than this many raw pixels of line of sight below the highest point
#: seen in its raw pixel is hidden (steep slopes facing the sensor put neighbours that much
#: apart in height within one raw pixel).
HIDDEN_TOLERANCE_PX = 1.5
#: Output pixels between the nodes where the DEM's (row, column) under the output grid is
#: computed through PROJ (bilinear between: the mapping bends by micro-pixels over them).
DEM_COORD_STEP = 16
#: Lattice of output pixels per side where the anchor error is measured.
ANCHOR_CHECK_LATTICE = 41


def lagrange_weights(nodes: NDArray[np.float64], x: NDArray[np.float64]) -> NDArray[np.float64]:
    """Lagrange interpolation weights at ``x`` through ``nodes``, shape ``(K, *x.shape)``."""
    w = np.ones((nodes.size, *np.shape(x)))
    for k in range(nodes.size):
        for m in range(nodes.size):
            if m != k:
                w[k] *= (x - nodes[m]) / (nodes[k] - nodes[m])
    return w


@dataclass(frozen=True, eq=False)
class Level3Geometry:
    """GEO for level 3: anchor grids at ``heights_m`` sharing one map grid, the DEM window
    under the scene (as given, and its heights above the ellipsoid), the DEM's (row,
    column) under every ``dem_step_px``-th output pixel, the anchor grid's measured error."""

    levels: tuple[Level2AGeometry, ...]
    heights_m: NDArray[np.float64]
    dem: Dem  # the part of the DEM under the scene, in its own CRS and datum
    dem_ellipsoidal_m: NDArray[np.float64]  # its heights above the ellipsoid
    dem_rc: NDArray[np.float64]  # (2, na, nb): its (row, column) at output (a·step, b·step)
    dem_step_px: float
    dem_spacing_m: float
    anchor_error_px: dict[str, float]

    @staticmethod
    def product_tree(bands: dict[str, Level3Geometry]) -> dict[str, object]:
        """The ``geometry/level_3`` tree of a product whose bands have these geometries
        (``docs/products.md``): the DEM used (its window, CRS, datum, spacing), the anchor
        grids' heights, each height's 2A tree, and the anchor error measured."""
        g = next(iter(bands.values()))
        dem = g.dem
        exact32 = np.array_equal(dem.height_m.astype(np.float32), dem.height_m, equal_nan=True)
        return {
            "heights_m": g.heights_m,
            "dem_step_px": g.dem_step_px,
            "anchor_error_px": {b: dict(geom.anchor_error_px) for b, geom in bands.items()},
            "dem": {
                "height_m": dem.height_m.astype(np.float32) if exact32 else dem.height_m,
                "geotransform": np.asarray(dem.geotransform),
                "crs_wkt": dem.crs_wkt,
                "vertical": dem.vertical,
                "source": Path(dem.source).name if dem.source else "",  # its name: not where
                "spacing_m": g.dem_spacing_m,
            },
            **{
                f"height_{k}": Level2AGeometry.product_tree(
                    {b: gb.levels[k] for b, gb in bands.items()}
                )
                for k in range(g.heights_m.size)
            },
        }

    @classmethod
    def from_tree(cls, tree: dict[str, object], band: str | None = None) -> Level3Geometry:
        """The geometry of ``band`` (the first by default) from a product's
        ``geometry/level_3`` tree (the DEM's heights on the output grid computed again from
        the DEM window it stores); :class:`ProductError` names what is missing or bad."""
        levels, heights, dem, step, spacing, err = cls._parts(tree, band)
        return cls(
            levels,
            heights,
            dem,
            _ellipsoidal(dem),
            _dem_coordinates(dem, levels[0].map_grid, step),
            step,
            spacing,
            err,
        )

    @classmethod
    def check_tree(cls, tree: dict[str, object], band: str | None = None) -> None:
        """:class:`ProductError` if ``from_tree`` would fail (without its heavy part)."""
        cls._parts(tree, band)

    @staticmethod
    def _parts(tree: dict[str, Any], band: str | None) -> tuple[Any, ...]:
        try:
            heights = np.asarray(tree["heights_m"], dtype=np.float64).ravel()
            if heights.size < 2 or not np.all(np.diff(heights) > 0):
                raise ValueError(f"anchor heights {heights} must increase")
            levels = tuple(
                Level2AGeometry.from_tree(tree[f"height_{k}"], band) for k in range(heights.size)
            )
            d = tree["dem"]
            gt = tuple(float(v) for v in np.asarray(d["geotransform"]).ravel())
            if len(gt) != 6:
                raise ValueError(f"DEM geotransform {gt}: 6 numbers expected")
            pyproj.CRS.from_wkt(str(d["crs_wkt"]))
            dem = Dem(
                np.asarray(d["height_m"], dtype=np.float64),
                gt,
                str(d["crs_wkt"]),
                str(d["vertical"]),
                str(d["source"]),
            )
            step = float(tree["dem_step_px"])
            if not step > 0:
                raise ValueError(f"dem_step_px = {step}")
            errors = tree["anchor_error_px"]
            err = errors[band if band is not None else next(iter(errors))]
            return (
                levels,
                heights,
                dem,
                step,
                float(d["spacing_m"]),
                {k: float(v) for k, v in err.items()},
            )
        except (
            KeyError,
            TypeError,
            ValueError,
            StopIteration,
            DemError,
            pyproj.exceptions.CRSError,
        ) as exc:
            if isinstance(exc, ProductError):
                raise
            raise ProductError(
                f"level 3 geometry tree is incomplete or damaged ({type(exc).__name__}: {exc})"
            ) from None

    @property
    def template(self) -> Level2AGeometry:
        """The first anchor level's 2A geometry: its map grid and inverse-grid nodes are
        every level's."""
        return self.levels[0]

    @property
    def map_grid(self) -> MapGrid:
        """The output grid (every anchor level's)."""
        return self.levels[0].map_grid

    def height_at(self, i: ArrayLike, j: ArrayLike) -> NDArray[np.float64]:
        """The DEM's ellipsoidal height under output pixels (NaN over voids)."""
        a = np.asarray(i, dtype=np.float64) / self.dem_step_px
        b = np.asarray(j, dtype=np.float64) / self.dem_step_px
        row = bilinear_grid(self._nodes(0), self._nodes(1), self.dem_rc[0], a, b)
        col = bilinear_grid(self._nodes(0), self._nodes(1), self.dem_rc[1], a, b)
        return bilinear_surface(self.dem_ellipsoidal_m, row, col)

    def _nodes(self, axis: int) -> NDArray[np.float64]:
        return np.arange(float(self.dem_rc.shape[1 + axis]))

    @property
    def terrain_range_m(self) -> tuple[float, float]:
        """The lowest and highest DEM heights (ellipsoidal) under the scene; NaN if none."""
        h = self.dem_ellipsoidal_m
        if not np.isfinite(h).any():
            return float("nan"), float("nan")
        return float(np.nanmin(h)), float(np.nanmax(h))

    def raw_of(
        self, i: ArrayLike, j: ArrayLike, h_m: ArrayLike | None = None
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Raw ``(L, C)`` of output pixels on the terrain (the DEM's height, or ``h_m``):
        each level's grid bilinearly, the levels by Lagrange in height; the line from the
        segment of the interpolated column (NaN over voids)."""
        i_a, j_a = np.broadcast_arrays(
            np.asarray(i, dtype=np.float64), np.asarray(j, dtype=np.float64)
        )
        h = self.height_at(i_a, j_a) if h_m is None else np.broadcast_to(h_m, i_a.shape)
        w = lagrange_weights(self.heights_m, h)
        g = self.template
        rows, cols = g.inverse_rows, g.inverse_cols
        col = sum(
            w[k] * bilinear_grid(rows, cols, lv.inverse_column, i_a, j_a)
            for k, lv in enumerate(self.levels)
        )
        col = np.asarray(col)
        seg = g.segment_of(np.nan_to_num(col))
        line = np.full(col.shape, np.nan)
        for s in np.unique(seg):
            m = seg == s
            line[m] = sum(
                w[k][m] * bilinear_grid(rows, cols, lv.inverse_line[s], i_a[m], j_a[m])
                for k, lv in enumerate(self.levels)
            )
        return line, np.where(np.isfinite(h), col, np.nan)

    def output_of(
        self, line: ArrayLike, column: ArrayLike, first_guess: tuple[NDArray, NDArray]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Output ``(I, J)`` where raw ``(L, C)`` lands on the terrain: Newton from
        ``first_guess`` with the grid's Jacobian (the DEM's slopes included)."""
        return invert_by_newton(self.raw_of, line, column, first_guess, 8)

    def anchor_error(self, scene: SceneGeometry, band: str | None = None) -> dict[str, float]:
        """The anchor grid against the rigorous model at the pixels' DEM heights, in raw
        pixels, over a lattice of output pixels inside the raw image (butting gaps left
        out, as for 2A: no detector sees there)."""
        model = scene.models[band] if band is not None else scene.model
        n = ANCHOR_CHECK_LATTICE
        i, j = (
            a.ravel()
            for a in np.meshgrid(
                np.linspace(0, self.map_grid.n_rows - 1, n),
                np.linspace(0, self.map_grid.n_cols - 1, n),
                indexing="ij",
            )
        )
        h = self.height_at(i, j)
        la, ca = self.raw_of(i, j, h)
        inside = (
            np.isfinite(h)
            & (la >= 0)
            & (la <= self.template.n_raw_lines - 1)
            & (ca >= 0)
            & (ca <= self.template.n_raw_columns - 1)
        )
        e, nn = self.map_grid.map_of(i[inside], j[inside])
        to_geo = pyproj.Transformer.from_crs(
            pyproj.CRS.from_wkt(self.map_grid.crs_wkt), "EPSG:4326", always_xy=True
        )
        lon, lat = to_geo.transform(e, nn)
        exact = model.ground_to_image(
            np.radians(lat), np.radians(lon), h[inside], first_line=la[inside]
        )
        gap = np.zeros(exact.column.size, dtype=bool)
        for first in butting_columns(model.look_angles)[1::2]:
            gap |= (exact.column > first - 1) & (exact.column < first)
        ok = exact.converged & ~gap
        return raw_error_stats((la[inside] - exact.line)[ok], (ca[inside] - exact.column)[ok])


def _dem_coordinates(dem: Dem, grid: MapGrid, step_px: float) -> NDArray[np.float64]:
    """The DEM's fractional (row, column) at output pixels ``(a·step, b·step)`` covering
    the grid, shape ``(2, na, nb)``."""
    na = int(np.ceil((grid.n_rows - 1) / step_px)) + 2
    nb = int(np.ceil((grid.n_cols - 1) / step_px)) + 2
    a, b = np.meshgrid(np.arange(na) * step_px, np.arange(nb) * step_px, indexing="ij")
    to_dem = pyproj.Transformer.from_crs(
        pyproj.CRS.from_wkt(grid.crs_wkt), pyproj.CRS.from_wkt(dem.crs_wkt), always_xy=True
    )
    east, north = grid.map_of(a, b)
    x, y = to_dem.transform(east.ravel(), north.ravel())
    row, col = dem.pixel_of(np.asarray(x), np.asarray(y))
    return np.stack([row.reshape(na, nb), col.reshape(na, nb)])


def _ellipsoidal(dem: Dem) -> NDArray[np.float64]:
    """The DEM's heights above the ellipsoid at its own nodes (EGM96's undulation added
    through PROJ's grid for a geoid DEM)."""
    if dem.vertical == "ellipsoid":
        return dem.height_m
    r, c = np.meshgrid(*(np.arange(float(n)) for n in dem.height_m.shape), indexing="ij")
    x, y = dem.xy_of(r, c)
    to_geo = pyproj.Transformer.from_crs(
        pyproj.CRS.from_wkt(dem.crs_wkt), "EPSG:4326", always_xy=True
    )
    lon, lat = to_geo.transform(x.ravel(), y.ravel())
    h = geoid_to_ellipsoid(np.radians(lat), np.radians(lon), dem.height_m.ravel())
    return h.reshape(dem.height_m.shape)


def _dem_window(dem: Dem, grid: MapGrid) -> Dem:
    """The part of the DEM under the grid, two nodes of margin: what a product stores."""
    row, col = _dem_coordinates(dem, grid, DEM_COORD_STEP)
    nr, nc = dem.height_m.shape
    inside = (row > -1) & (row < nr) & (col > -1) & (col < nc)
    if not inside.any():
        raise GeometryError(f"level 3: the DEM {dem.source or ''} does not cover the scene")
    r, c = row[inside], col[inside]
    return dem.window(
        slice(max(0, int(np.floor(r.min())) - 2), int(np.ceil(r.max())) + 3),
        slice(max(0, int(np.floor(c.min())) - 2), int(np.ceil(c.max())) + 3),
    )


def _dem_spacing_m(dem: Dem, lat_rad: float) -> float:
    sx, sy = dem.spacing
    crs = pyproj.CRS.from_wkt(dem.crs_wkt)
    if crs.is_geographic:
        r = 6371000.0
        return float(np.radians(min(sx * np.cos(lat_rad), sy)) * r)
    return float(min(sx, sy))


def _height_levels(scene: SceneGeometry, dem: Dem, footprint: MapGrid) -> NDArray[np.float64]:
    """The heights of level 3's 2A grids: :data:`HEIGHT_LEVELS` from the lowest to the
    highest of the DEM under the scene's footprint at its reference height (a bilinear
    surface peaks at its nodes), :data:`HEIGHT_MARGIN_M` beyond."""
    probe_dem = _ellipsoidal(_dem_window(dem, footprint))
    if not np.isfinite(probe_dem).any():
        raise GeometryError(
            f"level 3: the DEM {dem.source or ''} has only voids under scene {scene.cut.index}"
        )
    lo = float(np.nanmin(probe_dem)) - HEIGHT_MARGIN_M
    hi = float(np.nanmax(probe_dem)) + HEIGHT_MARGIN_M
    return np.linspace(lo, hi, HEIGHT_LEVELS)


@one_blas_thread
def level3_geometry(
    scene: SceneGeometry,
    dem: Dem,
    pixel_size_m: float,
    crs: pyproj.CRS,
    method: str = "nearest4",
    grid_rows: str = "attitude",
    band: str | None = None,
    like: Level3Geometry | None = None,
    grid_columns: str = "butting",
    inverse_step_px: int = 0,
) -> Level3Geometry:
    """GEO for level 3 (module docstring): the anchor spacing is halved from 2A's until
    its error is at most :data:`ANCHOR_TOLERANCE_PX` (``inverse_step_px`` fixes it)."""
    b = band or next(iter(scene.models))

    def grid_2a(s: SceneGeometry, like_2a: Level2AGeometry | None = None) -> Level2AGeometry:
        return level2a_geometry(
            s,
            pixel_size_m,
            crs,
            method,
            grid_rows=grid_rows,
            band=b,
            like=like_2a,
            grid_columns=grid_columns,
        )

    spacing = _dem_spacing_m(dem, scene.centre_lat_rad)
    heights = _height_levels(scene, dem, grid_2a(scene).map_grid)
    # one map grid for every level: the union of the footprints at the lowest and highest
    at = [replace(scene, reference_height_m=float(h)) for h in heights]
    if like is not None:
        template = like.template
    else:
        template = _union_grid([grid_2a(s) for s in (at[0], at[-1])], inverse_step_px)
    window = _dem_window(dem, template.map_grid)
    ellipsoidal = _ellipsoidal(window)
    coordinates = _dem_coordinates(window, template.map_grid, DEM_COORD_STEP)
    best: tuple[Level3Geometry, dict[str, float]] | None = None
    while True:
        levels = tuple(grid_2a(s, template) for s in at)
        geom = Level3Geometry(
            levels, heights, window, ellipsoidal, coordinates, DEM_COORD_STEP, spacing, {}
        )
        err = geom.anchor_error(scene, b)
        if not err["n_points"]:  # no raw pixel lands on the DEM's terrain
            raise GeometryError(
                f"level 3: no pixel of scene {scene.cut.index} meets the terrain of the DEM "
                f"{dem.source or ''} (voids, or heights off the scene's)"
            )
        current = template.inverse_step[0]
        if err["max_px"] <= ANCHOR_TOLERANCE_PX or inverse_step_px or current <= 1 or like:
            return replace(geom, anchor_error_px=err)
        if best is not None and err["max_px"] >= ANCHOR_GAIN * best[1]["max_px"]:
            # halving no longer helps: the error is the heights' interpolation between the
            # levels (a DEM spanning kilometres), which no finer grid removes; the coarser
            # grid is kept, its error stored (a grid of 1 px would take tens of GB)
            return replace(best[0], anchor_error_px=best[1])
        if best is None or err["max_px"] < best[1]["max_px"]:
            best = (geom, err)
        half = max(1, current // 2)
        template = replace(
            template,
            inverse_rows=np.arange(0.0, template.map_grid.n_rows - 1 + half, half),
            inverse_cols=np.arange(0.0, template.map_grid.n_cols - 1 + half, half),
        )


def _union_grid(ends: list[Level2AGeometry], inverse_step_px: int) -> Level2AGeometry:
    """The map grid of level 3: the union of the 2A grids of the footprints at the lowest
    and highest heights, its inverse grid at ``inverse_step_px`` (by default 2A's)."""
    grids = [g.map_grid for g in ends]
    res = grids[0].pixel_size_m
    x_min = min(g.x_min_m for g in grids)
    y_max = max(g.y_max_m for g in grids)
    x_max = max(g.x_min_m + g.n_cols * res for g in grids)
    y_min = min(g.y_max_m - g.n_rows * res for g in grids)
    n_rows = round((y_max - y_min) / res)
    n_cols = round((x_max - x_min) / res)
    s_i, s_j = ends[0].inverse_step
    step_ij = inverse_step_px or max(s_i, s_j)
    return replace(
        ends[0],
        map_grid=MapGrid.north_up(grids[0].crs_wkt, x_min, y_max, res, n_rows, n_cols),
        inverse_rows=np.arange(0.0, n_rows - 1 + step_ij, step_ij),
        inverse_cols=np.arange(0.0, n_cols - 1 + step_ij, step_ij),
    )


def on_terrain(
    model: PushbroomModel,
    line: NDArray[np.float64],
    column: NDArray[np.float64],
    dem: Dem,
    h0_m: float,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_]]:
    """Where raw pixels meet the DEM (the direct method's step): latitude, longitude (rad),
    height, and whether the damped fixed point ``h ← DEM(ground(h))`` converged to 1 cm
    (slopes facing the sensor steeper than the view itself have no single answer)."""
    h = np.full(np.shape(line), float(h0_m))
    ok = np.zeros(h.shape, dtype=bool)
    for _ in range(60):
        g = model.image_to_ground(line, column, h)
        terrain = dem.heights(g.lat_rad, g.lon_rad)
        step = terrain - h
        ok = np.abs(step) < 0.01
        if np.all(ok | ~np.isfinite(step)):
            break
        h = np.where(np.isfinite(step), h + 0.7 * step, h)
    return g.lat_rad, g.lon_rad, h, ok & np.isfinite(terrain)


def direct_method_error(
    scene: SceneGeometry, geom: Level3Geometry, band: str | None = None, n_check: int = 41
) -> dict[str, float]:
    """Shu Ning's direct method at the indirect grid's density, for comparison: anchors on
    a regular grid of the raw image (as many raw pixels apart as the indirect anchors are
    output pixels apart), each put on the DEM by the rigorous model (:func:`on_terrain`),
    every raw pixel's map position bilinear between its cell's four anchors. Its error
    against the rigorous answer at a lattice of raw pixels off the anchors, in output
    pixels (the indirect grid's :meth:`Level3Geometry.anchor_error` is in raw pixels: both
    are about the pixel size apart)."""
    model = scene.models[band] if band is not None else scene.model
    step = float(geom.template.inverse_step[0])
    nl, nc = scene.cut.n_lines, model.n_columns
    al = np.arange(0.0, nl - 1 + step, step)
    ac = np.arange(0.0, nc - 1 + step, step)
    to_map = pyproj.Transformer.from_crs(
        "EPSG:4326", pyproj.CRS.from_wkt(geom.map_grid.crs_wkt), always_xy=True
    )
    h0 = float(np.mean(geom.heights_m))

    def located(line: NDArray, col: NDArray) -> tuple[NDArray, NDArray, NDArray]:
        lat, lon, _h, ok = on_terrain(model, line, col, geom.dem, h0)
        e, n = to_map.transform(np.degrees(lon), np.degrees(lat))
        return np.asarray(e), np.asarray(n), ok

    ll, cc = np.meshgrid(al, ac, indexing="ij")
    e_a, n_a, ok_a = located(ll.ravel(), cc.ravel())
    e_a, n_a = (np.where(ok_a, v, np.nan).reshape(ll.shape) for v in (e_a, n_a))
    cl, ccol = np.meshgrid(
        np.linspace(0.37, nl - 1.37, n_check), np.linspace(0.41, nc - 1.41, n_check), indexing="ij"
    )
    line, col = cl.ravel(), ccol.ravel()
    e, n, ok = located(line, col)
    e_d = bilinear_grid(al, ac, e_a, line, col)
    n_d = bilinear_grid(al, ac, n_a, line, col)
    d = (
        np.hypot(e_d - e, n_d - n)[ok & np.isfinite(e_d) & np.isfinite(n_d)]
        / geom.map_grid.pixel_size_m
    )
    return {
        "n_points": int(d.size),
        "rms_px": float(np.sqrt(np.mean(d**2))) if d.size else float("nan"),
        "max_px": float(d.max()) if d.size else float("nan"),
        "anchor_step_raw_px": step,
    }
