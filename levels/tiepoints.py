"""Tie points: the same ground found in two overlapping scenes of different passes (or of
a twin), measured in their raw images (ADRIN's "secondary controls", paper ``001_…``;
PHOTOMOD's tie points, ``003_…``), for a block adjustment.

Both scenes are first brought to a common geometry by the model: their level 2A images
(map-projected at the reference height) on the first one's map grid. What is left between
them is the two system models' location error (hundreds of metres, nearly a translation
over a scene) and the relief's parallax between the two views. So:

1. **Global shift**: the translation between the two map images, by phase correlation
   (:func:`levels.quality.image_shift_px`) over their common valid part.
2. **Candidates**: corners of the first image (OpenCV's ``goodFeaturesToTrack``, Shi–Tomasi)
   away from invalid pixels.
3. **Matching**: each candidate's window (``WINDOW_PX``) by normalised cross-correlation
   (OpenCV's ``matchTemplate``) in the second image within ``SEARCH_PX`` of where the
   global shift puts it; refused when the peak is low (``MIN_NCC``), not unique (a second
   peak beyond two pixels within ``MIN_MARGIN`` of it: repetitive texture), or the window
   flat (``MIN_STD``: a cloud, water); the peak refined to a fraction of a pixel by a
   quadratic, then by Lucas–Kanade iterations on the windows (gain and offset normalised).
4. **Left–right consistency**: the match searched back from the second image must land
   within ``BACK_MATCH_PX`` of where it started.
5. **Consistency through the model**: the two lines of sight of a true tie point meet up to
   the models' error, which is smooth over a scene; their miss perpendicular to both (the
   y-parallax) is fitted as a plane over the first image, and a point off it by more than
   ``Y_PARALLAX_SIGMAS`` robust σ (at least ``Y_PARALLAX_FLOOR_PX``) is a wrong match.

The points are then taken back to each scene's raw image through its 2A inverse grid
(``Level2AGeometry.raw_of``, 0.001 px) and written as control points of kind ``tie``
(``docs/gcp.md``): the same id in each pass's file, the ground position the mid-point of the
two lines of sight (an approximation: a block adjustment solves it).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from levels.errors import GeometryError
from levels.geo.level2a import Level2AGeometry
from levels.geometry.model import PushbroomModel
from levels.readers.dem import EARTH_HEIGHTS_M
from levels.readers.gcp import ControlPointSet
from levels.stereo import closest_approach

if TYPE_CHECKING:
    from levels.product import Product

__all__ = [
    "BACK_MATCH_PX",
    "MIN_MARGIN",
    "MIN_NCC",
    "MIN_STD",
    "SEARCH_PX",
    "WINDOW_PX",
    "MapView",
    "TiePoints",
    "match_views",
]

#: Side of the correlation window (pixels, odd).
WINDOW_PX = 21
#: Search radius around the globally shifted position (pixels): the relief's parallax
#: between two views and what the location errors leave beyond a translation.
SEARCH_PX = 6
#: Lowest normalised cross-correlation accepted.
MIN_NCC = 0.8
#: The best peak must beat any other (beyond 2 px) by this much: repetitive texture fails.
MIN_MARGIN = 0.1
#: Lowest standard deviation of a window (counts): flat ground, water or cloud fails.
MIN_STD = 2.0
#: Lucas–Kanade iterations of the sub-pixel refinement.
LK_ITERATIONS = 5
#: The match found back from the second image must land this close to its start (px).
BACK_MATCH_PX = 0.5
#: Wrong matches off the y-parallax plane by more than this many robust σ ...
Y_PARALLAX_SIGMAS = 4.0
#: ... and at least this many pixels.
Y_PARALLAX_FLOOR_PX = 0.5
#: Candidates at most, and their least spacing (pixels).
MAX_CANDIDATES = 1000
MIN_DISTANCE_PX = 8
#: σ of a tie point's image measurement written to the file (pixels): the matching's RMS
#: against the truth (0.12 px on the reduced pair, 0.14 px on a full P pair), rounded up.
TIE_SIGMA_PX = 0.2
#: σ written for a tie point's ground position (m): unknown; a block adjustment solves it.
TIE_SIGMA_GROUND_M = 10_000.0
TIE_SIGMA_H_M = 5_000.0


@dataclass(frozen=True, eq=False)
class MapView:
    """One scene as the matcher sees it: a level 2A (or 2) band on its map grid, its
    geometry back to raw, and the model its 2A was made with."""

    name: str
    hrv: int
    image: NDArray[np.float32]
    valid: NDArray[np.bool_]
    geometry: Level2AGeometry
    model: PushbroomModel
    first_line: int
    scene: int = 0
    reference_height_m: float = 0.0

    @classmethod
    def of_product(cls, product: Product, band: str | None = None) -> MapView:
        """The view of a map product (2A or 2) of one band (default its first)."""
        from levels.geo.scenes import models_of_tree

        tree = product.geometry.get("level_2a")
        if tree is None:
            raise GeometryError(
                f"level {product.level}: tie points are matched on a 2A (or 2) product"
            )
        name = band or next(iter(product.bands))
        _, models = models_of_tree(product.geometry)
        b = product.bands[name]
        return cls(
            name=str(product.attrs.get("name", "")),
            hrv=int(product.attrs.get("hrv", 1)),
            image=np.asarray(b.image, dtype=np.float32),
            valid=np.asarray(b.valid, dtype=bool),
            geometry=Level2AGeometry.from_tree(tree, name),
            model=models[name],
            first_line=int(product.geometry["scene"]["first_line"]),
            scene=int(product.attrs.get("scene_index", 0)),
            reference_height_m=float(product.geometry.get("reference_height_m", 0.0)),
        )


@dataclass(frozen=True, eq=False)
class TiePoints:
    """Tie points between views ``a`` and ``b``: raw positions (L0 rows and detectors,
    0-based), their correlation, the mid-point of the two lines of sight and its
    y-parallax (the lines' miss perpendicular to both, m); ``counts`` how many candidates
    each test refused."""

    a: str
    b: str
    hrv_a: int
    hrv_b: int
    line_a: NDArray[np.float64]
    column_a: NDArray[np.float64]
    line_b: NDArray[np.float64]
    column_b: NDArray[np.float64]
    ncc: NDArray[np.float64]
    lat_rad: NDArray[np.float64]
    lon_rad: NDArray[np.float64]
    h_m: NDArray[np.float64]
    y_parallax_m: NDArray[np.float64]
    counts: dict[str, int] = field(default_factory=dict)
    scene_a: int = 0
    scene_b: int = 0

    def __len__(self) -> int:
        return int(self.line_a.size)

    @property
    def ids(self) -> tuple[str, ...]:
        pair = f"{self.a}_s{self.scene_a:03d}_{self.b}_s{self.scene_b:03d}"
        return tuple(f"t_{pair}_{k:05d}" for k in range(len(self)))

    def control_points(self, which: str) -> ControlPointSet:
        """The points as measured in view ``which`` (``"a"`` or ``"b"``): control points of
        kind ``tie`` (``docs/gcp.md``)."""
        if which not in ("a", "b"):
            raise ValueError(f"which = {which!r}: expected 'a' or 'b'")
        line = self.line_a if which == "a" else self.line_b
        column = self.column_a if which == "a" else self.column_b
        n = len(self)
        return ControlPointSet(
            self.ids,
            self.lon_rad.copy(),
            self.lat_rad.copy(),
            self.h_m.copy(),
            line.copy(),
            column.copy(),
            np.full(n, TIE_SIGMA_GROUND_M),
            np.full(n, TIE_SIGMA_H_M),
            np.full(n, TIE_SIGMA_PX),
            np.full(n, self.hrv_a if which == "a" else self.hrv_b, dtype=np.int64),
            np.ones(n, dtype=bool),
        )


def _b_of_a(a: MapView, b: MapView):
    """The function taking positions on ``a``'s map grid (row, col) to ``b``'s grid: an
    affine map when the grids share their CRS, else through pyproj."""
    ga, gb = a.geometry.map_grid.geotransform, b.geometry.map_grid.geotransform
    same = a.geometry.map_grid.crs_wkt == b.geometry.map_grid.crs_wkt
    transformer = None
    if not same:
        import pyproj

        transformer = pyproj.Transformer.from_crs(
            pyproj.CRS.from_wkt(a.geometry.map_grid.crs_wkt),
            pyproj.CRS.from_wkt(b.geometry.map_grid.crs_wkt),
            always_xy=True,
        )

    def f(row: NDArray, col: NDArray) -> tuple[NDArray, NDArray]:
        x = ga[0] + (col + 0.5) * ga[1] + (row + 0.5) * ga[2]
        y = ga[3] + (col + 0.5) * ga[4] + (row + 0.5) * ga[5]
        if transformer is not None:
            x, y = transformer.transform(x, y)
        det = gb[1] * gb[5] - gb[2] * gb[4]
        dx, dy = x - gb[0], y - gb[3]
        cb = (gb[5] * dx - gb[2] * dy) / det - 0.5
        rb = (-gb[4] * dx + gb[1] * dy) / det - 0.5
        return rb, cb

    return f


def _windows(
    image: NDArray, rows: NDArray, cols: NDArray, half: int, order: int = 1
) -> NDArray[np.float32]:
    """Windows of side ``2·half + 1`` of ``image`` centred on fractional (rows, cols), all
    at once (``(N, w, w)``, spline interpolation of ``order``; outside: NaN)."""
    g = np.arange(-half, half + 1, dtype=np.float64)
    rr = rows[:, None, None] + g[None, :, None]
    cc = cols[:, None, None] + g[None, None, :]
    rr, cc = np.broadcast_arrays(rr, cc)
    out = ndimage.map_coordinates(image, [rr, cc], order=order, mode="constant", cval=np.nan)
    return out.astype(np.float32)


def _valid_windows(valid: NDArray[np.bool_], rows: NDArray, cols: NDArray, half: int) -> NDArray:
    """Whether each window (nearest pixels) lies wholly on valid pixels."""
    w = _windows(valid.astype(np.float32), np.rint(rows), np.rint(cols), half, order=0)
    return np.all(w == 1.0, axis=(1, 2))


def _ncc_peaks(
    templates: NDArray[np.float32], searches: NDArray[np.float32]
) -> tuple[NDArray, NDArray, NDArray, NDArray]:
    """Per pair: the NCC peak's sub-pixel offset (rows, cols) from the search window's
    centre (quadratic fit of its 3×3), its value, and the best value beyond 2 px of it."""
    import cv2

    n = templates.shape[0]
    size = searches.shape[1] - templates.shape[1] + 1
    surf = np.empty((n, size, size), dtype=np.float32)
    for k in range(n):  # one C call per point: OpenCV's FFT correlation
        surf[k] = cv2.matchTemplate(searches[k], templates[k], cv2.TM_CCOEFF_NORMED)
    flat = surf.reshape(n, -1)
    peak = np.argmax(flat, axis=1)
    pr, pc = np.divmod(peak, size)
    best = flat[np.arange(n), peak]
    rr, cc = np.meshgrid(np.arange(size), np.arange(size), indexing="ij")
    far = (np.abs(rr[None] - pr[:, None, None]) > 2) | (np.abs(cc[None] - pc[:, None, None]) > 2)
    second = np.where(far, surf, -1.0).reshape(n, -1).max(axis=1)
    inner = (pr > 0) & (pr < size - 1) & (pc > 0) & (pc < size - 1)
    prc, pcc = np.clip(pr, 1, size - 2), np.clip(pc, 1, size - 2)
    idx = np.arange(n)

    def vertex(m: NDArray, c0: NDArray, p: NDArray) -> NDArray:
        den = m - 2.0 * c0 + p
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(den < 0, 0.5 * (m - p) / den, 0.0)

    c0 = surf[idx, prc, pcc]
    dr = vertex(surf[idx, prc - 1, pcc], c0, surf[idx, prc + 1, pcc])
    dc = vertex(surf[idx, prc, pcc - 1], c0, surf[idx, prc, pcc + 1])
    half = (size - 1) // 2
    off_r = np.where(inner, pr - half + dr, np.nan)
    off_c = np.where(inner, pc - half + dc, np.nan)
    return off_r, off_c, best, second


def _lucas_kanade(
    a_win: NDArray[np.float32], sample_b, start_r: NDArray, start_c: NDArray, half: int
) -> tuple[NDArray, NDArray]:
    """Translation refinement: the position on ``b`` where its window, gain and offset
    matched, best equals ``a_win`` (Gauss–Newton on the windows, ``LK_ITERATIONS``)."""
    r, c = start_r.copy(), start_c.copy()
    a = a_win.astype(np.float64)
    a_mean, a_std = a.mean(axis=(1, 2), keepdims=True), a.std(axis=(1, 2), keepdims=True)
    for _ in range(LK_ITERATIONS):
        w = sample_b(r, c, half).astype(np.float64)
        s = w.std(axis=(1, 2), keepdims=True)
        w = (w - w.mean(axis=(1, 2), keepdims=True)) * (a_std / np.where(s > 0, s, 1.0)) + a_mean
        gr, gc = np.gradient(w, axis=(1, 2))
        e = a - w
        grr, gcc, grc = (gr * gr).sum((1, 2)), (gc * gc).sum((1, 2)), (gr * gc).sum((1, 2))
        br, bc = (gr * e).sum((1, 2)), (gc * e).sum((1, 2))
        det = grr * gcc - grc**2
        with np.errstate(divide="ignore", invalid="ignore"):
            r = r + (gcc * br - grc * bc) / det
            c = c + (grr * bc - grc * br) / det
    return r, c


def _sampler(b: MapView, to_b: Any) -> Any:
    """``sample_b(rows, cols, h, order)``: windows of ``b`` on ``a``'s grid around
    positions of ``a``'s grid (``to_b``: :func:`_b_of_a`); ``b``'s cubic B-spline
    coefficients computed once (map_coordinates would filter the whole image at every
    call)."""
    b_spline = ndimage.spline_filter(b.image, order=3, output=np.float32)

    def sample_b(rows: NDArray, cols: NDArray, h: int, order: int = 3) -> NDArray:
        g = np.arange(-h, h + 1, dtype=np.float64)
        rr, cc = np.broadcast_arrays(
            rows[:, None, None] + g[None, :, None], cols[:, None, None] + g[None, None, :]
        )
        br, bc = to_b(rr, cc)
        return ndimage.map_coordinates(
            b_spline if order == 3 else b.image,
            [br, bc],
            order=order,
            mode="constant",
            cval=np.nan,
            prefilter=False,
        ).astype(np.float32)

    return sample_b


def _global_shift(a: MapView, b: MapView, to_b: Any) -> tuple[float, float]:
    """Step 1: the shift of ``b`` on ``a``'s grid, by phase correlation on a decimated
    common grid: ``b(x) ≈ a(x − s)``, ``a``'s point ``x`` is at ``x + s``."""
    from levels.quality import image_shift_px

    step = max(1, int(np.ceil(max(a.image.shape) / 1024)))
    gr, gc = np.mgrid[0 : a.image.shape[0] : step, 0 : a.image.shape[1] : step].astype(float)
    br, bc = to_b(gr, gc)
    b_on_a = ndimage.map_coordinates(b.image, [br, bc], order=1, mode="constant", cval=np.nan)
    vb = ndimage.map_coordinates(b.valid.astype(np.float32), [br, bc], order=0, cval=0.0) == 1
    both = a.valid[::step, ::step] & vb & np.isfinite(b_on_a)
    if both.sum() < 64:
        raise GeometryError(f"{a.name} and {b.name}: their images do not overlap")
    s_r, s_c = image_shift_px(np.nan_to_num(b_on_a), a.image[::step, ::step], both)
    return s_r * step, s_c * step


def _corners(a: MapView, max_points: int, margin: int) -> tuple[NDArray, NDArray]:
    """Step 2: corners of ``a`` (rows, columns) whose window and search, ``margin`` pixels
    each way, lie on its valid pixels."""
    import cv2

    side = 2 * margin + 1
    mask = cv2.erode(a.valid.astype(np.uint8), np.ones((side, side), np.uint8))
    corners = cv2.goodFeaturesToTrack(
        a.image, maxCorners=max_points, qualityLevel=0.01, minDistance=MIN_DISTANCE_PX, mask=mask
    )
    if corners is None:
        raise GeometryError(f"{a.name}: no corner to match (a flat or invalid image)")
    pa = np.rint(corners[:, 0, ::-1]).astype(np.float64)  # (row, col)
    return pa[:, 0], pa[:, 1]


def _refuse(ok: NDArray[np.bool_], bad: NDArray[np.bool_], counts: dict, why: str) -> None:
    """Candidates still ``ok`` and ``bad`` are refused, counted under ``why``."""
    counts[why] = int((ok & bad).sum())
    ok &= ~bad


def _left_right(
    a: MapView, sample_b: Any, ok: NDArray, ra: NDArray, ca: NDArray, mr: NDArray,
    mc: NDArray, half: int,
) -> NDArray[np.bool_]:  # fmt: skip
    """Step 4: the matches whose window of ``b`` does not find ``a``'s point back (within
    ``BACK_MATCH_PX``, correlation ``MIN_NCC``)."""
    bad = np.zeros(ra.size, dtype=bool)
    if ok.any():
        back_t = sample_b(mr[ok], mc[ok], half, order=3)
        back_s = _windows(a.image, ra[ok], ca[ok], half + 2, order=0)
        b_r, b_c, b_best, _ = _ncc_peaks(np.nan_to_num(back_t), back_s)
        miss = np.hypot(b_r, b_c)  # the back-match's offset from where a's point is
        bad[np.flatnonzero(ok)[~(miss <= BACK_MATCH_PX) | ~(b_best >= MIN_NCC)]] = True
    return bad


def _approximate_ground(
    a: MapView, b: MapView, la: NDArray, cola: NDArray, lb: NDArray, colb: NDArray
) -> tuple[NDArray, NDArray, NDArray, NDArray]:
    """The mid-point of the two lines of sight (latitude, longitude, height) and their
    y-parallax. Lines that meet nowhere near the Earth (views from one track through the
    mirror converge by a few 1e-4 rad: their tie points tie the images, not the heights)
    get ``a``'s line of sight at its reference height instead."""
    from levels.geometry.ellipsoid import WGS84

    r1, u1 = a.model.sight(la, cola)
    r2, u2 = b.model.sight(lb, colb)
    mid, ypar = closest_approach(r1, u1, r2, u2)
    lat, lon, h = WGS84.to_geodetic(mid)
    h_lo, h_hi = EARTH_HEIGHTS_M
    wild = np.isfinite(h) & ((h < h_lo) | (h > h_hi))
    if wild.any():
        on_ref = a.model.image_to_ground(la[wild], cola[wild], a.reference_height_m)
        lat[wild], lon[wild], h[wild] = on_ref.lat_rad, on_ref.lon_rad, a.reference_height_m
    return lat, lon, h, ypar


def _off_plane(
    ypar: NDArray, h: NDArray, la: NDArray, cola: NDArray, res: float
) -> NDArray[np.bool_]:
    """Step 5: the matches off the y-parallax's plane over ``a``'s image (fitted robustly,
    Tukey's biweight): wrong matches, the two models' smooth error being a plane."""
    keep = np.isfinite(ypar) & np.isfinite(h)
    if keep.sum() < 3:
        return ~keep
    design = np.column_stack([np.ones(la.size), la / 1000.0, cola / 1000.0])
    w = keep.astype(float)
    for _ in range(10):  # iteratively reweighted: Tukey's biweight on the residuals
        coef, *_ = np.linalg.lstsq(design * w[:, None], ypar * w, rcond=None)
        resid = ypar - design @ coef
        mad = 1.4826 * np.median(np.abs(resid[keep]))
        scale = max(Y_PARALLAX_SIGMAS * mad, Y_PARALLAX_FLOOR_PX * res)
        u = resid / scale
        w = np.where(keep & (np.abs(u) < 1), (1 - u**2) ** 2, 0.0)
    return ~keep | (np.abs(resid) > scale)


def match_views(a: MapView, b: MapView, max_points: int = MAX_CANDIDATES) -> TiePoints:
    """Tie points between two overlapping views (module docstring)."""
    half, search = WINDOW_PX // 2, SEARCH_PX
    to_b = _b_of_a(a, b)
    sample_b = _sampler(b, to_b)
    shift_r, shift_c = _global_shift(a, b, to_b)
    ra, ca = _corners(a, max_points, half + search + 2)
    counts: dict[str, int] = {"candidates": int(ra.size)}
    pr, pc = ra + shift_r, ca + shift_c
    tpl = _windows(a.image, ra, ca, half, order=0)
    srch = sample_b(np.rint(pr), np.rint(pc), half + search, order=1)
    ok = np.ones(ra.size, dtype=bool)
    _refuse(ok, ~np.isfinite(srch).all(axis=(1, 2)), counts, "off_the_second_image")
    _refuse(ok, tpl.std(axis=(1, 2)) < MIN_STD, counts, "flat")

    # 3. correlation, uniqueness, sub-pixel
    off_r, off_c, best, second = (np.full(ra.size, np.nan) for _ in range(4))
    if ok.any():
        off_r[ok], off_c[ok], best[ok], second[ok] = _ncc_peaks(tpl[ok], np.nan_to_num(srch[ok]))
    _refuse(ok, ~(best >= MIN_NCC), counts, "low_correlation")
    _refuse(ok, (best - second < MIN_MARGIN) | ~np.isfinite(off_r), counts, "ambiguous")
    mr, mc = np.rint(pr) + off_r, np.rint(pc) + off_c  # on a's grid
    if ok.any():
        lr, lc = _lucas_kanade(tpl[ok], sample_b, mr[ok], mc[ok], half)
        moved = np.hypot(lr - mr[ok], lc - mc[ok])
        good = np.isfinite(moved) & (moved < 1.0)
        mr[ok], mc[ok] = np.where(good, lr, np.nan), np.where(good, lc, np.nan)
    _refuse(ok, ~np.isfinite(mr), counts, "refinement_diverged")
    _refuse(ok, _left_right(a, sample_b, ok, ra, ca, mr, mc, half), counts, "left_right")

    # to raw, the lines of sight, the y-parallax
    k = np.flatnonzero(ok)
    rb, cb = to_b(mr[k], mc[k])
    la, cola = a.geometry.raw_of(ra[k], ca[k])
    lb, colb = b.geometry.raw_of(rb, cb)
    lat, lon, h, ypar = _approximate_ground(a, b, la, cola, lb, colb)
    off_plane = _off_plane(ypar, h, la, cola, abs(a.geometry.map_grid.geotransform[1]))
    counts["off_the_model"] = int(off_plane.sum())
    good = ~off_plane
    counts["kept"] = int(good.sum())
    k = k[good]
    return TiePoints(
        a=a.name,
        b=b.name,
        hrv_a=a.hrv,
        hrv_b=b.hrv,
        line_a=la[good] + a.first_line,
        column_a=cola[good],
        line_b=lb[good] + b.first_line,
        column_b=colb[good],
        ncc=best[k],
        lat_rad=lat[good],
        lon_rad=lon[good],
        h_m=h[good],
        y_parallax_m=ypar[good],
        counts=counts,
        scene_a=a.scene,
        scene_b=b.scene,
    )
