"""A stereo pair's epipolar geometry: each view's level 2 and 1A (:class:`StereoView`), the
pair's epipolar frame and grids (:func:`epipolar_pair`), the epipolar images resampled
from the raw pixels.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import pyproj
from numpy.typing import NDArray

from levels.choices import Level
from levels.cor.epipolar import resample_epipolar
from levels.errors import GeometryError
from levels.geo.inverse_grid import bilinear_grid
from levels.geo.level2a import Level2AGeometry
from levels.geometry.model import PushbroomModel

if TYPE_CHECKING:
    from levels.product import Product

#: Spacing of the epipolar grid's nodes (pixels): the model through level 2's inverse grid
#: there, bilinearly between (its approximation error is stored with the pair).
NODE_STEP_PX = 16
#: Height span over which the disparity direction and the epipolar error are measured (m).
TILT_SPAN_M = 1000.0


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
    def of_products(cls, level2: Product, level1a: Product, band: str | None = None) -> StereoView:
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

    def tree(self) -> dict[str, object]:
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
