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

import numba as nb
import numpy as np
import pyproj
from numpy.typing import ArrayLike, NDArray

from levels.errors import GeometryError
from levels.geo.level1b import N_BREAKPOINTS
from levels.geo.polynomial import Poly2D
from levels.geo.scenes import SceneGeometry
from levels.geometry.model import PushbroomModel
from levels.geometry.sensor import LookAngleTable
from levels.quality import raw_error_stats

__all__ = ["INVERSE_METHODS", "Level2AGeometry", "bilinear_grid", "butting_columns",
           "level2a_geometry", "map_crs"]

INVERSE_METHODS = ("nearest4", "poly3", "poly4", "poly5")
#: SPOT 1–4 orbit for the Space Oblique Mercator: inclination and revolution period.
_SPOT_INCLINATION_DEG = 98.7
_SPOT_PERIOD_DAYS = 101.4 / 1440.0


def map_crs(kind: str, centre_lat_rad: float, centre_lon_rad: float,
            ascending_node_lon_rad: float | None = None) -> pyproj.CRS:
    """The map projection of a product.

    ``"utm"``: the UTM zone of the scene centre (WGS84, north or south); ``"som"``: the Space
    Oblique Mercator of the SPOT orbit (needs the longitude of the ascending node); anything
    else is handed to :meth:`pyproj.CRS.from_user_input` (``"EPSG:32721"``, a WKT …).
    """
    if kind == "utm":
        zone = int((np.degrees(centre_lon_rad) + 180.0) // 6.0) % 60 + 1
        return pyproj.CRS.from_epsg((32700 if centre_lat_rad < 0 else 32600) + zone)
    if kind == "som":
        if ascending_node_lon_rad is None:
            raise GeometryError("SOM needs the longitude of the ascending node")
        return pyproj.CRS.from_proj4(
            f"+proj=som +inc_angle={_SPOT_INCLINATION_DEG} +ps_rev={_SPOT_PERIOD_DAYS:.9f} "
            f"+asc_lon={np.degrees(ascending_node_lon_rad):.9f} +ellps=WGS84 +units=m +no_defs")
    try:
        return pyproj.CRS.from_user_input(kind)
    except pyproj.exceptions.CRSError as exc:
        raise GeometryError(f"map CRS {kind!r}: {exc}; use 'utm', 'som', an EPSG code or "
                            "a WKT") from None


@nb.njit(cache=True, nogil=True)
def _walk(gl, gc, gi, gj, ip, jp, a, b, u, v, b_lo, b_hi, max_moves):
    """Raw ``(L, C)`` of output point ``(ip, jp)``: Newton on the bilinear map of direct-grid
    cell ``(a, b)`` from local coordinates ``(u, v)``, moving to the neighbouring cell while
    they fall outside [0, 1]. Cells are kept within rows ``0 .. na − 2`` and columns
    ``b_lo .. b_hi − 1`` (a CCD segment's own columns); beyond them the edge cell is
    extrapolated. The walk moves one cell at a time: a butting cell is one pixel wide, and
    its bilinear map extrapolated far from it has spurious roots that a jump of several
    cells would take. Returns ``(L, C, a, b, u, v)``."""
    na = gi.shape[0]
    for _move in range(max_moves):
        for _it in range(6):
            i00, i01, i10, i11 = gi[a, b], gi[a, b + 1], gi[a + 1, b], gi[a + 1, b + 1]
            j00, j01, j10, j11 = gj[a, b], gj[a, b + 1], gj[a + 1, b], gj[a + 1, b + 1]
            ii = (1 - u) * ((1 - v) * i00 + v * i01) + u * ((1 - v) * i10 + v * i11)
            jj = (1 - u) * ((1 - v) * j00 + v * j01) + u * ((1 - v) * j10 + v * j11)
            a11 = (1 - v) * (i10 - i00) + v * (i11 - i01)
            a12 = (1 - u) * (i01 - i00) + u * (i11 - i10)
            a21 = (1 - v) * (j10 - j00) + v * (j11 - j01)
            a22 = (1 - u) * (j01 - j00) + u * (j11 - j10)
            det = a11 * a22 - a12 * a21
            ri, rj = ip - ii, jp - jj
            du = (a22 * ri - a12 * rj) / det
            dv = (-a21 * ri + a11 * rj) / det
            u += du
            v += dv
            if abs(du) + abs(dv) < 1e-7:
                break  # Newton's quadratic convergence: what remains is below 1e-14
        na_ = min(max(a + (1 if u >= 1.0 else (-1 if u < 0.0 else 0)), 0), na - 2)
        nb2 = min(max(b + (1 if v >= 1.0 else (-1 if v < 0.0 else 0)), b_lo), b_hi - 1)
        if na_ == a and nb2 == b:
            break
        u -= na_ - a
        v -= nb2 - b
        a, b = na_, nb2
    return gl[a] + u * (gl[a + 1] - gl[a]), gc[b] + v * (gc[b + 1] - gc[b]), a, b, u, v


@nb.njit(cache=True, nogil=True)
def _segment_line(gl, gc, gi, gj, ip, jp, line, a, b, u, v, b0, b1):
    """The line of segment ``b0 .. b1 − 1`` at output point ``(ip, jp)``, from the whole
    grid's walk (``line`` in cell ``(a, b)`` at ``(u, v)``): the same if that cell is the
    segment's, else a walk over the segment's cells from its nearest one."""
    if b0 <= b < b1:
        return line
    bs = min(max(b, b0), b1 - 1)
    return _walk(gl, gc, gi, gj, ip, jp, a, bs, u, v + b - bs, b0, b1,
                 gi.shape[0] + gi.shape[1])[0]


@nb.njit(cache=True, nogil=True)
def _invert_points(gl, gc, gi, gj, i_pts, j_pts, a0, b0, seg_b0, seg_b1, lines, col):
    """:func:`_walk` for scattered points, each from its own first-guess cell ``(a0, b0)``,
    over the whole grid (``col``) and over each segment's cells ``seg_b0[s] .. seg_b1[s] − 1``
    (``lines[s]``); a point whose whole-grid cell lies in the segment has the segment's
    answer already."""
    n_seg = lines.shape[0]
    na, nb_ = gi.shape
    for k in range(i_pts.size):
        line, c, a, b, u, v = _walk(gl, gc, gi, gj, i_pts[k], j_pts[k], a0[k], b0[k], 0.5, 0.5,
                                    0, nb_ - 1, na + nb_)
        col[k] = c
        for s in range(n_seg):
            lines[s, k] = _segment_line(gl, gc, gi, gj, i_pts[k], j_pts[k], line, a, b, u, v,
                                        seg_b0[s], seg_b1[s])


@nb.njit(cache=True, nogil=True)
def _invert_nodes(gl, gc, gi, gj, rows, cols, seg_b0, seg_b1, seg_lo, seg_hi, lines, col):
    """The inverse grid by :func:`_walk`, row by row, each node starting from the cell of
    the node before it, at the cell coordinates extrapolated from the two nodes before it:
    a step of the inverse grid is a fraction of a direct-grid cell, so a walk rarely moves
    and Newton starts close (a row's first node starts from the centre of the grid).
    Serial: a scene's grid takes milliseconds, and idle parallel threads would spin
    against BLAS.

    A segment's line is taken exactly (over its own columns, extrapolated beyond) at the
    nodes of every inverse-grid cell whose column range meets the raw columns that belong
    to the segment, ``[seg_lo[s], seg_hi[s])``: those are the nodes the 2A kernel's
    bilinear interpolation reads for it. Elsewhere the field holds the whole grid's line,
    the line of the CCD that does see there.
    """
    n_seg = lines.shape[0]
    na, nb_ = gi.shape
    nr, nc = rows.size, cols.size
    cell_a = np.empty((nr, nc), dtype=np.int64)
    cell_b = np.empty((nr, nc), dtype=np.int64)
    cell_u = np.empty((nr, nc))
    cell_v = np.empty((nr, nc))
    whole = np.empty((nr, nc))
    for r in range(nr):
        a, b, u, v = (na - 1) // 2, (nb_ - 1) // 2, 0.5, 0.5
        for c in range(nc):
            if c >= 2:  # linear prediction in global cell coordinates
                pu = 2.0 * (cell_a[r, c - 1] + cell_u[r, c - 1]) - (cell_a[r, c - 2]
                                                                  + cell_u[r, c - 2])
                pv = 2.0 * (cell_b[r, c - 1] + cell_v[r, c - 1]) - (cell_b[r, c - 2]
                                                                  + cell_v[r, c - 2])
                a = min(max(int(np.floor(pu)), 0), na - 2)
                b = min(max(int(np.floor(pv)), 0), nb_ - 2)
                u, v = pu - a, pv - b
            moves = na + nb_ if c == 0 else 16
            line, cc, a, b, u, v = _walk(gl, gc, gi, gj, rows[r], cols[c], a, b, u, v, 0,
                                         nb_ - 1, moves)
            whole[r, c], col[r, c] = line, cc
            cell_a[r, c], cell_b[r, c], cell_u[r, c], cell_v[r, c] = a, b, u, v
    need = np.zeros((n_seg, nr, nc), dtype=np.bool_)
    for r in range(nr - 1):
        for c in range(nc - 1):
            lo = min(min(col[r, c], col[r, c + 1]), min(col[r + 1, c], col[r + 1, c + 1]))
            hi = max(max(col[r, c], col[r, c + 1]), max(col[r + 1, c], col[r + 1, c + 1]))
            for s in range(n_seg):
                if lo < seg_hi[s] and hi >= seg_lo[s]:
                    need[s, r, c] = need[s, r, c + 1] = True
                    need[s, r + 1, c] = need[s, r + 1, c + 1] = True
    for r in range(nr):
        for s in range(n_seg):
            for c in range(nc):
                lines[s, r, c] = whole[r, c] if not need[s, r, c] else _segment_line(
                    gl, gc, gi, gj, rows[r], cols[c], whole[r, c], cell_a[r, c], cell_b[r, c],
                    cell_u[r, c], cell_v[r, c], seg_b0[s], seg_b1[s])


def _segment_cells(grid_column: NDArray[np.float64], segment_first_column: NDArray[np.float64]
                   ) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Direct-grid column indices of each segment's first and last detector: segment ``s``
    owns the cells ``first[s] .. last[s] − 1``. The cell across a butting gap, between the
    last detector of one CCD and the first of the next, belongs to neither."""
    ends = np.append(segment_first_column[1:] - 1, grid_column[-1])
    first = np.searchsorted(grid_column, segment_first_column)
    last = np.searchsorted(grid_column, ends)
    if not (np.all(grid_column[first] == segment_first_column)
            and np.all(grid_column[last] == ends)):
        raise GeometryError("the direct grid must hold both sides of every CCD butting")
    return first.astype(np.int64), last.astype(np.int64)


def _invert_scattered(gl: NDArray[np.float64], gc: NDArray[np.float64],
                      gi: NDArray[np.float64], gj: NDArray[np.float64],
                      segment_first_column: NDArray[np.float64], i: ArrayLike, j: ArrayLike,
                      first_guess: tuple[NDArray, NDArray]
                      ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Line per segment ``(segments, N)`` and column ``(N,)`` of scattered output points
    ``(I, J)``, from the four nearest direct-grid points: each point starts in the cell of
    its ``first_guess`` ``(L, C)`` and walks (:func:`_walk`); points beyond the grid are
    extrapolated from the edge cell."""
    i_a, j_a = (np.ascontiguousarray(x, dtype=np.float64).ravel()
                for x in np.broadcast_arrays(i, j))
    na, nb_ = gi.shape
    a = np.clip(np.searchsorted(gl, np.ravel(first_guess[0])) - 1, 0, na - 2)
    b = np.clip(np.searchsorted(gc, np.ravel(first_guess[1])) - 1, 0, nb_ - 2)
    seg_b0, seg_b1 = _segment_cells(gc, segment_first_column)
    lines = np.empty((segment_first_column.size, i_a.size))
    col = np.empty(i_a.size)
    _invert_points(np.asarray(gl, float), np.asarray(gc, float),
                   np.ascontiguousarray(gi, dtype=np.float64),
                   np.ascontiguousarray(gj, dtype=np.float64), i_a, j_a,
                   a.astype(np.int64), b.astype(np.int64), seg_b0, seg_b1, lines, col)
    return lines, col


@dataclass(frozen=True, eq=False)
class Level2AGeometry:
    """GEO for level 2A: map grid, direct grid, inverse polynomials and inverse grid.

    The raw image is split into column segments at the CCD butting (``segment_first_column``;
    one segment without butting): the raw line seen at a map point jumps across a butting,
    so the inverse grid holds one line field per segment (``inverse_line``, shape
    ``(segments, rows, cols)``), each smooth, and one column field (``inverse_column``).
    A pixel takes its line from the segment of the raw column it samples.
    """

    crs_wkt: str
    pixel_size_m: float
    x_min_m: float
    y_max_m: float
    n_rows: int
    n_cols: int
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
        if self.inverse_rows[0] != 0 or self.inverse_cols[0] != 0 or si != int(si) \
                or sj != int(sj):
            raise GeometryError("the inverse grid must start at 0 with integer steps")
        return int(si), int(sj)

    @property
    def geotransform(self) -> tuple[float, float, float, float, float, float]:
        """GDAL geotransform of the output grid (upper-left corner of the first pixel)."""
        return (self.x_min_m, self.pixel_size_m, 0.0, self.y_max_m, 0.0, -self.pixel_size_m)

    def map_of(self, i: ArrayLike, j: ArrayLike) -> tuple[NDArray[np.float64],
                                                          NDArray[np.float64]]:
        """Map coordinates (E, N) of output pixel coordinates."""
        return (self.x_min_m + (np.asarray(j, dtype=np.float64) + 0.5) * self.pixel_size_m,
                self.y_max_m - (np.asarray(i, dtype=np.float64) + 0.5) * self.pixel_size_m)

    def ij_of_map(self, e_m: ArrayLike, n_m: ArrayLike) -> tuple[NDArray[np.float64],
                                                                NDArray[np.float64]]:
        """Output pixel coordinates of map coordinates."""
        return ((self.y_max_m - np.asarray(n_m, dtype=np.float64)) / self.pixel_size_m - 0.5,
                (np.asarray(e_m, dtype=np.float64) - self.x_min_m) / self.pixel_size_m - 0.5)

    def segment_of(self, column: ArrayLike) -> NDArray[np.int64]:
        """Segment of (fractional) raw columns: a column belongs to the segment of its
        nearest detector."""
        c = np.floor(np.asarray(column, dtype=np.float64) + 0.5)
        return np.clip(np.searchsorted(self.segment_first_column, c, side="right") - 1, 0,
                       self.segment_first_column.size - 1)

    def _nodes(self, i: NDArray[np.float64], j: NDArray[np.float64], method: str
               ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Line per segment ``(segments, N)`` and column ``(N,)`` of output points."""
        if method == "nearest4":
            # first guesses from the cubic inverse: near enough for the walk between cells
            pl3, pc3 = self.inverse_polynomials[3]
            return _invert_scattered(self.grid_line, self.grid_column, self.grid_i,
                                     self.grid_j, self.segment_first_column, i, j,
                                     (pl3[0](i, j), pc3(i, j)))
        pl, pc = self.inverse_polynomials[_order(method)]
        return np.stack([p(i, j) for p in pl]), pc(i, j)

    def inverse_at(self, i: ArrayLike, j: ArrayLike, method: str | None = None
                   ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Raw ``(L, C)`` of output points by an inversion method, without the inverse grid."""
        i_a, j_a = np.broadcast_arrays(np.asarray(i, dtype=np.float64),
                                       np.asarray(j, dtype=np.float64))
        lines, col = self._nodes(i_a.ravel(), j_a.ravel(), method or self.method)
        line = np.take_along_axis(lines, self.segment_of(col)[None], 0)[0]
        return line.reshape(i_a.shape), col.reshape(i_a.shape)

    def raw_of(self, i: ArrayLike, j: ArrayLike) -> tuple[NDArray[np.float64],
                                                          NDArray[np.float64]]:
        """Raw ``(L, C)`` of output pixels through the inverse grid (what COR uses)."""
        i_a, j_a = np.broadcast_arrays(np.asarray(i, dtype=np.float64),
                                       np.asarray(j, dtype=np.float64))
        col = bilinear_grid(self.inverse_rows, self.inverse_cols, self.inverse_column, i_a, j_a)
        seg = self.segment_of(col)
        line = np.empty_like(col)
        for s in np.unique(seg):
            k = seg == s
            line[k] = bilinear_grid(self.inverse_rows, self.inverse_cols,
                                    self.inverse_line[s], i_a[k], j_a[k])
        return line, col

    def output_of(self, line: ArrayLike, column: ArrayLike, first_guess: tuple[NDArray, NDArray]
                  ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Output ``(I, J)`` where the inverse grid sends raw ``(L, C)``: where a raw pixel
        appears in the product. Newton from ``first_guess``, with the grid's Jacobian."""
        la, ca = (np.asarray(x, dtype=np.float64).ravel() for x in (line, column))
        i, j = (np.asarray(x, dtype=np.float64).ravel().copy() for x in first_guess)
        eps = 0.25
        for _ in range(6):
            lo, co = self.raw_of(i, j)
            li, ci = self.raw_of(i + eps, j)
            lj, cj = self.raw_of(i, j + eps)
            a11, a12 = (li - lo) / eps, (lj - lo) / eps
            a21, a22 = (ci - co) / eps, (cj - co) / eps
            det = a11 * a22 - a12 * a21
            rl, rc = la - lo, ca - co
            i = i + (a22 * rl - a12 * rc) / det
            j = j + (-a21 * rl + a11 * rc) / det
        return i, j

    def approximation_error(self, model: PushbroomModel, reference_height_m: float,
                            method: str | None = None, per_side: int = 61,
                            through_grid: bool = True) -> dict[str, float]:
        """How far an inversion puts output pixels from the rigorous model, in raw pixels.

        A lattice of output pixels is taken back to the ground (map → geodetic at the
        reference height) and into the raw image by the model's iteration; the same pixels
        go through the inversion (``method``, with or without the inverse grid's bilinear
        interpolation). Pixels outside the raw image are left out, and so are those whose
        exact column falls in a butting gap, between the last detector of one CCD and the
        first of the next: no detector sees there, and the model's answer is only the linear
        interpolation of the look-angle table across the gap.
        """
        i, j = np.meshgrid(np.linspace(0, self.n_rows - 1, per_side),
                           np.linspace(0, self.n_cols - 1, per_side), indexing="ij")
        i, j = i.ravel(), j.ravel()
        if through_grid:
            grid = self if method in (None, self.method) else self.with_inverse(method)
            la, ca = grid.raw_of(i, j)
        else:
            la, ca = self.inverse_at(i, j, method)
        inside = ((la >= 0) & (la <= self.n_raw_lines - 1) & (ca >= 0)
                  & (ca <= self.n_raw_columns - 1))
        e, n = self.map_of(i[inside], j[inside])
        to_geo = pyproj.Transformer.from_crs(pyproj.CRS.from_wkt(self.crs_wkt), "EPSG:4326",
                                             always_xy=True)
        lon, lat = to_geo.transform(e, n)
        exact = model.ground_to_image(np.radians(lat), np.radians(lon), reference_height_m,
                                      first_line=la[inside])
        gap = np.zeros(exact.column.size, dtype=bool)
        for first in self.segment_first_column[1:]:
            gap |= (exact.column > first - 1) & (exact.column < first)
        ok = exact.converged & ~gap
        return raw_error_stats((la[inside] - exact.line)[ok], (ca[inside] - exact.column)[ok])

    def with_inverse(self, method: str) -> Level2AGeometry:
        """The same geometry with the inverse grid computed by another method."""
        if method not in INVERSE_METHODS:
            raise GeometryError(f"inverse method {method!r}: expected one of {INVERSE_METHODS}")
        shape = (self.inverse_rows.size, self.inverse_cols.size)
        if method == "nearest4":
            lines = np.empty((self.segment_first_column.size, *shape))
            col = np.empty(shape)
            seg_b0, seg_b1 = _segment_cells(self.grid_column, self.segment_first_column)
            # the raw columns each segment's line serves: those its nearest detector is in
            seg_lo = np.append(-np.inf, self.segment_first_column[1:] - 0.5)
            seg_hi = np.append(self.segment_first_column[1:] - 0.5, np.inf)
            _invert_nodes(self.grid_line, self.grid_column, self.grid_i, self.grid_j,
                          np.asarray(self.inverse_rows, dtype=np.float64),
                          np.asarray(self.inverse_cols, dtype=np.float64),
                          seg_b0, seg_b1, seg_lo, seg_hi, lines, col)
        else:
            i, j = np.meshgrid(self.inverse_rows, self.inverse_cols, indexing="ij")
            lines, col = self._nodes(i.ravel(), j.ravel(), method)
            lines, col = lines.reshape(-1, *shape), col.reshape(shape)
        return Level2AGeometry(**{**self.__dict__, "method": method, "inverse_line": lines,
                                  "inverse_column": col})


def butting_columns(look: LookAngleTable) -> NDArray[np.float64]:
    """Columns on either side of each jump of the along-track look angle (the butting of
    the CCDs): a direct grid must hold both, or its bilinear cells smear the jump (half a
    7 µrad butting step is 0.29 px at nadir)."""
    d = np.abs(np.diff(look.psi_x_rad))
    typical = np.median(d)
    k = np.flatnonzero(d > 10.0 * typical + 1e-9)  # 1 nrad: far below any butting offset
    return np.union1d(look.column[k], look.column[k + 1])


def _order(method: str) -> int:
    if method not in INVERSE_METHODS[1:]:
        raise GeometryError(f"inverse method {method!r}: expected one of {INVERSE_METHODS}")
    return int(method[-1])


def bilinear_grid(rows: NDArray[np.float64], cols: NDArray[np.float64],
                  z: NDArray[np.float64], i: ArrayLike, j: ArrayLike) -> NDArray[np.float64]:
    """Bilinear interpolation of a field on a grid of integer steps from (0, 0), extrapolated
    at the far edges: the arithmetic of the 2A kernel, first along rows then columns, so that
    checks and products agree to the last bit."""
    i_a, j_a = np.broadcast_arrays(np.asarray(i, dtype=np.float64),
                                   np.asarray(j, dtype=np.float64))
    step_i, step_j = rows[1] - rows[0], cols[1] - cols[0]
    a = np.clip(np.floor(i_a / step_i).astype(np.int64), 0, rows.size - 2)
    b = np.clip(np.floor(j_a / step_j).astype(np.int64), 0, cols.size - 2)
    u = (i_a - a * step_i) * (1.0 / step_i)
    v = (j_a - b * step_j) * (1.0 / step_j)
    at_b = (1.0 - u) * z[a, b] + u * z[a + 1, b]
    at_b1 = (1.0 - u) * z[a, b + 1] + u * z[a + 1, b + 1]
    return (1.0 - v) * at_b + v * at_b1


def level2a_geometry(scene: SceneGeometry, pixel_size_m: float, crs: pyproj.CRS,
                     method: str = "nearest4", n_breakpoints: int = N_BREAKPOINTS,
                     inverse_step_px: int = 0, grid_rows: str = "attitude",
                     band: str | None = None, like: Level2AGeometry | None = None
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
    Columns are INPE's 61, plus both sides of each CCD butting (:func:`butting_columns`).
    """
    if method not in INVERSE_METHODS:
        raise GeometryError(f"inverse method {method!r}: expected one of {INVERSE_METHODS}")
    if grid_rows not in ("attitude", "regular"):
        raise GeometryError(f"grid_rows {grid_rows!r}: expected 'attitude' or 'regular'")
    model = scene.models[band] if band is not None else scene.model
    nl, nc = scene.cut.n_lines, model.n_columns
    gl = (scene.attitude_lines() if grid_rows == "attitude"
          else np.linspace(0.0, nl - 1.0, n_breakpoints))
    butting = butting_columns(model.look_angles)
    gc = np.union1d(np.linspace(0.0, nc - 1.0, n_breakpoints), butting)
    ll, cc = np.meshgrid(gl, gc, indexing="ij")
    g = model.image_to_ground(ll.ravel(), cc.ravel(), scene.reference_height_m)
    if not np.all(g.ok):
        raise GeometryError(f"level 2A: {np.count_nonzero(~g.ok)} direct-grid breakpoints of "
                            f"scene {scene.cut.index} not located")
    if like is not None:
        if like.pixel_size_m != float(pixel_size_m) or not pyproj.CRS.from_wkt(
                like.crs_wkt).equals(crs):
            raise GeometryError("level 2A: a shared map grid must have the same CRS and "
                                "pixel size")
        crs = pyproj.CRS.from_wkt(like.crs_wkt)
    to_map = pyproj.Transformer.from_crs("EPSG:4326", crs, always_xy=True)
    e, n = to_map.transform(np.degrees(g.lon_rad), np.degrees(g.lat_rad))
    e, n = np.asarray(e).reshape(ll.shape), np.asarray(n).reshape(ll.shape)
    res = float(pixel_size_m)
    if like is None:
        x_min = float(np.floor(e.min() / res) * res)
        y_max = float(np.ceil(n.max() / res) * res)
        n_cols = int(np.ceil((e.max() - x_min) / res))
        n_rows = int(np.ceil((y_max - n.min()) / res))
        step = inverse_step_px or max(1, round(max(n_rows, n_cols) / (n_breakpoints - 1) / 4))
        rows = np.arange(0.0, n_rows - 1 + step, step)
        cols = np.arange(0.0, n_cols - 1 + step, step)
    else:
        x_min, y_max, n_rows, n_cols = like.x_min_m, like.y_max_m, like.n_rows, like.n_cols
        rows, cols = like.inverse_rows, like.inverse_cols
    gi = (y_max - n) / res - 0.5
    gj = (e - x_min) / res - 0.5
    seg_first = np.concatenate([[0.0], butting[1::2]])
    # each segment's own grid columns, its first detector to its last
    segments = [slice(f, last + 1) for f, last in zip(*_segment_cells(gc, seg_first),
                                                       strict=True)]
    orders = (3, 4, 5)
    line_fits = [Poly2D.fit_orders(gi[:, k], gj[:, k], ll[:, k], orders) for k in segments]
    col_fits = Poly2D.fit_orders(gi, gj, cc, orders)
    polys = {o: (tuple(f[o] for f in line_fits), col_fits[o]) for o in orders}
    geom = Level2AGeometry(
        crs_wkt=crs.to_wkt(), pixel_size_m=res, x_min_m=x_min, y_max_m=y_max, n_rows=n_rows,
        n_cols=n_cols, grid_line=gl, grid_column=gc, grid_i=gi, grid_j=gj,
        segment_first_column=seg_first, inverse_polynomials=polys, method=method,
        inverse_rows=rows, inverse_cols=cols,
        inverse_line=np.empty((seg_first.size, rows.size, cols.size)),
        inverse_column=np.empty((rows.size, cols.size)), n_raw_lines=nl, n_raw_columns=nc)
    return geom.with_inverse(method)
