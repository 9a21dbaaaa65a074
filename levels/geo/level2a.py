"""Level 2A geometry: INPE's direct grid, its inversion, and the north-up map grid.

Paper ``004_…`` §3, in three steps:

1. **Direct grid.** The photogrammetric model over the reference surface for 61 × 61
   breakpoints regularly spread over the raw image gives ``(L, C, φ, λ)``; pyproj turns
   ``(φ, λ)`` into map coordinates (the UTM zone of the scene centre by default, SOM or any
   CRS offered), and these into output pixels ``(I, J)`` of a north-up grid at the nominal
   resolution. That sets up the direct relation ``(L, C) → (I, J)``.
2. **Inversion** on a grid of breakpoints regularly spread over the *corrected* image (the
   inverse grid), by one of:

   * ``"nearest4"``: from the four nearest direct-grid points, as INPE was researching: the
     direct-grid cell that holds ``(I, J)`` is found and its bilinear map inverted;
   * ``"poly3"``, ``"poly4"``, ``"poly5"``: ``L`` and ``C`` as polynomials of ``(I, J)`` of
     that order, least-squares fitted on the whole direct grid (INPE: "polynomials cannot
     represent high frequency distortions ... not reliable ... outside of the original
     grid"; :meth:`Level2AGeometry.approximation_error` measures both).
3. **Resampling** (``levels.cor.resample``) interpolates the inverse grid bilinearly at
   every output pixel and the raw image there.

Output pixel ``(I, J)`` (0-based, integers at pixel centres) has map coordinates
``E = x_min + (J + ½)·res``, ``N = y_max − (I + ½)·res``: the GDAL geotransform
``(x_min, res, 0, y_max, 0, −res)``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import pyproj
from numpy.typing import ArrayLike, NDArray

from levels.choices import GridColumns, GridRows, InverseMethod
from levels.errors import GeometryError, ProductError
from levels.geo.inverse_grid import (
    bilinear_grid,
    invert_by_newton,
    invert_nodes,
    invert_scattered,
    segment_cells,
)
from levels.geo.level1b import N_BREAKPOINTS
from levels.geo.maps import MapGrid, map_crs
from levels.geo.misfit import raw_error_stats
from levels.geo.polynomial import Poly2D
from levels.geo.scenes import SceneGeometry
from levels.geometry.model import PushbroomModel
from levels.geometry.sensor import butting_columns
from levels.threads import one_blas_thread

__all__ = [
    "INVERSE_METHODS",
    "Level2AGeometry",
    "bilinear_grid",
    "butting_columns",
    "level2a_geometry",
    "map_crs",
]

INVERSE_METHODS = tuple(str(m) for m in InverseMethod)


@dataclass(frozen=True, eq=False)
class Level2AGeometry:
    """GEO for level 2A: map grid, direct grid, inverse polynomials and inverse grid.

    The raw image is split into column segments at the CCD butting (``segment_first_column``;
    one segment without butting): the raw line seen at a map point jumps across a butting,
    so the inverse grid holds one line field per segment (``inverse_line``, shape
    ``(segments, rows, cols)``), each smooth, and one column field (``inverse_column``).
    A pixel takes its line from the segment of the raw column it samples. The output grid
    (CRS, geotransform, shape) is ``map_grid``.
    """

    map_grid: MapGrid
    grid_line: NDArray[np.float64]
    grid_column: NDArray[np.float64]
    grid_i: NDArray[np.float64]
    grid_j: NDArray[np.float64]
    segment_first_column: NDArray[np.float64]
    inverse_polynomials: dict[int, tuple[tuple[Poly2D, ...], Poly2D]]
    method: str
    inverse_rows: NDArray[np.float64]
    inverse_cols: NDArray[np.float64]
    inverse_line: NDArray[np.float64]
    inverse_column: NDArray[np.float64]
    n_raw_lines: int
    n_raw_columns: int

    @property
    def inverse_step(self) -> tuple[int, int]:
        """Spacing of the inverse grid in output rows and columns (integers, from 0)."""
        si = self.inverse_rows[1] - self.inverse_rows[0]
        sj = self.inverse_cols[1] - self.inverse_cols[0]
        if self.inverse_rows[0] != 0 or self.inverse_cols[0] != 0 or si != int(si) or sj != int(sj):
            raise GeometryError("the inverse grid must start at 0 with integer steps")
        return int(si), int(sj)

    def segment_of(self, column: ArrayLike) -> NDArray[np.int64]:
        """Segment of (fractional) raw columns: a column belongs to the segment of its
        nearest detector."""
        c = np.floor(np.asarray(column, dtype=np.float64) + 0.5)
        return np.clip(
            np.searchsorted(self.segment_first_column, c, side="right") - 1,
            0,
            self.segment_first_column.size - 1,
        )

    def _nodes(
        self, i: NDArray[np.float64], j: NDArray[np.float64], method: str
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Line per segment ``(segments, N)`` and column ``(N,)`` of output points."""
        if method == "nearest4":
            # first guesses from the cubic inverse: near enough for the walk between cells
            pl3, pc3 = self.inverse_polynomials[3]
            return invert_scattered(
                self.grid_line,
                self.grid_column,
                self.grid_i,
                self.grid_j,
                self.segment_first_column,
                i,
                j,
                (pl3[0](i, j), pc3(i, j)),
            )
        pl, pc = self.inverse_polynomials[_order(method)]
        return np.stack([p(i, j) for p in pl]), pc(i, j)

    def inverse_at(
        self, i: ArrayLike, j: ArrayLike, method: str | None = None
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Raw ``(L, C)`` of output points by an inversion method, without the inverse grid."""
        i_a, j_a = np.broadcast_arrays(
            np.asarray(i, dtype=np.float64), np.asarray(j, dtype=np.float64)
        )
        lines, col = self._nodes(i_a.ravel(), j_a.ravel(), method or self.method)
        line = np.take_along_axis(lines, self.segment_of(col)[None], 0)[0]
        return line.reshape(i_a.shape), col.reshape(i_a.shape)

    def raw_of(self, i: ArrayLike, j: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Raw ``(L, C)`` of output pixels through the inverse grid (what COR uses)."""
        i_a, j_a = np.broadcast_arrays(
            np.asarray(i, dtype=np.float64), np.asarray(j, dtype=np.float64)
        )
        col = bilinear_grid(self.inverse_rows, self.inverse_cols, self.inverse_column, i_a, j_a)
        seg = self.segment_of(col)
        line = np.empty_like(col)
        for s in np.unique(seg):
            k = seg == s
            line[k] = bilinear_grid(
                self.inverse_rows, self.inverse_cols, self.inverse_line[s], i_a[k], j_a[k]
            )
        return line, col

    def output_of(
        self, line: ArrayLike, column: ArrayLike, first_guess: tuple[NDArray, NDArray]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Output ``(I, J)`` where the inverse grid sends raw ``(L, C)``: where a raw pixel
        appears in the product. Newton from ``first_guess``, with the grid's Jacobian."""
        return invert_by_newton(self.raw_of, line, column, first_guess, 6)

    def approximation_error(
        self,
        model: PushbroomModel,
        reference_height_m: float,
        method: str | None = None,
        per_side: int = 61,
        through_grid: bool = True,
    ) -> dict[str, float]:
        """How far an inversion puts output pixels from the rigorous model, in raw pixels.

        A lattice of output pixels is taken back to the ground (map → geodetic at the
        reference height) and into the raw image by the model's iteration; the same pixels
        go through the inversion (``method``, with or without the inverse grid's bilinear
        interpolation). Pixels outside the raw image are left out, and so are those whose
        exact column falls in a butting gap, between the last detector of one CCD and the
        first of the next: no detector sees there, and the model's answer is only the linear
        interpolation of the look-angle table across the gap.
        """
        lattice_i, lattice_j = np.meshgrid(
            np.linspace(0, self.map_grid.n_rows - 1, per_side),
            np.linspace(0, self.map_grid.n_cols - 1, per_side),
            indexing="ij",
        )
        i, j = lattice_i.ravel(), lattice_j.ravel()
        if through_grid:
            geom = self if method in (None, self.method) else self.with_inverse(method)
            la, ca = geom.raw_of(i, j)
        else:
            la, ca = self.inverse_at(i, j, method)
        inside = (
            (la >= 0) & (la <= self.n_raw_lines - 1) & (ca >= 0) & (ca <= self.n_raw_columns - 1)
        )
        e, n = self.map_grid.map_of(i[inside], j[inside])
        to_geo = pyproj.Transformer.from_crs(
            pyproj.CRS.from_wkt(self.map_grid.crs_wkt), "EPSG:4326", always_xy=True
        )
        lon, lat = to_geo.transform(e, n)
        exact = model.ground_to_image(
            np.radians(lat), np.radians(lon), reference_height_m, first_line=la[inside]
        )
        gap = np.zeros(exact.column.size, dtype=bool)
        for first in butting_columns(model.look_angles)[1::2]:  # whatever the grid knows
            gap |= (exact.column > first - 1) & (exact.column < first)
        ok = exact.converged & ~gap
        return raw_error_stats((la[inside] - exact.line)[ok], (ca[inside] - exact.column)[ok])

    def raw_line_span(self, row: float | None = None) -> tuple[float, float]:
        """Raw lines and raw columns one output row reads (the middle row by default),
        over the pixels that fall inside the raw image: the window of raw lines COR's
        north-up resampling must hold (INPE: 950 in P, 475 in XS at Cuiabá, paper
        ``004_…``); their ratio is the tangent of the raw lines' azimuth on the map grid."""
        j = np.arange(0.0, self.map_grid.n_cols)
        i = np.full(j.size, self.map_grid.n_rows / 2 if row is None else float(row))
        line, col = self.raw_of(i, j)
        inside = (
            (col >= 0)
            & (col <= self.n_raw_columns - 1)
            & (line >= 0)
            & (line <= self.n_raw_lines - 1)
        )
        if not inside.any():
            return 0.0, 0.0
        return float(np.ptp(line[inside])), float(np.ptp(col[inside]))

    @staticmethod
    def product_tree(bands: dict[str, Level2AGeometry]) -> dict[str, object]:
        """The ``geometry/level_2a`` tree of a product whose bands have these geometries
        (they share the first band's map grid; ``docs/products.md``)."""
        g = next(iter(bands.values()))
        return {
            "crs_wkt": g.map_grid.crs_wkt,
            "geotransform": np.asarray(g.map_grid.geotransform),
            "pixel_size_m": g.map_grid.pixel_size_m,
            "inverse_method": g.method,
            "n_rows": g.map_grid.n_rows,
            "n_cols": g.map_grid.n_cols,
            "n_raw_lines": g.n_raw_lines,
            "n_raw_columns": g.n_raw_columns,
            "bands": {b: band._band_tree() for b, band in bands.items()},
        }

    def _band_tree(self) -> dict[str, object]:
        polys = {
            f"poly{o}": {"line": np.stack([p.as_array() for p in pl]), "column": pc.as_array()}
            for o, (pl, pc) in self.inverse_polynomials.items()
        }
        return {
            "direct_grid": {
                "line": self.grid_line,
                "column": self.grid_column,
                "i": self.grid_i,
                "j": self.grid_j,
            },
            "segment_first_column": self.segment_first_column,
            "inverse_grid": {
                "rows": self.inverse_rows,
                "cols": self.inverse_cols,
                "line": self.inverse_line,
                "column": self.inverse_column,
            },
            "inverse_polynomials": polys,
        }

    @classmethod
    def from_tree(cls, tree: dict[str, Any], band: str | None = None) -> Level2AGeometry:
        """The geometry of ``band`` (the first by default) from a product's
        ``geometry/level_2a`` tree; :class:`ProductError` names what is missing or bad."""
        try:
            bands = tree["bands"]
            b = bands[band if band is not None else next(iter(bands))]
            gt = [float(x) for x in np.asarray(tree["geotransform"]).ravel()]
            if len(gt) != 6 or gt[2] != 0.0 or gt[4] != 0.0 or gt[1] <= 0 or gt[5] != -gt[1]:
                raise ProductError(
                    f"level 2A geotransform {gt}: expected a north-up grid "
                    "(x_min, res, 0, y_max, 0, -res)"
                )
            pyproj.CRS.from_wkt(str(tree["crs_wkt"]))
            polys = {}
            for name, p in b["inverse_polynomials"].items():
                lines = tuple(Poly2D.from_array(a) for a in np.atleast_2d(p["line"]))
                polys[int(name.removeprefix("poly"))] = (lines, Poly2D.from_array(p["column"]))
            d, inv = b["direct_grid"], b["inverse_grid"]
            grid = MapGrid.north_up(
                str(tree["crs_wkt"]),
                gt[0],
                gt[3],
                float(tree["pixel_size_m"]),
                int(tree["n_rows"]),
                int(tree["n_cols"]),
            )
            return cls(
                map_grid=grid,
                grid_line=d["line"],
                grid_column=d["column"],
                grid_i=d["i"],
                grid_j=d["j"],
                segment_first_column=b["segment_first_column"],
                inverse_polynomials=polys,
                method=str(tree["inverse_method"]),
                inverse_rows=inv["rows"],
                inverse_cols=inv["cols"],
                inverse_line=inv["line"],
                inverse_column=inv["column"],
                n_raw_lines=int(tree["n_raw_lines"]),
                n_raw_columns=int(tree["n_raw_columns"]),
            )
        except (
            KeyError,
            TypeError,
            ValueError,
            StopIteration,
            GeometryError,
            pyproj.exceptions.CRSError,
        ) as exc:
            if isinstance(exc, ProductError):
                raise
            raise ProductError(
                f"level 2A geometry tree is incomplete or damaged ({type(exc).__name__}: {exc})"
            ) from None

    def with_inverse(self, method: str) -> Level2AGeometry:
        """The same geometry with the inverse grid computed by another method."""
        if method not in INVERSE_METHODS:
            raise GeometryError(f"inverse method {method!r}: expected one of {INVERSE_METHODS}")
        shape = (self.inverse_rows.size, self.inverse_cols.size)
        if method == "nearest4":
            lines = np.empty((self.segment_first_column.size, *shape))
            col = np.empty(shape)
            seg_b0, seg_b1 = segment_cells(self.grid_column, self.segment_first_column)
            # the raw columns each segment's line serves: those its nearest detector is in
            seg_lo = np.append(-np.inf, self.segment_first_column[1:] - 0.5)
            seg_hi = np.append(self.segment_first_column[1:] - 0.5, np.inf)
            invert_nodes(
                self.grid_line,
                self.grid_column,
                self.grid_i,
                self.grid_j,
                np.asarray(self.inverse_rows, dtype=np.float64),
                np.asarray(self.inverse_cols, dtype=np.float64),
                seg_b0,
                seg_b1,
                seg_lo,
                seg_hi,
                lines,
                col,
            )
        else:
            i, j = np.meshgrid(self.inverse_rows, self.inverse_cols, indexing="ij")
            lines, col = self._nodes(i.ravel(), j.ravel(), method)
            lines, col = lines.reshape(-1, *shape), col.reshape(shape)
        return Level2AGeometry(
            **{**self.__dict__, "method": method, "inverse_line": lines, "inverse_column": col}
        )


def _order(method: str) -> int:
    if method not in INVERSE_METHODS[1:]:
        raise GeometryError(f"inverse method {method!r}: expected one of {INVERSE_METHODS}")
    return int(method[-1])


@one_blas_thread
def level2a_geometry(
    scene: SceneGeometry,
    pixel_size_m: float,
    crs: pyproj.CRS,
    method: str = "nearest4",
    n_breakpoints: int = N_BREAKPOINTS,
    inverse_step_px: int = 0,
    grid_rows: str = "attitude",
    band: str | None = None,
    like: Level2AGeometry | None = None,
    grid_columns: str = "butting",
) -> Level2AGeometry:
    """GEO for level 2A (module docstring).

    Parameters
    ----------
    n_breakpoints
        Breakpoints per side of the direct grid (61: INPE).
    inverse_step_px
        Spacing of the inverse grid in output pixels; by default a quarter of the direct
        grid's spacing (the inverse grid only costs a lookup in the kernel).
    grid_rows
        ``"regular"``: INPE's 61 rows regularly spaced. ``"attitude"``: one row at each
        attitude sample of the scene, where the model's attitude (linear between the
        samples) bends, plus the first and last line; with Westin's rough pitch drift the
        regular rows miss those bends by up to 0.06 px at nadir.
    band
        The band whose model is gridded (the first by default).
    like
        The geometry of another band of the scene: its map grid (CRS, extent, inverse-grid
        nodes) is shared, so that the XS bands of a product are registered on one grid,
        each through its own direct and inverse grids.
    grid_columns
        ``"butting"``: INPE's 61 columns plus both sides of each CCD butting
        (:func:`butting_columns`), and one inverse line field per butting segment.
        ``"regular"``: INPE's 61 columns only, one field for the whole line: with
        ``grid_rows = "regular"`` this is INPE's exact 61 × 61 configuration, whose bilinear
        cells smear the along-track jump at each butting.
    """
    _check_choices(method, grid_rows, grid_columns)
    model = scene.models[band] if band is not None else scene.model
    nl, nc = scene.cut.n_lines, model.n_columns
    gl, gc, butting = _grid_lines_columns(scene, model, n_breakpoints, grid_rows, grid_columns)
    ll, cc = np.meshgrid(gl, gc, indexing="ij")
    crs = _shared_crs(crs, pixel_size_m, like)
    e, n = _direct_grid_on_map(scene, model, ll, cc, crs)
    res = float(pixel_size_m)
    x_min, y_max, n_rows, n_cols, rows, cols = _map_extent(
        e, n, res, like, inverse_step_px, n_breakpoints
    )
    gi = (y_max - n) / res - 0.5
    gj = (e - x_min) / res - 0.5
    seg_first = np.concatenate([[0.0], butting[1::2]])
    polys = _inverse_polynomials(gi, gj, ll, cc, gc, seg_first)
    geom = Level2AGeometry(
        map_grid=MapGrid.north_up(crs.to_wkt(), x_min, y_max, res, n_rows, n_cols),
        grid_line=gl,
        grid_column=gc,
        grid_i=gi,
        grid_j=gj,
        segment_first_column=seg_first,
        inverse_polynomials=polys,
        method=method,
        inverse_rows=rows,
        inverse_cols=cols,
        inverse_line=np.empty((seg_first.size, rows.size, cols.size)),
        inverse_column=np.empty((rows.size, cols.size)),
        n_raw_lines=nl,
        n_raw_columns=nc,
    )
    return geom.with_inverse(method)


def _check_choices(method: str, grid_rows: str, grid_columns: str) -> None:
    """:class:`GeometryError` naming a choice this module does not know."""
    if method not in INVERSE_METHODS:
        raise GeometryError(f"inverse method {method!r}: expected one of {INVERSE_METHODS}")
    if grid_rows not in tuple(GridRows):
        raise GeometryError(f"grid_rows {grid_rows!r}: expected 'attitude' or 'regular'")
    if grid_columns not in tuple(GridColumns):
        raise GeometryError(f"grid_columns {grid_columns!r}: expected 'butting' or 'regular'")


def _inverse_polynomials(
    gi: NDArray[np.float64],
    gj: NDArray[np.float64],
    ll: NDArray[np.float64],
    cc: NDArray[np.float64],
    gc: NDArray[np.float64],
    seg_first: NDArray[np.float64],
) -> dict[int, tuple[tuple[Poly2D, ...], Poly2D]]:
    """The inverse polynomials of orders 3 to 5 through the direct grid's output pixels
    ``gi``, ``gj``: the raw line per butting segment (each on its own grid columns, its
    first detector to its last), the raw column over the whole line."""
    segments = [slice(f, last + 1) for f, last in zip(*segment_cells(gc, seg_first), strict=True)]
    orders = (3, 4, 5)
    line_fits = [Poly2D.fit_orders(gi[:, k], gj[:, k], ll[:, k], orders) for k in segments]
    col_fits = Poly2D.fit_orders(gi, gj, cc, orders)
    return {o: (tuple(f[o] for f in line_fits), col_fits[o]) for o in orders}


def _grid_lines_columns(
    scene: SceneGeometry,
    model: PushbroomModel,
    n_breakpoints: int,
    grid_rows: str,
    grid_columns: str,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """The direct grid's raw lines and columns, and the butting columns among these."""
    nl, nc = scene.cut.n_lines, model.n_columns
    gl = (
        scene.attitude_lines()
        if grid_rows == "attitude"
        else np.linspace(0.0, nl - 1.0, n_breakpoints)
    )
    butting = butting_columns(model.look_angles) if grid_columns == "butting" else np.zeros(0)
    gc = np.union1d(np.linspace(0.0, nc - 1.0, n_breakpoints), butting)
    return gl, gc, butting


def _direct_grid_on_map(
    scene: SceneGeometry,
    model: PushbroomModel,
    ll: NDArray[np.float64],
    cc: NDArray[np.float64],
    crs: pyproj.CRS,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The direct grid's raw pixels ``ll``, ``cc`` located at the reference height and
    projected: their map coordinates (E, N), in the grid's shape."""
    g = model.image_to_ground(ll.ravel(), cc.ravel(), scene.reference_height_m)
    if not np.all(g.ok):
        raise GeometryError(
            f"level 2A: {np.count_nonzero(~g.ok)} direct-grid breakpoints of "
            f"scene {scene.cut.index} not located"
        )
    to_map = pyproj.Transformer.from_crs("EPSG:4326", crs, always_xy=True)
    e, n = to_map.transform(np.degrees(g.lon_rad), np.degrees(g.lat_rad))
    return np.asarray(e).reshape(ll.shape), np.asarray(n).reshape(ll.shape)


def _shared_crs(crs: pyproj.CRS, pixel_size_m: float, like: Level2AGeometry | None) -> pyproj.CRS:
    """The map CRS: ``like``'s when a band shares another's grid (which must then have the
    same CRS and pixel size)."""
    if like is None:
        return crs
    shared = pyproj.CRS.from_wkt(like.map_grid.crs_wkt)
    if like.map_grid.pixel_size_m != float(pixel_size_m) or not shared.equals(crs):
        raise GeometryError("level 2A: a shared map grid must have the same CRS and pixel size")
    return shared


def _map_extent(
    e: NDArray[np.float64],
    n: NDArray[np.float64],
    res: float,
    like: Level2AGeometry | None,
    inverse_step_px: int,
    n_breakpoints: int,
) -> tuple[float, float, int, int, NDArray[np.float64], NDArray[np.float64]]:
    """The output grid over the direct grid's map points ``e``, ``n`` (its upper-left
    corner on whole pixels, its size) and the inverse grid's rows and columns; ``like``'s
    when the grid is shared."""
    if like is not None:
        g = like.map_grid
        return g.x_min_m, g.y_max_m, g.n_rows, g.n_cols, like.inverse_rows, like.inverse_cols
    x_min = float(np.floor(e.min() / res) * res)
    y_max = float(np.ceil(n.max() / res) * res)
    n_cols = int(np.ceil((e.max() - x_min) / res))
    n_rows = int(np.ceil((y_max - n.min()) / res))
    step = inverse_step_px or max(1, round(max(n_rows, n_cols) / (n_breakpoints - 1) / 4))
    rows = np.arange(0.0, n_rows - 1 + step, step)
    cols = np.arange(0.0, n_cols - 1 + step, step)
    return x_min, y_max, n_rows, n_cols, rows, cols
