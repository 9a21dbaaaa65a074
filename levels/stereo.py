"""Stereo: a DEM from two overlapping scenes of different passes (PHOTOMOD, paper ``003_…``),
on their adjusted models (level 2 of a block, :mod:`levels.adjust`).

1. **Epipolar grid from the rigorous model.** Each scene's raw image is resampled onto one
   grid on the plane at the pair's reference height ``h0`` (both level 2s' own), turned so
   that its rows are epipolar lines: a ground point at height ``h`` appears in a scene's
   map image at ``h0`` moved by ``(h − h0)·a`` along its view's horizontal tilt ``a``
   (metres per metre), so between the two by ``(h − h0)·(a_b − a_a)``: the grid's ``u``
   axis is the direction of ``a_b − a_a``, and a point's images differ only in ``u``, by
   the disparity ``d = (h − h0)·|a_b − a_a| / pixel``. ``a`` is measured through the model
   (ground → raw → plane) over the scene; what ``a`` turns across it is the *epipolar
   error* (the ``v``-parallax over the height range, pixels), stored with the pair. The grid
   reaches the raw image through each level 2's inverse grid (the adjusted model at
   ``h0``, :class:`~levels.geo.level2a.Level2AGeometry`), sampled at nodes every
   ``NODE_STEP_PX`` (a CCD segment's lines apart), and both images are resampled with the
   COR kernel (:func:`levels.cor.epipolar.resample_epipolar`): the 2A arithmetic, the raw
   image read once.
2. **Dense matching** by OpenCV's semi-global matching (``StereoSGBM``, Hirschmüller 2008)
   over the disparity range the pair's tie points give, its uniqueness and left–right
   checks and speckle filter; then each pixel's disparity refined to a fraction of a pixel
   by least-squares matching in a ``REFINE_WINDOW_PX`` window (Lucas–Kanade along the row,
   :func:`levels.cor.epipolar.window_solve`): SGBM's 1/16 px parabola is biased toward
   whole pixels ("pixel locking"), the least-squares solution is not. The window is warped
   by each of its pixels' own disparity and fits the disparity as a plane (its value at
   the centre, its two slopes), an offset and a shift across the row (the ``v``-parallax
   the grid leaves): a window that solved for one shift gave the mean of its pixels'
   disparities weighted by their texture, off on every slope (full P pair: 0.34 → 0.22 px
   RMS, docs/stereo.md). Its a posteriori σ (Förstner: the residual variance times the
   shift's term of the inverse normal matrix) is each pixel's matching σ. A pixel is
   refused when SGBM found no unique match, the refinement moved it more than
   ``MAX_REFINE_PX`` or failed, its window is flat, or its σ exceeds ``MAX_SIGMA_PX``.
3. **Triangulation** by the middle of the common perpendicular of the two lines of sight
   (PHOTOMOD), the miss kept per point.
4. **Gridding** onto a north-up map grid of ``cell_px`` pixels: the mean of the points in
   each cell, their count, and the predicted σ of the mean (the points' matching σ times
   the metres of height per pixel of disparity, reduced by the number of independent
   windows in the cell); cells without a point are holes (NaN), never filled.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Any

import numba as nb
import numpy as np
import pyproj
from numpy.typing import NDArray

from levels.choices import Level
from levels.cor.epipolar import resample_epipolar, shift_rows, window_solve
from levels.errors import GeometryError
from levels.geo.inverse_grid import bilinear_grid
from levels.geo.level2a import Level2AGeometry
from levels.geo.maps import MapGrid
from levels.geometry.ellipsoid import WGS84
from levels.geometry.model import PushbroomModel
from levels.readers.gcp import ControlPointSet
from levels.threads import over_blocks

_log = logging.getLogger(__name__)

__all__ = [
    "MAX_REFINE_PX",
    "MAX_SIGMA_PX",
    "NODE_STEP_PX",
    "REFINE_WINDOW_PX",
    "Disparity",
    "EpipolarPair",
    "StereoDem",
    "StereoView",
    "blunder_cells",
    "closest_approach",
    "dem_grid",
    "epipolar_pair",
    "grid_points",
    "match",
    "stereo_dem",
    "triangulate",
]

#: Spacing of the epipolar grid's nodes (pixels): the model through level 2's inverse grid
#: there, bilinearly between (its approximation error is stored with the pair).
NODE_STEP_PX = 16
#: Height span over which the disparity direction and the epipolar error are measured (m).
TILT_SPAN_M = 1000.0
#: Side of the least-squares refinement's window (pixels, odd).
REFINE_WINDOW_PX = 15
#: Refinement iterations, and how far they may move SGBM's disparity (pixels).
REFINE_ITERATIONS = 4
MAX_REFINE_PX = 1.0
#: The largest matching σ kept (pixels): a window that cannot tell its match from the next
#: pixel's (full P pair: the 0.01 % of pixels above it were 24 % of the squared error; the
#: reduced pair's textureless patches, whole windows at 100 m, sit between 0.5 and 1 px).
MAX_SIGMA_PX = 1.0
#: SGBM's block (pixels, odd), smoothness penalties per 8-bit grey level and block pixel,
#: uniqueness (%), left–right tolerance (px), speckle filter (pixels, disparity range).
SGBM_BLOCK_PX = 5
SGBM_P1, SGBM_P2 = 8, 32
SGBM_UNIQUENESS = 10
SGBM_LR_PX = 1
SGBM_SPECKLE_PX, SGBM_SPECKLE_RANGE = 100, 2
#: Margin around the tie points' disparity range (pixels, each side).
DISPARITY_MARGIN_PX = 8.0
#: Lowest gradient energy of a refinement window (counts² per pixel): flatter is refused.
MIN_GRADIENT = 0.2
#: Points triangulated at once (memory: about 1 kB each in flight).
_CHUNK = 1 << 20


@dataclass(frozen=True, eq=False)
class StereoView:
    """One scene of a pair: its raw image (level 1A, NaN where not valid), the adjusted
    model and level 2's geometry back to raw (its inverse grid at the reference height)."""

    name: str
    scene: int
    image: NDArray[np.float32]
    model: PushbroomModel
    geometry: Level2AGeometry
    reference_height_m: float
    first_line: int = 0  # the L0 row of the scene's line 0 (tie-point files count L0 rows)
    time_utc: str = ""  # the scene's centre time (ISO 8601, UTC)

    @classmethod
    def of_products(cls, level2: Any, level1a: Any, band: str | None = None) -> StereoView:
        """The view of a scene from its level 2 product (the adjusted model and grids) and
        its level 1A (the raw pixels)."""
        from levels.geo.scenes import models_of_tree

        if level2.level != Level.L2 or level1a.level != Level.L1A:
            raise GeometryError(
                f"a stereo view is made of a level 2 and a level 1A, got {level2.level} and "
                f"{level1a.level}"
            )
        name = band or next(iter(level2.bands))
        one = level1a.bands[name]
        image = np.where(one.valid, one.image.astype(np.float32), np.float32(np.nan))
        epoch, models = models_of_tree(level2.geometry)
        geom = Level2AGeometry.from_tree(level2.geometry["level_2a"], name)
        if image.shape != (geom.n_raw_lines, geom.n_raw_columns):
            raise GeometryError(
                f"the 1A image {image.shape} is not the raw image of the level 2 "
                f"({geom.n_raw_lines}, {geom.n_raw_columns}): not the same scene"
            )
        return cls(
            name=str(level2.attrs.get("name", "")),
            scene=int(level2.attrs.get("scene_index", 0)),
            image=image,
            model=models[name],
            geometry=geom,
            reference_height_m=float(level2.geometry["reference_height_m"]),
            first_line=int(level2.geometry["scene"]["first_line"]),
            time_utc=str(epoch.utc(np.array([float(level2.geometry["scene"]["t_centre_s"])]))[0]),
        )

    def ground_to_plane(
        self, lat: NDArray, lon: NDArray, h: NDArray, to_map: pyproj.Transformer
    ) -> tuple[NDArray, NDArray, NDArray]:
        """Where ground points appear on the map plane at the reference height (x, y, m),
        through the model: raw pixel, then its line of sight met with the plane; and the
        raw line and column."""
        img = self.model.ground_to_image(lat, lon, h)
        on = self.model.image_to_ground(img.line, img.column, self.reference_height_m)
        x, y = to_map.transform(np.degrees(on.lon_rad), np.degrees(on.lat_rad))
        return np.asarray(x), np.asarray(y), img.line


@dataclass(frozen=True)
class EpipolarFrame:
    """The epipolar grid on the map plane: pixel ``(v, u)`` (row, column) is at map
    ``origin + pixel·(u·ex + v·ey)``; ``ex`` the disparity direction."""

    crs_wkt: str
    origin_m: tuple[float, float]
    ex: tuple[float, float]
    pixel_m: float
    shape: tuple[int, int]

    @property
    def ey(self) -> tuple[float, float]:
        return (self.ex[1], -self.ex[0])  # rows go "down" the image, as map rows do

    def map_of(self, u: NDArray, v: NDArray) -> tuple[NDArray, NDArray]:
        (x0, y0), (ax, ay), (bx, by) = self.origin_m, self.ex, self.ey
        return x0 + self.pixel_m * (u * ax + v * bx), y0 + self.pixel_m * (u * ay + v * by)

    def uv_of(self, x: NDArray, y: NDArray) -> tuple[NDArray, NDArray]:
        dx, dy = (np.asarray(x) - self.origin_m[0]), (np.asarray(y) - self.origin_m[1])
        (ax, ay), (bx, by) = self.ex, self.ey
        return (dx * ax + dy * ay) / self.pixel_m, (dx * bx + dy * by) / self.pixel_m


@dataclass(frozen=True, eq=False)
class EpipolarPair:
    """Two views on one epipolar frame: each one's raw column and per-segment lines at the
    grid's nodes, the tilts and what they leave."""

    a: StereoView
    b: StereoView
    frame: EpipolarFrame
    step: int
    nodes: tuple[tuple[NDArray, NDArray], tuple[NDArray, NDArray]]  # (columns, lines) per view
    height_per_px_m: float  # metres of height per pixel of disparity
    base_to_height: float  # |a_b − a_a|: B/H
    epipolar_error_px: float  # the most v-parallax over TILT_SPAN_M, over the frame
    convergence_deg: float
    tan_incidence: tuple[float, float]  # each view's: its tilt's length

    def raw_of(self, which: int, u: NDArray, v: NDArray) -> tuple[NDArray, NDArray]:
        """Raw (line, column) of view ``which`` (0: a, 1: b) at epipolar ``(u, v)``."""
        cols, lines = self.nodes[which]
        rows = np.arange(cols.shape[0], dtype=np.float64) * self.step
        cc = np.arange(cols.shape[1], dtype=np.float64) * self.step
        col = bilinear_grid(rows, cc, cols, v, u)
        g = (self.a, self.b)[which].geometry
        seg = g.segment_of(col)
        line = np.empty_like(col)
        for s in np.unique(seg):
            k = seg == s
            line[k] = bilinear_grid(rows, cc, lines[s], v[k], u[k])
        return line, col

    def image(self, which: int) -> NDArray[np.float32]:
        """View ``which``'s raw image on the epipolar grid (NaN where not valid)."""
        cols, lines = self.nodes[which]
        view = (self.a, self.b)[which]
        return resample_epipolar(
            view.image, self.step, cols, lines, view.geometry.segment_first_column, self.frame.shape
        )

    def tree(self) -> dict[str, Any]:
        """What a DEM product keeps of the pair's geometry."""
        f = self.frame
        return {
            "view_a": f"{self.a.name}_s{self.a.scene:03d}",
            "view_b": f"{self.b.name}_s{self.b.scene:03d}",
            "reference_height_m": self.a.reference_height_m,
            "epipolar_origin_m": np.array(f.origin_m),
            "epipolar_direction": np.array(f.ex),
            "epipolar_pixel_m": f.pixel_m,
            "epipolar_shape": np.array(f.shape),
            "base_to_height": self.base_to_height,
            "convergence_deg": self.convergence_deg,
            "tan_incidence": np.array(self.tan_incidence),
            "height_per_disparity_px_m": self.height_per_px_m,
            "epipolar_error_px": self.epipolar_error_px,
        }


def _to_map(crs_wkt: str) -> pyproj.Transformer:
    return pyproj.Transformer.from_crs(
        pyproj.CRS.from_epsg(4326), pyproj.CRS.from_wkt(crs_wkt), always_xy=True
    )


def _valid_xy(view: StereoView, decimate: int = 4) -> tuple[NDArray, NDArray]:
    """Map positions of a view's level 2 footprint (its inverse grid's cells that fall in
    the raw image)."""
    g = view.geometry
    i, j = np.meshgrid(
        np.arange(0, g.map_grid.n_rows, decimate, dtype=np.float64),
        np.arange(0, g.map_grid.n_cols, decimate, dtype=np.float64),
        indexing="ij",
    )
    line, col = g.raw_of(i.ravel(), j.ravel())
    inside = (line >= 0) & (line <= g.n_raw_lines - 1) & (col >= 0) & (col <= g.n_raw_columns - 1)
    return g.map_grid.map_of(i.ravel()[inside], j.ravel()[inside])


def _tilts(
    view: StereoView, lat: NDArray, lon: NDArray, to_map: pyproj.Transformer
) -> NDArray[np.float64]:
    """The view's horizontal tilt ``a`` (metres on the plane per metre of height, (N, 2))
    at ground points on the plane: where they appear raised by ``TILT_SPAN_M``."""
    h0 = view.reference_height_m
    x0, y0, _ = view.ground_to_plane(lat, lon, np.full(lat.shape, h0), to_map)
    x1, y1, _ = view.ground_to_plane(lat, lon, np.full(lat.shape, h0 + TILT_SPAN_M), to_map)
    return np.column_stack([x1 - x0, y1 - y0]) / TILT_SPAN_M


def epipolar_pair(a: StereoView, b: StereoView, step: int = NODE_STEP_PX) -> EpipolarPair:
    """The epipolar grid of two views over their common footprint (module docstring)."""
    ga, gb = a.geometry.map_grid, b.geometry.map_grid
    if ga.crs_wkt != gb.crs_wkt:
        raise GeometryError("a stereo pair's level 2s must share their map CRS")
    if abs(a.reference_height_m - b.reference_height_m) > 1e-6:
        raise GeometryError(
            f"a stereo pair's level 2s must share their reference height "
            f"({a.reference_height_m} and {b.reference_height_m} m)"
        )
    to_map = _to_map(ga.crs_wkt)
    xa, ya = _valid_xy(a)
    xb, yb = _valid_xy(b)
    lo = np.maximum([xa.min(), ya.min()], [xb.min(), yb.min()])
    hi = np.minimum([xa.max(), ya.max()], [xb.max(), yb.max()])
    if np.any(hi - lo <= 0):
        raise GeometryError("the two scenes do not overlap")
    # the tilts over the common part: a 7 × 7 lattice of it on the plane
    gx, gy = np.meshgrid(np.linspace(lo[0], hi[0], 7), np.linspace(lo[1], hi[1], 7))
    lon, lat = pyproj.Transformer.from_crs(
        pyproj.CRS.from_wkt(ga.crs_wkt), pyproj.CRS.from_epsg(4326), always_xy=True
    ).transform(gx.ravel(), gy.ravel())
    lat, lon = np.radians(lat), np.radians(lon)
    tilt_a, tilt_b = _tilts(a, lat, lon, to_map), _tilts(b, lat, lon, to_map)
    tilt = tilt_b - tilt_a
    mean = np.nanmean(tilt, axis=0)
    base_to_height = float(np.hypot(*mean))
    if not base_to_height > 0.05:
        raise GeometryError(
            f"the two views converge by B/H {base_to_height:.3f}: no stereo (views from one "
            "track see a point along one line of sight)"
        )
    ex = mean / base_to_height
    ey = np.array([ex[1], -ex[0]])
    pixel = abs(ga.geotransform[1])
    epipolar_error = float(np.nanmax(np.abs(tilt @ ey))) * TILT_SPAN_M / pixel
    # the frame: the two footprints' common box in (u, v) (the disparity direction runs
    # across the tracks: a scene is nearly a rectangle there), on whole pixels
    box = [
        (np.array([x, y]).T @ ex / pixel, np.array([x, y]).T @ ey / pixel)
        for x, y in ((xa, ya), (xb, yb))
    ]
    u_lo, u_hi = max(u.min() for u, _ in box), min(u.max() for u, _ in box)
    v_lo, v_hi = max(v.min() for _, v in box), min(v.max() for _, v in box)
    if not (u_hi > u_lo and v_hi > v_lo):
        raise GeometryError("the two scenes do not overlap")
    u0, v0 = np.floor(u_lo), np.floor(v_lo)
    origin = tuple(pixel * (u0 * ex + v0 * ey))
    shape = (int(np.ceil(v_hi - v0)) + 1, int(np.ceil(u_hi - u0)) + 1)
    frame = EpipolarFrame(
        ga.crs_wkt,
        (float(origin[0]), float(origin[1])),
        (float(ex[0]), float(ex[1])),
        pixel,
        shape,
    )
    nodes = tuple(_nodes(view, frame, step) for view in (a, b))
    return EpipolarPair(
        a=a,
        b=b,
        frame=frame,
        step=step,
        nodes=nodes,  # type: ignore[arg-type]
        height_per_px_m=pixel / base_to_height,
        base_to_height=base_to_height,
        epipolar_error_px=epipolar_error,
        convergence_deg=float(np.degrees(2 * np.arctan(base_to_height / 2))),
        tan_incidence=(
            float(np.nanmean(np.hypot(*tilt_a.T))),
            float(np.nanmean(np.hypot(*tilt_b.T))),
        ),
    )


def _nodes(view: StereoView, frame: EpipolarFrame, step: int) -> tuple[NDArray, NDArray]:
    """A view's raw column and per-segment lines at the frame's nodes (through its level
    2 inverse grid)."""
    rows, cols = frame.shape
    nv, nu = -(-(rows - 1) // step) + 1, -(-(cols - 1) // step) + 1
    v, u = np.meshgrid(np.arange(nv) * step, np.arange(nu) * step, indexing="ij")
    x, y = frame.map_of(u.astype(float), v.astype(float))
    i, j = view.geometry.map_grid.ij_of_map(x, y)
    g = view.geometry
    col = bilinear_grid(g.inverse_rows, g.inverse_cols, g.inverse_column, i, j)
    lines = np.stack(
        [bilinear_grid(g.inverse_rows, g.inverse_cols, z, i, j) for z in g.inverse_line]
    )
    return col, lines


@dataclass(frozen=True, eq=False)
class Disparity:
    """A disparity field on the epipolar grid (``u_b = u_a + d``, pixels; NaN where
    refused), its matching σ (pixels) and what each test refused."""

    d: NDArray[np.float32]
    sigma: NDArray[np.float32]
    counts: dict[str, int]

    @property
    def valid(self) -> NDArray[np.bool_]:
        return np.isfinite(self.d)


def _box(x: NDArray, w: int) -> NDArray:
    import cv2

    return cv2.boxFilter(x, -1, (w, w), normalize=True, borderType=cv2.BORDER_REFLECT)


def _bytes(img: NDArray[np.float32]) -> NDArray[np.uint8]:
    return np.clip(np.rint(np.nan_to_num(img, nan=0.0)), 0, 255).astype(np.uint8)


def _sgbm(left: NDArray, right: NDArray, d_lo: float, d_hi: float) -> NDArray[np.float32]:
    """OpenCV's SGBM (its disparity ``left(x) = right(x − D)``: ``D = −d``), NaN where it
    found none."""
    import cv2

    lo = int(np.floor(-d_hi - DISPARITY_MARGIN_PX))
    n = int(np.ceil((d_hi - d_lo + 2 * DISPARITY_MARGIN_PX) / 16.0)) * 16
    if n + SGBM_BLOCK_PX >= left.shape[1]:
        raise GeometryError(
            f"a disparity search of {n} px over epipolar images {left.shape[1]} px wide: the "
            "pair overlaps too little for its relief"
        )
    cn = 1
    sgbm = cv2.StereoSGBM.create(
        minDisparity=lo,
        numDisparities=n,
        blockSize=SGBM_BLOCK_PX,
        P1=SGBM_P1 * cn * SGBM_BLOCK_PX**2,
        P2=SGBM_P2 * cn * SGBM_BLOCK_PX**2,
        disp12MaxDiff=SGBM_LR_PX,
        uniquenessRatio=SGBM_UNIQUENESS,
        speckleWindowSize=SGBM_SPECKLE_PX,
        speckleRange=SGBM_SPECKLE_RANGE,
        mode=cv2.StereoSGBM_MODE_SGBM_3WAY,
    )
    raw = sgbm.compute(_bytes(left), _bytes(right))
    d = -raw.astype(np.float32) / 16.0
    d[raw < lo * 16] = np.nan
    return d


#: Lags over which the residual's correlation is measured (pixels, each axis).
CORRELATION_LAGS = 4


def _correlation_factor(res: NDArray, d: NDArray, w: int) -> float:
    """How much the window's residuals' correlation inflates Förstner's variance: the
    residual (what the two images still differ by once aligned: blur, aliasing, relief) is
    not white, and the variance of a least-squares shift over ``w`` pixels of correlated
    residuals is the white one times ``Σ (1 − |k|/w) ρ(k)`` along each axis (the variance of
    a mean of correlated samples); ``ρ`` measured over the whole image at lags up to
    ``CORRELATION_LAGS``."""
    ok = np.isfinite(d) & (res != 0)
    r = np.where(ok, res, 0.0).astype(np.float64)
    var = float(np.sum(r * r))
    if var <= 0:
        return 1.0
    factor = 1.0
    for axis in (0, 1):
        total = 1.0
        for k in range(1, CORRELATION_LAGS + 1):
            a = np.take(r, np.arange(r.shape[axis] - k), axis=axis)
            b = np.take(r, np.arange(k, r.shape[axis]), axis=axis)
            rho = float(np.sum(a * b)) / var
            total += 2.0 * (1.0 - k / w) * rho
        factor *= max(total, 1.0)
    return factor


#: Rows refined at once (memory: about 130 bytes a pixel in flight).
_REFINE_ROWS = 1024


def _window_sums(
    g: NDArray[np.float32],
    gv: NDArray[np.float32],
    y: NDArray[np.float32],
    kept: NDArray[np.float32],
    w: int,
) -> NDArray[np.float32]:
    """The window sums of :data:`levels.cor.epipolar.WINDOW_SUMS` over ``w × w`` windows
    (``g``, ``gv``, ``y`` zero where ``kept`` is)."""
    import cv2

    t = np.arange(w, dtype=np.float32) - np.float32(w // 2)
    one, t2 = np.ones(w, dtype=np.float32), t * t
    gg, ggv = g * g, g * gv
    gy = g * y
    terms = (
        (g, one, one), (g, t, one), (g, one, t), (gv, one, one), (y, one, one),
        (gg, one, one), (gg, t, one), (gg, one, t), (gg, t2, one), (gg, t, t), (gg, one, t2),
        (ggv, one, one), (ggv, t, one), (ggv, one, t), (gv * gv, one, one),
        (gy, one, one), (gy, t, one), (gy, one, t), (gv * y, one, one), (y * y, one, one),
        (kept, one, one),
    )  # fmt: skip
    out = np.empty((len(terms), *g.shape), dtype=np.float32)
    for k, (f, kx, kz) in enumerate(terms):
        cv2.sepFilter2D(f, cv2.CV_32F, kx, kz, dst=out[k], borderType=cv2.BORDER_REFLECT)
    return out


def _refine(
    left: NDArray[np.float32], right: NDArray[np.float32], d0: NDArray[np.float32]
) -> tuple[NDArray[np.float32], NDArray[np.float32], NDArray[np.float32], NDArray[np.float32]]:
    """SGBM's disparity refined by least squares (module docstring, step 2): the disparity,
    its σ before the residual's correlation, the window's centred gradient energy per pixel
    and the residual image."""
    w, n = REFINE_WINDOW_PX, REFINE_WINDOW_PX**2
    gx_right = np.gradient(right, axis=1).astype(np.float32)
    gv_right = np.gradient(right, axis=0).astype(np.float32)
    lft = np.nan_to_num(left).astype(np.float32)
    ok = np.isfinite(d0)
    d_ref = np.float32(np.median(d0[ok])) if ok.any() else np.float32(0.0)
    d = np.where(ok, d0, d_ref).astype(np.float32)
    var = s2 = den = np.zeros_like(d)
    for _ in range(REFINE_ITERATIONS):
        rw = shift_rows(right, d)
        # a window's pixels: those with a disparity from SGBM, read inside both images (the
        # others' first-order model does not hold: they are left out, not zeroed in)
        kept = np.isfinite(d) & np.isfinite(rw) & np.isfinite(left)
        g = np.where(kept, shift_rows(gx_right, d), 0.0).astype(np.float32)
        gv = np.where(kept, shift_rows(gv_right, d), 0.0).astype(np.float32)
        g, gv = np.nan_to_num(g), np.nan_to_num(gv)
        # y = g·d_true(q) + c, to first order, whatever the disparity d(q) each pixel was
        # warped by: the window fits d_true as a plane (its slope) and solves for its value
        # at its centre, not a mean of its pixels' (biased on a slope by where the texture
        # lies in the window); gv·θ takes the v-parallax the epipolar grid leaves
        y = np.where(kept, lft - rw + g * (d - d_ref), 0.0).astype(np.float32)
        sums = _window_sums(g, gv, y, kept.astype(np.float32), w)
        new, var, s2 = window_solve(sums, n // 2)
        den = (sums[5] - sums[0] * sums[0] / np.maximum(sums[20], 1.0)) / np.maximum(sums[20], 1.0)
        new += d_ref
        d = (d + np.clip(new - d, -0.5, 0.5)).astype(np.float32)
        d[~ok] = np.nan
    rw0 = np.nan_to_num(shift_rows(right, d))
    res = (lft - _box(lft, w)) - (rw0 - _box(rw0, w))
    return d, np.sqrt(s2 * var).astype(np.float32), den.astype(np.float32), res


def match(
    left: NDArray[np.float32], right: NDArray[np.float32], d_lo: float, d_hi: float
) -> Disparity:
    """Dense disparity between two epipolar images over ``[d_lo, d_hi]`` pixels (module
    docstring, step 2)."""
    counts: dict[str, int] = {}
    bad = ~(np.isfinite(left))
    d0 = _sgbm(left, right, d_lo, d_hi)
    d0[bad] = np.nan
    counts["sgbm_none"] = int(np.sum(~np.isfinite(d0) & ~bad))
    d, sigma, den, res = (np.empty_like(d0) for _ in range(4))
    # by strips of rows, each with a halo the iterations' windows reach through: the same
    # disparities as the whole image at once, in a bounded memory
    halo = REFINE_ITERATIONS * (REFINE_WINDOW_PX // 2) + 2
    for r0 in range(0, left.shape[0], _REFINE_ROWS):
        r1 = min(r0 + _REFINE_ROWS, left.shape[0])
        a, b = max(r0 - halo, 0), min(r1 + halo, left.shape[0])
        out = _refine(left[a:b], right[a:b], d0[a:b])
        for whole, part in zip((d, sigma, den, res), out, strict=True):
            whole[r0:r1] = part[r0 - a : r1 - a]
    sigma *= np.float32(np.sqrt(_correlation_factor(res, d, REFINE_WINDOW_PX)))
    moved = np.abs(d - d0)
    refused = [
        ("refinement_moved", np.isfinite(d0) & ~(moved <= MAX_REFINE_PX)),
        ("flat", np.isfinite(d0) & ~(den >= MIN_GRADIENT)),
        ("uncertain", np.isfinite(d0) & ~(sigma <= MAX_SIGMA_PX)),
    ]
    keep = np.isfinite(d0) & np.isfinite(d)
    for why, mask in refused:
        counts[why] = int(np.sum(mask & keep))
        keep &= ~mask
    d[~keep] = np.nan
    sigma[~keep] = np.nan
    counts["valid"] = int(keep.sum())
    return Disparity(d, sigma, counts)


def closest_approach(
    r1: NDArray, u1: NDArray, r2: NDArray, u2: NDArray
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Mid-point of the common perpendicular of two lines (PHOTOMOD's triangulation,
    paper ``003_…``: "the middle of the common perpendicular", the rays never meeting) and
    the lines' miss along it (m, signed)."""
    w = r1 - r2
    b = np.sum(u1 * u2, axis=1)
    d, e = np.sum(u1 * w, axis=1), np.sum(u2 * w, axis=1)
    den = 1.0 - b**2
    s = (b * e - d) / den
    t = (e - b * d) / den
    p1, p2 = r1 + s[:, None] * u1, r2 + t[:, None] * u2
    n = np.cross(u1, u2)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    return 0.5 * (p1 + p2), np.sum((p2 - p1) * n, axis=1)


@dataclass(frozen=True, eq=False)
class StereoPoints:
    """Triangulated points: map position (m), ellipsoidal height (m), the rays' miss (m)
    and the predicted height σ (m)."""

    x_m: NDArray[np.float64]
    y_m: NDArray[np.float64]
    h_m: NDArray[np.float32]
    miss_m: NDArray[np.float32]
    sigma_h_m: NDArray[np.float32]
    pixel_m: float  # the epipolar pixel they were triangulated on
    stride: int  # every stride-th pixel of it


def triangulate_raw(
    a: PushbroomModel,
    b: PushbroomModel,
    la: NDArray,
    ca: NDArray,
    lb: NDArray,
    cb: NDArray,
) -> tuple[NDArray, NDArray, NDArray, NDArray]:
    """Latitude, longitude (rad), height (m) and miss (m) of points measured at raw
    ``(la, ca)`` in the image of model ``a`` and ``(lb, cb)`` in that of ``b``."""
    r1, u1 = a.sight(la, ca)
    r2, u2 = b.sight(lb, cb)
    mid, miss = closest_approach(r1, u1, r2, u2)
    lat, lon, h = WGS84.to_geodetic(mid)
    return lat, lon, h, miss


def _triangulate_exact(
    pair: EpipolarPair, u: NDArray, v: NDArray, d: NDArray
) -> tuple[NDArray, NDArray, NDArray, NDArray]:
    """Map x, y, height and miss of epipolar points ``(u, v)`` matched at ``u + d``."""
    to_map = _to_map(pair.frame.crs_wkt)
    out = [np.empty(u.size) for _ in range(4)]
    for k in range(0, u.size, _CHUNK):
        s = slice(k, k + _CHUNK)
        la, ca = pair.raw_of(0, u[s], v[s])
        lb, cb = pair.raw_of(1, u[s] + d[s], v[s])
        lat, lon, h, miss = triangulate_raw(pair.a.model, pair.b.model, la, ca, lb, cb)
        x, y = to_map.transform(np.degrees(lon), np.degrees(lat))
        out[0][s], out[1][s], out[2][s], out[3][s] = x, y, h, miss
    return out[0], out[1], out[2], out[3]


#: The triangulation's anchor grid: nodes every ``ANCHOR_STEP_PX`` epipolar pixels, and
#: ``ANCHOR_LEVELS`` disparities over the range, fitted per node by a cubic in the
#: disparity (a point moves along smooth curves as its disparity grows), bilinearly
#: between nodes: level 3's anchor grids, in the pair's geometry. Its error against the
#: rigorous triangulation is measured on ``ANCHOR_CHECKS`` points and kept.
ANCHOR_STEP_PX = 32
ANCHOR_LEVELS = 7
ANCHOR_CHECKS = 2000


def _anchor_fit(
    pair: EpipolarPair, d_range: tuple[float, float]
) -> tuple[NDArray, NDArray, NDArray, float, float]:
    """Per node, the cubic coefficients in the normalised disparity of x, y, h and miss:
    ``(4 quantities, 4 powers, nodes v, nodes u)``; the node rows, columns, and the
    normalisation (centre, half span)."""
    rows, cols = pair.frame.shape
    step = ANCHOR_STEP_PX
    nv, nu = -(-(rows - 1) // step) + 1, -(-(cols - 1) // step) + 1
    v_n, u_n = np.arange(nv) * float(step), np.arange(nu) * float(step)
    c, half = 0.5 * (d_range[0] + d_range[1]), max(0.5 * (d_range[1] - d_range[0]), 1.0)
    t = np.cos(np.pi * (np.arange(ANCHOR_LEVELS) + 0.5) / ANCHOR_LEVELS)  # Chebyshev nodes
    V, U, T = np.meshgrid(v_n, u_n, t, indexing="ij")
    q = np.stack(_triangulate_exact(pair, U.ravel(), V.ravel(), c + half * T.ravel()))
    q = q.reshape(4, nv, nu, ANCHOR_LEVELS)
    powers = np.vander(t, 4, increasing=True)  # (levels, 4)
    coef = np.linalg.lstsq(powers, q.reshape(-1, ANCHOR_LEVELS).T, rcond=None)[0]
    return coef.T.reshape(4, nv, nu, 4).transpose(0, 3, 1, 2), v_n, u_n, c, half


@nb.njit(cache=True, nogil=True)
def _kernel_anchor(lo, hi, d, stride, coef, step, c, half, index, out):
    """Rows ``lo … hi − 1`` of the strided disparity field: each valid pixel's x, y, h and
    miss from the anchor fit (Horner in the disparity, coefficients bilinear between
    nodes), stored at its rank ``index[row]`` + its count along the row."""
    nv, nu = coef.shape[2], coef.shape[3]
    for r in range(lo, hi):
        v = r * stride
        a = min(v // step, nv - 2)
        fv = (v - a * step) / step
        k = index[r]
        for q in range(0, d.shape[1], stride):
            dd = d[v, q]
            if not (dd == dd):
                continue
            b = min(q // step, nu - 2)
            fu = (q - b * step) / step
            t = (dd - c) / half
            for m in range(4):
                acc = 0.0
                for p in range(3, -1, -1):
                    z = coef[m, p]
                    at_b = (1.0 - fv) * z[a, b] + fv * z[a + 1, b]
                    at_b1 = (1.0 - fv) * z[a, b + 1] + fv * z[a + 1, b + 1]
                    acc = acc * t + ((1.0 - fu) * at_b + fu * at_b1)
                out[m, k] = acc
            k += 1


def _anchor_eval(
    fit: tuple[NDArray, NDArray, NDArray, float, float], u: NDArray, v: NDArray, d: NDArray
) -> NDArray:
    """x, y, h, miss ``(4, N)`` from the anchor fit at scattered points (the checks)."""
    coef, v_n, u_n, c, half = fit
    t = (d - c) / half
    out = np.zeros((4, u.size))
    for p in range(3, -1, -1):  # Horner in t, each coefficient bilinearly between nodes
        at = np.stack([bilinear_grid(v_n, u_n, coef[k, p], v, u) for k in range(4)])
        out = out * t + at
    return out


def triangulate(
    pair: EpipolarPair, disparity: Disparity, d_range: tuple[float, float], stride: int = 1
) -> tuple[StereoPoints, float]:
    """Every ``stride``-th valid pixel of the disparity field, triangulated through the
    anchor grid (step 3); and the grid's largest height error on the checks (m)."""
    valid = disparity.valid[::stride, ::stride]
    per_row = np.count_nonzero(valid, axis=1)
    index = np.concatenate([[0], np.cumsum(per_row)[:-1]]).astype(np.int64)
    n = int(per_row.sum())
    fit = _anchor_fit(pair, d_range)
    out = np.empty((4, n))
    coef, v_n, _, c, half = fit
    over_blocks(
        _kernel_anchor,
        per_row.size,
        disparity.d,
        stride,
        np.ascontiguousarray(coef),
        int(v_n[1] - v_n[0]),
        float(c),
        float(half),
        index,
        out,
    )
    # the checks: a random draw of the points, their pixels found from their ranks
    check = np.sort(np.random.default_rng(0).choice(n, min(ANCHOR_CHECKS, n), replace=False))
    row = np.searchsorted(index, check, side="right") - 1
    col = np.array(
        [np.flatnonzero(valid[r])[k - index[r]] for r, k in zip(row, check, strict=True)],
        dtype=np.int64,
    )
    v, u = (row * stride).astype(np.float64), (col * stride).astype(np.float64)
    d = disparity.d[row * stride, col * stride].astype(np.float64)
    exact = np.stack(_triangulate_exact(pair, u, v, d))
    error = float(np.max(np.abs(exact[:3] - out[:3, check]))) if check.size else 0.0
    sigma = disparity.sigma[::stride, ::stride][valid].astype(np.float32) * pair.height_per_px_m
    points = StereoPoints(
        out[0],
        out[1],
        out[2].astype(np.float32),
        out[3].astype(np.float32),
        sigma,
        pair.frame.pixel_m,
        stride,
    )
    return points, error


def _mean_correlation(m: int, stride: int, window: int) -> float:
    """Mean correlation of the matching errors of ``m × m`` points ``stride`` pixels apart
    whose ``window``-pixel windows overlap (box windows: ``(1 − |dx|/w)(1 − |dy|/w)``)."""
    k = np.arange(m) * stride
    dx = np.abs(k[:, None] - k[None, :])
    r1 = np.clip(1.0 - dx / window, 0.0, None)
    return float(np.mean(r1) ** 2)


def grid_points(
    points: StereoPoints, grid: MapGrid, window: int = REFINE_WINDOW_PX
) -> tuple[NDArray[np.float32], NDArray[np.uint16], NDArray[np.float32]]:
    """Heights (NaN: a hole), point counts and predicted σ (m) on ``grid`` (step 4)."""
    i, j = grid.ij_of_map(points.x_m, points.y_m)
    i, j = np.rint(i).astype(np.int64), np.rint(j).astype(np.int64)
    inside = (i >= 0) & (i < grid.n_rows) & (j >= 0) & (j < grid.n_cols) & np.isfinite(points.h_m)
    k = i[inside] * grid.n_cols + j[inside]
    size = grid.n_rows * grid.n_cols
    n = np.bincount(k, minlength=size)
    s = np.bincount(k, points.h_m[inside], minlength=size)
    s2 = np.bincount(k, points.sigma_h_m[inside] ** 2, minlength=size)
    with np.errstate(invalid="ignore", divide="ignore"):
        h = np.where(n > 0, s / n, np.nan)
        var = s2 / n  # the points' mean variance
    m = max(1, round(abs(grid.geotransform[1]) / (points.pixel_m * points.stride)))
    rho = _mean_correlation(m, points.stride, window)
    sigma = np.sqrt(var * (rho + (1.0 - rho) / np.maximum(n, 1)))
    shape = (grid.n_rows, grid.n_cols)
    return (
        h.reshape(shape).astype(np.float32),
        np.minimum(n, 65535).reshape(shape).astype(np.uint16),
        np.where(n > 0, sigma, np.nan).reshape(shape).astype(np.float32),
    )


@dataclass(frozen=True, eq=False)
class StereoDem:
    """A pair's DEM: heights on a map grid (NaN: holes), points per cell, predicted σ, and
    the pair, its disparity, its points and timings."""

    grid: MapGrid
    height_m: NDArray[np.float32]
    count: NDArray[np.uint16]
    sigma_m: NDArray[np.float32]
    pair: EpipolarPair
    disparity: Disparity
    points: StereoPoints
    disparity_range_px: tuple[float, float]
    timings_s: dict[str, float]
    anchor_error_m: float  # the triangulation grid's largest error on its checks


def disparity_range(
    pair: EpipolarPair, ties_a: ControlPointSet, ties_b: ControlPointSet
) -> tuple[float, float]:
    """The disparity range the pair's tie points span (pixels): each tie point's raw
    positions taken onto the epipolar grid through each view's model at ``h0``."""
    common = sorted(set(ties_a.id) & set(ties_b.id))
    if len(common) < 3:
        raise GeometryError(
            f"{len(common)} tie points between the pair: the disparity range needs 3 or more"
        )
    ia = [ties_a.id.index(t) for t in common]
    ib = [ties_b.id.index(t) for t in common]
    first = (pair.a, pair.b)
    u = []
    for view, ties, idx in zip(first, (ties_a, ties_b), (ia, ib), strict=True):
        line = np.asarray(ties.line)[idx] - view.first_line
        col = np.asarray(ties.column)[idx]
        on = view.model.image_to_ground(line, col, view.reference_height_m)
        x, y = _to_map(pair.frame.crs_wkt).transform(np.degrees(on.lon_rad), np.degrees(on.lat_rad))
        uu, _ = pair.frame.uv_of(np.asarray(x), np.asarray(y))
        u.append(uu)
    d = u[1] - u[0]
    d = d[np.isfinite(d)]
    return float(np.min(d)), float(np.max(d))


#: The coarse search's reduction, and its range beyond the tie points' (coarse pixels).
COARSE_FACTOR = 8
COARSE_MARGIN_PX = 24


def coarse_range(
    left: NDArray[np.float32], right: NDArray[np.float32], d_range: tuple[float, float]
) -> tuple[float, float]:
    """The disparity range of the whole pair: SGBM on both images reduced ``COARSE_FACTOR``
    times (area averages) over the tie points' range widened by ``COARSE_MARGIN_PX`` coarse
    pixels each side (tie points, matched where the parallax is small, may miss the
    highest and lowest ground), where both are valid; its 1–99 % span, full scale, a
    coarse pixel wider each side, united with ``d_range``."""
    import cv2

    f = COARSE_FACTOR

    def reduce(x: NDArray) -> NDArray:  # NaN where any pixel of the area is
        return cv2.resize(x, None, fx=1 / f, fy=1 / f, interpolation=cv2.INTER_AREA)

    small = [reduce(x) for x in (left, right)]
    lo, hi = d_range[0] / f - COARSE_MARGIN_PX, d_range[1] / f + COARSE_MARGIN_PX
    try:
        d = _sgbm(np.nan_to_num(small[0]), np.nan_to_num(small[1]), lo, hi)
    except GeometryError:  # a pair too small to be reduced that much: the tie points' range
        return d_range
    # only where the left pixel and its match on the right are valid
    rows, cols = np.nonzero(np.isfinite(d) & np.isfinite(small[0]))
    at = np.rint(cols + d[rows, cols]).astype(np.int64)
    inside = (at >= 0) & (at < d.shape[1])
    ok = np.zeros(rows.size, dtype=bool)
    ok[inside] = np.isfinite(small[1][rows[inside], at[inside]])
    d = d[rows[ok], cols[ok]] * f
    if d.size < 100:
        return d_range
    p_lo, p_hi = np.percentile(d, [1.0, 99.0])
    return min(d_range[0], float(p_lo) - f), max(d_range[1], float(p_hi) + f)


def stereo_dem(
    pair: EpipolarPair,
    d_range: tuple[float, float],
    cell_px: int = 2,
    stride: int = 1,
) -> StereoDem:
    """The pair's DEM (module docstring): epipolar images, matching over ``d_range``,
    triangulation of every ``stride``-th pixel, gridding on ``cell_px`` pixels."""
    import time

    t: dict[str, float] = {}
    t0 = time.perf_counter()
    left, right = pair.image(0), pair.image(1)
    t["resample"] = time.perf_counter() - t0
    _log.info(
        "stereo: epipolar images %d × %d resampled in %.1f s; matching",
        *left.shape,
        t["resample"],
    )
    t0 = time.perf_counter()
    d_range = coarse_range(left, right, d_range)
    disparity = match(left, right, *d_range)
    t["match"] = time.perf_counter() - t0
    _log.info(
        "stereo: %d pixels matched in %.1f s (disparity %.1f to %.1f px); triangulating",
        disparity.counts.get("valid", 0),
        t["match"],
        *d_range,
    )
    t0 = time.perf_counter()
    points, anchor_error = triangulate(pair, disparity, d_range, stride)
    t["triangulate"] = time.perf_counter() - t0
    _log.info("stereo: triangulated in %.1f s; gridding", t["triangulate"])
    t0 = time.perf_counter()
    grid = dem_grid(points, pair.frame.crs_wkt, cell_px * pair.frame.pixel_m)
    h, n, sigma = grid_points(points, grid)
    wild = blunder_cells(h, BLUNDER_FLOOR_PX * pair.height_per_px_m)
    h[wild], sigma[wild], n[wild] = np.nan, np.nan, 0
    disparity.counts["blunder_cells"] = int(wild.sum())
    t["grid"] = time.perf_counter() - t0
    return StereoDem(grid, h, n, sigma, pair, disparity, points, d_range, t, anchor_error)


#: Blunder cells (:func:`blunder_cells`): the reference surface's block (cells), and how far
#: from it a cell may lie, in robust σ of all cells' deviations, and at least in pixels of
#: disparity.
BLUNDER_BLOCK = 8
BLUNDER_SIGMAS = 6.0
BLUNDER_FLOOR_PX = 3.0


def blunder_cells(h: NDArray[np.float32], floor_m: float) -> NDArray[np.bool_]:
    """Cells of a gridded DEM far off the surface of their neighbourhood: wrong matches that
    survived the matcher's tests (a patch matched at the end of the search range). The
    surface: the median of each ``BLUNDER_BLOCK``² block's valid cells, bilinear between
    blocks; a cell is a blunder beyond ``BLUNDER_SIGMAS`` robust σ of every cell's
    deviation from it, and beyond ``floor_m``."""
    from scipy import ndimage

    b = BLUNDER_BLOCK
    rows, cols = h.shape
    pad = np.full((-(-rows // b) * b, -(-cols // b) * b), np.nan, dtype=np.float32)
    pad[:rows, :cols] = h
    blocks = pad.reshape(pad.shape[0] // b, b, pad.shape[1] // b, b).transpose(0, 2, 1, 3)
    with np.errstate(all="ignore"):
        import warnings

        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN blocks
            med = np.nanmedian(blocks.reshape(*blocks.shape[:2], -1), axis=2)
    have = np.isfinite(med)
    if not have.any():
        return np.zeros(h.shape, dtype=bool)
    # empty blocks take their nearest block's median
    near = ndimage.distance_transform_edt(~have, return_distances=False, return_indices=True)
    med = med[tuple(near)]
    r = (np.arange(rows) + 0.5) / b - 0.5
    c = (np.arange(cols) + 0.5) / b - 0.5
    rr, cc = np.meshgrid(r, c, indexing="ij")
    surface = ndimage.map_coordinates(med, [rr, cc], order=1, mode="nearest")
    dev = h - surface
    ok = np.isfinite(dev)
    if not ok.any():
        return np.zeros(h.shape, dtype=bool)
    spread = 1.4826 * float(np.median(np.abs(dev[ok])))
    return ok & (np.abs(dev) > max(BLUNDER_SIGMAS * spread, floor_m))


def dem_grid(points: StereoPoints, crs_wkt: str, cell_m: float) -> MapGrid:
    """A north-up grid of ``cell_m`` over the points, its nodes on multiples of it."""
    x0 = np.floor(np.nanmin(points.x_m) / cell_m) * cell_m
    x1 = np.ceil(np.nanmax(points.x_m) / cell_m) * cell_m
    y0 = np.floor(np.nanmin(points.y_m) / cell_m) * cell_m
    y1 = np.ceil(np.nanmax(points.y_m) / cell_m) * cell_m
    rows, cols = round((y1 - y0) / cell_m) + 1, round((x1 - x0) / cell_m) + 1
    return MapGrid.north_up(crs_wkt, x0 - cell_m / 2, y1 + cell_m / 2, cell_m, rows, cols)
