"""Control points found on a reference ortho-image (issue 51): COSI-Corr's loop (Leprince
et al. 2007, IEEE TGRS 45(6), §III) on the processing centre's own models.

A user of an archive scene has a reference ortho-image (Sentinel-2 on ESA's GRI, Landsat
Tier 1) and a DEM, not points measured by hand. For each candidate point of the reference
(where it has texture, inside the scene):

1. **orthorectify a patch** of the raw image onto the reference's own grid with the current
   model: each reference pixel of a ``PATCH_PX``² window, its ground (the grid's map
   coordinates, the DEM's height), through :meth:`~levels.geometry.model.PushbroomModel.
   ground_to_image` to the raw image, sampled there (bilinear);
2. **measure its shift** against the reference window by phase correlation (a Hann window;
   the peak refined by an upsampled DFT to ``1 / UPSAMPLE`` px, Guizar-Sicairos et al.
   2008): the raw pixel the model puts at the window's centre ``p`` truly shows the ground
   the reference shows at ``p + s``;
3. that pixel and that ground (the reference's map position, the DEM's height there) make
   a **control point**, of σ the reference's stated accuracy on the ground (shared by all
   the points: level 2 adds it once to its prediction, :func:`levels.adjust.model.
   shared_sigma_m`) and ``MATCH_SIGMA_PX`` in the image;
4. **level 2's adjustment** refines the pass's model on the points (and rejects blunders,
   :mod:`levels.adjust`); the patches are made again on the refined model, until the mean
   shift (the median of the points' shifts: the model's, not each match's noise) is at most
   ``CONVERGED_PX`` (1/20 px) or ``MAX_LOOPS`` loops.

The result is the pass's control points (kind ``reference``, ``docs/gcp.md``) and, each
loop, the mean and largest shift: what COSI-Corr reports.
"""

from __future__ import annotations

import contextlib
import dataclasses
import logging
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
import pyproj
from numpy.typing import NDArray

from levels.adjust import Adjustment
from levels.adjust.model import REFERENCE_OWN_SIGMA_M
from levels.adjust.passes import say_refused
from levels.errors import GcpError
from levels.geo.maps import MapGrid
from levels.geo.scenes import PassGeometry, SceneGeometry
from levels.geometry.dem import Dem
from levels.options import ProcessingOptions
from levels.readers.gcp import ControlPointSet
from levels.readers.l0 import L0Archive

__all__ = [
    "CONVERGED_PX",
    "MATCH_SIGMA_PX",
    "MAX_LOOPS",
    "PATCH_PX",
    "Reference",
    "ReferenceInput",
    "ReferencePoints",
    "find_on_reference",
    "phase_shifts",
    "raw_images",
    "read_reference",
    "reference_control_points",
]

#: The window correlated at each point (reference pixels a side).
PATCH_PX = 32
#: Candidates: one per cell of this many reference pixels a side (at least), the most
#: textured; cells widened so that a reference has at most ``MAX_WINDOWS`` of them (a full
#: scene on a 10 m reference: 8000 windows took 52 s for a median error of 2.6 m; level 2
#: fits 12 parameters).
CELL_PX = 48
MAX_WINDOWS = 1200
#: A window's relative texture (standard deviation over mean) below which it is not used.
MIN_TEXTURE = 0.02
#: The upsampled DFT's factor: the shift's resolution is 1 / UPSAMPLE px.
UPSAMPLE = 50
#: The loop stops when the mean shift is at most this (COSI-Corr's 1/20 px) …
CONVERGED_PX = 0.05
#: … after at least this many (the system model's, and two on refined models: the
#: second refinement takes 0.04 px off level 2's checkpoints on the quickstart) …
MIN_LOOPS = 3
#: … or after this many loops.
MAX_LOOPS = 5
#: Matched windows a loop needs to go on: level 2's adjustment needs three points to fit
#: the attitude offsets at all (with the ephemeris held by its prior).
MIN_POINTS = 3
#: A loop whose median shift is beyond this (px) is coarse (:func:`_coarse`).
COARSE_PX = 1.0
#: A reference finer than this is first used at this pixel (m): a window of 32 of them
#: sees a model off by ±960 m (SPOT 1–4's system location: 350 m rms).
COARSE_PIXEL_M = 60.0
#: A measured point's σ in the image (raw pixels) is ``MATCH_SIGMA_PX · (1 − ρ) / ρ``, ρ
#: the phase correlation's peak: measured against the truth on the reduced quickstart at
#: 60 m (median error 0.14 px at ρ 0.4–0.6, 0.25 px at 0.3–0.4, 0.58 px at 0.2–0.3).
MATCH_SIGMA_PX = 0.12
#: The smallest σ a point is given (raw pixels).
MIN_SIGMA_PX = 0.02
#: A point that level 2's last adjustment misses by more than this many of its σ in the
#: image (on either axis) is not handed on (:func:`_kept`).
KEEP_SIGMAS = 3.0
#: Phase correlation's peak below which a window is taken as unmatched: below it, one
#: window in ten was off by 4 px or more (clouds, water, the wrong texture).
MIN_PEAK = 0.35


@dataclass(frozen=True, eq=False)
class Reference:
    """A reference ortho-image: its first band (NaN where it has none), map grid, stated
    accuracy on the ground (1σ per axis, m) and file."""

    image: NDArray[np.float32]
    grid: MapGrid
    sigma_m: float = 0.0
    source: str = ""


def raw_images(archive: L0Archive, band: str) -> Callable[[SceneGeometry], NDArray]:
    """``raw_of(scene)`` for :func:`reference_control_points`: the scene's rows of the
    archive's ``band``, calibrated (the 1A's values), NaN where not valid."""
    from levels.cor.radiometry import calibrate

    b = archive.bands[band]

    def raw_of(scene: SceneGeometry) -> NDArray:
        rows = slice(scene.cut.first_line, scene.cut.first_line + scene.cut.n_lines)
        valid = b.pixel_valid_rows(rows)
        image = calibrate(b.counts[rows], valid, b.gain, b.offset_counts).astype(np.float64)
        image[~valid] = np.nan
        return image

    return raw_of


def read_reference(path: str | Path, sigma_m: float = 0.0) -> Reference:
    """A north-up GeoTIFF (any GDAL raster) as a :class:`Reference`; its nodata as NaN."""
    import rasterio

    with rasterio.open(path) as ds:
        image = ds.read(1, masked=True).astype(np.float32).filled(np.nan)
        gt = ds.transform.to_gdal()
        crs = ds.crs.to_wkt() if ds.crs else ""
    if not crs:
        raise GcpError(f"{path}: a reference image needs a CRS (it has none)")
    grid = MapGrid(crs, gt, image.shape[0], image.shape[1])
    return Reference(image, grid, float(sigma_m), str(Path(path).name))


@dataclass
class ReferencePoints:
    """What :func:`reference_control_points` found: the points, the last loop's shift of
    each (reference pixels: row, column) and correlation peak, each loop's mean and
    largest shift, and the adjustment made on the points."""

    points: ControlPointSet
    shift_px: NDArray[np.float64]
    peak: NDArray[np.float64]
    loops: list[dict[str, float]] = field(default_factory=list)
    adjustment: Adjustment | None = None


def _sigma_px(peak: NDArray[np.float64]) -> NDArray[np.float64]:
    """A point's σ in the image from its correlation peak (``MATCH_SIGMA_PX``)."""
    rho = np.clip(peak, 1e-3, 1.0)
    return np.maximum(MATCH_SIGMA_PX * (1.0 - rho) / rho, MIN_SIGMA_PX)


def _hann(n: int) -> NDArray[np.float64]:
    w = np.hanning(n)
    return np.outer(w, w)


def phase_shifts(
    a: NDArray[np.floating], b: NDArray[np.floating]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The shift ``s`` (row, column; pixels) of each window pair, ``b(p) = a(p + s)``, and
    the phase correlation's peak: windows (N, W, W), NaN-free; the peak refined by an
    upsampled DFT over ±0.75 px at ``1 / UPSAMPLE`` px."""
    n, w, _ = a.shape
    win = _hann(w)

    def spectrum(x: NDArray) -> NDArray:
        x = x - x.mean(axis=(1, 2), keepdims=True)
        return np.fft.fft2(x * win)

    cross = spectrum(a) * np.conj(spectrum(b))
    cross /= np.abs(cross) + 1e-12
    corr = np.fft.ifft2(cross).real
    flat = corr.reshape(n, -1).argmax(axis=1)
    peak0 = np.stack(np.unravel_index(flat, (w, w)), axis=1).astype(np.float64)
    peak0 = np.where(peak0 > w // 2, peak0 - w, peak0)  # signed
    # upsampled DFT about the integer peak: CC(y, x) = Σ R(k, l) e^{i2π(ky + lx)/W}
    u = np.arange(-0.75, 0.75 + 1e-9, 1.0 / UPSAMPLE)
    freq = np.fft.fftfreq(w) * w
    ey = np.exp(2j * np.pi * (peak0[:, 0, None, None] + u[None, :, None]) * freq / w)
    ex = np.exp(2j * np.pi * (peak0[:, 1, None, None] + u[None, :, None]) * freq / w)
    fine = (ey @ cross @ np.swapaxes(ex, 1, 2)).real / (w * w)  # two batched products
    k = fine.reshape(n, -1).argmax(axis=1)
    iy, ix = np.unravel_index(k, fine.shape[1:])
    shift = peak0 + np.stack([u[iy], u[ix]], axis=1)
    return shift, fine.reshape(n, -1).max(axis=1)


def _candidates(ref: Reference, inside: Callable, half: int) -> tuple[NDArray, NDArray, float]:
    """The most textured window's centre in each ``CELL_PX`` cell of the reference, where
    ``inside(rows, cols)`` says the scene sees the whole window; cells of half a window
    where that gives fewer than ``MIN_CANDIDATES`` (a scene of a few kilometres at the
    coarse stage's 60 m, a reference three times coarser than the scene); and how much
    the windows overlap (their width over the cell's: each pixel then counts in that many
    squared, whose errors are one: each point's σ is widened by it, :func:`_measure`)."""
    from scipy.ndimage import uniform_filter

    img = np.nan_to_num(ref.image.astype(np.float64), nan=0.0)
    mean = uniform_filter(img, PATCH_PX)
    var = uniform_filter(img * img, PATCH_PX) - mean * mean
    texture = np.sqrt(np.maximum(var, 0.0)) / np.maximum(np.abs(mean), 1e-12)
    texture[np.isnan(uniform_filter(ref.image.astype(np.float64), PATCH_PX))] = 0.0
    nr, nc = ref.image.shape
    cell = max(CELL_PX, int(np.sqrt(nr * nc / MAX_WINDOWS)))
    rows, cols = _best_of_cells(texture, cell, half, inside)
    if rows.size < MIN_CANDIDATES:  # a small scene: windows half overlapping
        cell = PATCH_PX // 2
        rows, cols = _best_of_cells(texture, cell, half, inside)
    return rows, cols, max(1.0, PATCH_PX / cell)


#: Fewer candidates than this in the scene and the cells shrink to half a window.
MIN_CANDIDATES = 25


def _best_of_cells(
    texture: NDArray, cell: int, half: int, inside: Callable
) -> tuple[NDArray, NDArray]:
    nr, nc = texture.shape
    r0 = np.arange(half + 1, nr - half - 1 - cell + 1, cell)
    c0 = np.arange(half + 1, nc - half - 1 - cell + 1, cell)
    if not r0.size or not c0.size:
        return np.empty(0, np.int64), np.empty(0, np.int64)
    cells = texture[r0[0] : r0[-1] + cell, c0[0] : c0[-1] + cell]
    cells = cells.reshape(r0.size, cell, c0.size, cell).transpose(0, 2, 1, 3)
    best = cells.reshape(r0.size, c0.size, -1).argmax(axis=2)
    rows = (r0[:, None] + best // cell).ravel()
    cols = (c0[None, :] + best % cell).ravel()
    keep = texture[rows, cols] >= MIN_TEXTURE
    rows, cols = rows[keep], cols[keep]
    ok = inside(rows, cols)
    return rows[ok], cols[ok]


@dataclass(frozen=True, eq=False)
class _Windows:
    """The candidates of one scene: their reference pixel, its window's reference values
    and each window pixel's ground (geodetic, the DEM's ellipsoidal height)."""

    scene: int
    row: NDArray[np.int64]
    col: NDArray[np.int64]
    ref: NDArray[np.float64]  # (n, W, W)
    lat: NDArray[np.float64]  # (n, W, W) radians
    lon: NDArray[np.float64]
    h: NDArray[np.float64]
    #: Each window's σ widened by this (windows overlapping: :func:`_candidates`).
    overlap: float = 1.0


def _window_ground(ref: Reference, dem: Dem, rows: NDArray, cols: NDArray):
    """Each window pixel's reference value and ground (lat, lon in radians, height)."""
    half = PATCH_PX // 2
    d = np.arange(-half, PATCH_PX - half)
    r = rows[:, None, None] + d[None, :, None] + 0 * d[None, None, :]
    c = cols[:, None, None] + 0 * d[None, :, None] + d[None, None, :]
    values = ref.image[r, c].astype(np.float64)
    x, y = ref.grid.map_of(r, c)
    to_geo = pyproj.Transformer.from_crs(ref.grid.crs_wkt, "EPSG:4326", always_xy=True)
    lon, lat = (np.radians(v).reshape(r.shape) for v in to_geo.transform(x.ravel(), y.ravel()))
    return values, lat, lon, dem.heights(lat, lon)


#: Nodes a side of each window where the model is evaluated (at the window's lowest and
#: highest heights); its pixels between them bilinearly, linearly in height: the model
#: through 50 points a window instead of 1024 (a twentieth of the time; 1e-4 px).
NODES = 5


def _node_matrix(nodes: NDArray[np.int64]) -> NDArray[np.float64]:
    """(PATCH_PX, len(nodes)): linear weights of the window's pixels on its nodes (pixel
    indices, first and last included)."""
    x = np.arange(PATCH_PX, dtype=np.float64)
    k = np.clip(np.searchsorted(nodes, x, side="right") - 1, 0, nodes.size - 2)
    f = (x - nodes[k]) / (nodes[k + 1] - nodes[k])
    m = np.zeros((PATCH_PX, nodes.size))
    m[np.arange(PATCH_PX), k] = 1.0 - f
    m[np.arange(PATCH_PX), k + 1] = f
    return m


def _ortho(model, raw: NDArray, w: _Windows) -> NDArray:
    """The raw image on each window's reference pixels through ``model`` (bilinear; NaN
    where a pixel falls outside or on an invalid raw pixel); the model evaluated at the
    ``NODES``² nodes at the window's two extreme heights (``NODES``)."""
    from scipy.ndimage import map_coordinates

    nodes = np.rint(np.linspace(0, PATCH_PX - 1, NODES)).astype(int)
    lat = w.lat[:, nodes][:, :, nodes]
    lon = w.lon[:, nodes][:, :, nodes]
    lo = np.nanmin(w.h, axis=(1, 2))
    hi = np.maximum(np.nanmax(w.h, axis=(1, 2)), lo + 1.0)
    m = _node_matrix(nodes)
    grids = []
    for h in (lo, hi):
        ip = model.ground_to_image(lat, lon, np.broadcast_to(h[:, None, None], lat.shape))
        line = np.where(ip.converged, ip.line, np.nan).reshape(lat.shape)
        col = np.asarray(ip.column).reshape(lat.shape)
        grids.append([m @ line @ m.T, m @ col @ m.T])  # (n, W, W) each
    t = (w.h - lo[:, None, None]) / (hi - lo)[:, None, None]
    line = grids[0][0] + t * (grids[1][0] - grids[0][0])
    col = grids[0][1] + t * (grids[1][1] - grids[0][1])
    coords = np.stack(
        [np.nan_to_num(line, nan=-10.0).ravel(), np.nan_to_num(col, nan=-10.0).ravel()]
    )
    out = map_coordinates(raw, coords, order=1, cval=np.nan, mode="constant")
    return out.reshape(w.lat.shape)


def _centres(model, w: _Windows) -> tuple[NDArray, NDArray]:
    """The raw (line, column) of each candidate pixel through ``model``."""
    half = PATCH_PX // 2
    lat, lon, h = (a[:, half, half] for a in (w.lat, w.lon, w.h))
    ip = model.ground_to_image(lat, lon, h)
    return ip.line, ip.column


def reference_control_points(
    pg: PassGeometry,
    scenes: Sequence[SceneGeometry],
    raw_of: Callable[[SceneGeometry], NDArray],
    ref: Reference,
    dem: Dem,
    options: ProcessingOptions,
    hrv: int = 1,
    band: str | None = None,
) -> ReferencePoints:
    """Control points of a pass found on ``ref`` (module docstring). ``raw_of(scene)``: the
    scene's raw image (calibrated, float, NaN where not valid); ``scenes``: GEO's, on the
    system model; ``options``: level 2's (its priors and blunder threshold).

    A fine reference is first used at ``COARSE_PIXEL_M`` (its pixels averaged by blocks,
    the raw image smoothed alike): a system model hundreds of metres off is tens of fine
    pixels off, beyond what a window's correlation can see (half its width); the coarse
    loops bring it within a pixel, the fine loops finish."""
    with _said_once():
        raws = {k: raw_of(s) for k, s in enumerate(scenes)}
        raw_px = _raw_pixel_m(scenes[0])
        factor = max(1, round(COARSE_PIXEL_M / ref.grid.pixel_size_m))
        current, loops = list(scenes), []
        if factor > 1:
            coarse_ref = _coarser(ref, factor)
            f_raw = round(coarse_ref.grid.pixel_size_m / raw_px)
            coarse_raws = {k: _smoothed(r, f_raw) for k, r in raws.items()}
            found = _loop(
                pg,
                scenes,
                current,
                coarse_raws,
                coarse_ref,
                dem,
                options,
                hrv,
                band,
                until_px=COARSE_PX / 2,
            )
            loops += [{**loop, "scale": float(factor)} for loop in found.loops]
            assert found.adjustment is not None
            current = [found.adjustment.refine(pg, s) for s in scenes]
        f_raw = round(ref.grid.pixel_size_m / raw_px)  # a reference coarser than the scene
        fine = {k: _smoothed(r, f_raw) for k, r in raws.items()} if f_raw > 1 else raws
        found = _loop(pg, scenes, current, fine, ref, dem, options, hrv, band, until_px=0.0)
        found.loops = loops + [{**loop, "scale": 1.0} for loop in found.loops]
        found = _kept(found)
    adj = found.adjustment
    if adj is not None:  # the last fit's refusals, once (each loop refused them again)
        say_refused(list(adj.point_id), np.asarray(adj.point_status), adj.residual_before_px)
    return found


@contextlib.contextmanager
def _said_once() -> Iterator[None]:
    """Level 2's adjustment says each point it refuses; the loop fits the same points up to
    ``MAX_LOOPS`` times: silenced while it runs (:func:`reference_control_points` says the
    last fit's)."""
    log = logging.getLogger(say_refused.__module__)
    level = log.level
    log.setLevel(logging.ERROR)
    try:
        yield
    finally:
        log.setLevel(level)


def _kept(found: ReferencePoints) -> ReferencePoints:
    """The points level 2's last adjustment used and fits within ``KEEP_SIGMAS`` of their
    σ in the image on each axis: a window matched on a cloud's edge, or on another band's
    unlike texture, is a point off by a pixel that the blunder test of one loop may let
    pass; it is not handed on."""
    adj = found.adjustment
    if adj is None:
        return found
    status = dict(zip(adj.point_id, adj.point_status, strict=True))
    after = dict(zip(adj.point_id, np.abs(adj.residual_after_px), strict=True))
    g = found.points
    keep = np.array(
        [
            status.get(i) == "used"
            and bool(np.all(np.nan_to_num(after[i], nan=np.inf) <= KEEP_SIGMAS * g.sigma_px[k]))
            for k, i in enumerate(g.id)
        ]
    )
    if keep.sum() < 3:
        raise GcpError(
            f"of {len(keep)} windows matched on the reference, {int(keep.sum())} fit the "
            "refined model: too few control points (clouds, another band's texture?)"
        )
    found.points = found.points._subset(keep)
    found.shift_px, found.peak = found.shift_px[keep], found.peak[keep]
    return found


def _raw_pixel_m(scene: SceneGeometry) -> float:
    """The ground size of a raw pixel at the scene's centre (m; the mean of a line step
    and a column step on the reference surface)."""
    m = scene.model
    line, col = 0.5 * (scene.cut.n_lines - 1), 0.5 * (m.n_columns - 1)
    g = m.image_to_ground(
        np.array([line, line + 1, line]), np.array([col, col, col + 1]), scene.reference_height_m
    )
    from levels.geometry.ellipsoid import WGS84

    p = WGS84.to_ecef(g.lat_rad, g.lon_rad, g.h_m)
    return float(0.5 * (np.linalg.norm(p[1] - p[0]) + np.linalg.norm(p[2] - p[0])))


def _coarser(ref: Reference, f: int) -> Reference:
    """The reference at ``f`` times its pixel: each block's mean (NaN if any is)."""
    n, m = (ref.image.shape[0] // f) * f, (ref.image.shape[1] // f) * f
    blocks = ref.image[:n, :m].astype(np.float64).reshape(n // f, f, m // f, f)
    gt = ref.grid.geotransform
    grid = MapGrid(ref.grid.crs_wkt, (gt[0], gt[1] * f, 0.0, gt[3], 0.0, gt[5] * f), n // f, m // f)
    return Reference(blocks.mean(axis=(1, 3)).astype(np.float32), grid, ref.sigma_m, ref.source)


def _smoothed(raw: NDArray, f: int) -> NDArray:
    """The raw image averaged over about ``f`` × ``f`` pixels (to a reference's coarser
    pixel), over an odd width so that each pixel stays at its place; as it is for
    ``f`` ≤ 1."""
    if f <= 1:
        return raw
    from scipy.ndimage import uniform_filter

    return np.asarray(uniform_filter(raw, f | 1, mode="nearest"))  # odd: centred


def _loop(
    pg: PassGeometry,
    scenes: Sequence[SceneGeometry],
    current: list[SceneGeometry],
    raws: dict[int, NDArray],
    ref: Reference,
    dem: Dem,
    options: ProcessingOptions,
    hrv: int,
    band: str | None,
    until_px: float,
) -> ReferencePoints:
    """Measure, adjust, measure again on the refined model (module docstring, 1–4) on one
    reference: until the median shift is ``CONVERGED_PX`` (``MIN_LOOPS`` loops at least),
    or ``until_px`` (a coarse stage), or ``MAX_LOOPS`` loops."""
    windows = _scene_windows(current, ref, dem)
    scale = ref.grid.pixel_size_m / _raw_pixel_m(scenes[0])  # reference px → raw px
    if sum(w.row.size for w in windows) < 3:
        raise GcpError(
            f"the reference {ref.source or ''} overlaps the scenes in fewer than 3 textured "
            "windows: too few control points can be found on it"
        )
    loops: list[dict[str, float]] = []
    while True:
        gcps, shift, peak, to_raw = _measure(windows, current, raws, ref, dem, hrv, scale)
        if len(gcps) < MIN_POINTS:
            n_windows = sum(w.row.size for w in windows)
            raise GcpError(
                f"{len(gcps)} of {n_windows} windows matched the reference "
                f"{ref.source or ''} (loop {len(loops) + 1}; its {ref.grid.pixel_size_m:g} m "
                f"pixel is {scale:.2g} raw pixels): too few control points to refine the "
                f"model (at least {MIN_POINTS}); the scene is too small or too coarse for "
                "this reference, or shows too little of it"
            )
        mean = float(np.hypot(*np.median(shift, axis=0)))  # the model's, not the noise's
        loops.append(
            {
                "mean_shift_px": mean,
                "point_shift_px": float(np.mean(np.hypot(*shift.T))),
                "max_shift_px": float(np.max(np.hypot(*shift.T))),
                "points": float(len(gcps)),
            }
        )
        coarse = until_px > 0 or mean > COARSE_PX  # the model at large, not each point
        gcps = _coarse(gcps, shift, to_raw) if coarse else _scattered(gcps, shift, to_raw)
        gcps, adjustment = _adjusted(pg, scenes, gcps, options, band)
        done = mean <= CONVERGED_PX and len(loops) >= MIN_LOOPS
        if done or mean <= until_px or len(loops) >= MAX_LOOPS:
            return ReferencePoints(gcps, shift, peak, loops, adjustment)
        current = [adjustment.refine(pg, s) for s in scenes]


#: Fits made again with σ widened by σ0 before a failing χ² test is the answer.
REFITS = 3


def _adjusted(
    pg: PassGeometry,
    scenes: Sequence[SceneGeometry],
    gcps: ControlPointSet,
    options: ProcessingOptions,
    band: str | None,
) -> tuple[ControlPointSet, Adjustment]:
    """Level 2's adjustment on the points; a fit that fails its χ² test is made again (up to
    ``REFITS`` times) with each point's σ in the image times the fit's σ0 (its a posteriori
    variance factor: the matches' σ are estimates, from the peak and the loop's scatter,
    and a reference of another season or view can make every match noisier than they
    say); the points handed on carry the widened σ."""
    from levels.adjust import adjust
    from levels.errors import FitRefused

    for _ in range(REFITS):
        try:
            return gcps, adjust(pg, list(scenes), gcps, options, band)
        except FitRefused as e:  # each refit may reject other blunders: σ0 moves again
            gcps = _with_sigma_px(gcps, gcps.sigma_px * e.sigma0)
    return gcps, adjust(pg, list(scenes), gcps, options, band)


def _with_sigma_px(g: ControlPointSet, sigma_px: NDArray[np.float64]) -> ControlPointSet:
    return replace(g, sigma_px=sigma_px)


def _scattered(
    gcps: ControlPointSet, shift: NDArray[np.float64], to_raw: NDArray[np.float64]
) -> ControlPointSet:
    """The points, each σ in the image at least the loop's own scatter of shifts about
    their median (1.4826 MAD, per axis): on a refined model what is left is the matches'
    noise, which the peak alone underrates where the image is noisy or its texture weak
    (a full P scene on a 10 m reference: 0.15–0.24 px). Over ten draws of full P scenes
    over the SRTM tile, level 2's error is then 1.11 of what its adjustment predicts, at
    nadir and at 27° (0.81–1.36; ``tools/reference_draws.py --full``). The
    shifts are in reference pixels: ``to_raw`` makes them raw pixels (and widens them
    where windows overlap and share their errors, :func:`_candidates`)."""
    med = np.median(shift, axis=0)
    per_axis = 1.4826 * np.median(np.abs(shift - med), axis=0)
    spread = float(np.sqrt(np.mean(per_axis**2)))  # σ is per axis
    return _with_sigma_px(gcps, np.maximum(gcps.sigma_px, spread * to_raw))


def _coarse(
    gcps: ControlPointSet, shift: NDArray[np.float64], to_raw: NDArray[np.float64]
) -> ControlPointSet:
    """A loop whose windows are far off their place (median shift beyond ``COARSE_PX``):
    its points within 3 robust σ of the median shift, each point's σ in the image that
    spread (1.4826 MAD per axis): the windows overlap their references only in part, and
    what this loop must take off is the model's error at large, not each point's."""
    med = np.median(shift, axis=0)
    spread = 1.4826 * np.median(np.abs(shift - med), axis=0) + MATCH_SIGMA_PX
    keep = np.all(np.abs(shift - med) <= 3.0 * spread, axis=1)
    k = np.flatnonzero(keep)
    sub = gcps._subset(keep)
    sigma = np.hypot(sub.sigma_px, float(np.hypot(*spread)) * to_raw[keep])
    return _with_sigma_px(sub, sigma) if k.size >= 3 else gcps


def _scene_windows(scenes: Sequence[SceneGeometry], ref: Reference, dem: Dem) -> list[_Windows]:
    """Each scene's candidates (a candidate in two scenes: the first's)."""
    half = PATCH_PX // 2
    taken = np.zeros(ref.image.shape, dtype=bool)
    to_geo = pyproj.Transformer.from_crs(ref.grid.crs_wkt, "EPSG:4326", always_xy=True)
    out = []
    for k, scene in enumerate(scenes):
        model = scene.model

        def inside(rows: NDArray, cols: NDArray, model=model) -> NDArray:
            corners = [(-half, -half), (-half, half), (half, -half), (half, half)]
            ok = ~taken[rows, cols]
            for dr, dc in corners:
                x, y = ref.grid.map_of(rows + dr, cols + dc)
                lon, lat = (np.radians(v) for v in to_geo.transform(x, y))
                ip = model.ground_to_image(lat, lon, dem.heights(lat, lon))
                ok &= ip.converged & (ip.line >= 2) & (ip.line <= model.n_lines - 3)
                ok &= (ip.column >= 2) & (ip.column <= model.n_columns - 3)
            return ok

        rows, cols, overlap = _candidates(ref, inside, half)
        if not rows.size:
            continue
        taken[rows, cols] = True
        values, lat, lon, h = _window_ground(ref, dem, rows, cols)
        good = np.isfinite(values).all(axis=(1, 2)) & np.isfinite(h).all(axis=(1, 2))
        sub = (rows[good], cols[good], values[good], lat[good], lon[good], h[good])
        out.append(_Windows(k, *sub, overlap))
    return out


def _measure(
    windows: list[_Windows],
    scenes: Sequence[SceneGeometry],
    raws: dict[int, NDArray],
    ref: Reference,
    dem: Dem,
    hrv: int,
    scale: float,
) -> tuple[ControlPointSet, NDArray, NDArray, NDArray]:
    """One loop's measurement (module docstring, 1–3): the points, their shifts (reference
    pixels), peaks, and what makes a σ in reference pixels one in raw pixels (``scale``,
    their sizes' ratio, times the windows' overlap, :func:`_candidates`)."""
    to_geo = pyproj.Transformer.from_crs(ref.grid.crs_wkt, "EPSG:4326", always_xy=True)
    parts = []
    for w in windows:
        scene = scenes[w.scene]
        ortho = _ortho(scene.model, raws[w.scene], w)
        ok = np.isfinite(ortho).all(axis=(1, 2))
        if not ok.any():
            continue
        shift, peak = phase_shifts(w.ref[ok], ortho[ok])
        line, col = _centres(scene.model, w)
        x, y = ref.grid.map_of(w.row[ok] + shift[:, 0], w.col[ok] + shift[:, 1])
        lon, lat = (np.radians(v) for v in to_geo.transform(x, y))
        matched = peak >= MIN_PEAK
        parts.append(
            (
                [f"ref_{w.scene}_{r}_{c}" for r, c in zip(w.row[ok], w.col[ok], strict=True)],
                lon,
                lat,
                dem.heights(lat, lon),
                line[ok] + scene.cut.first_line,
                col[ok],
                shift,
                peak,
                matched,
                np.full(shift.shape[0], w.overlap * scale),
            )
        )
    if not parts:
        raise GcpError(f"no window of the reference {ref.source or ''} could be matched")
    ids = [i for p in parts for i in p[0]]
    cat = [np.concatenate([p[k] for p in parts]) for k in range(1, 10)]
    lon, lat, h, line, col, shift, peak, matched, to_raw = cat
    matched = matched.astype(bool)
    n = len(ids)
    gcps = ControlPointSet(
        tuple(np.array(ids)[matched]),
        lon[matched],
        lat[matched],
        h[matched],
        line[matched],
        col[matched],
        np.full(n, max(ref.sigma_m, REFERENCE_OWN_SIGMA_M))[matched],
        np.full(n, 5.0)[matched],
        # the matcher's σ from its peak; a window far off its place overlaps its reference
        # only in part: its σ grows with the shift (a tenth of it) until the model is refined
        (to_raw * np.hypot(_sigma_px(peak), 0.1 * np.hypot(*shift.T)))[matched],
        np.full(n, hrv, dtype=np.int64)[matched],
        reference=np.ones(int(matched.sum()), dtype=bool),
    )
    return gcps, shift[matched], peak[matched], to_raw[matched]


@dataclass(frozen=True, eq=False)
class ReferenceInput:
    """A pass's control points to be found on a reference ortho-image over a DEM: a node
    of the plan before level 2's adjustment, on GEO's set-up of the pass (made once)."""

    reference: Reference
    dem: Dem


def find_on_reference(
    archive: L0Archive,
    pg: PassGeometry,
    scenes: Sequence[SceneGeometry],
    given: ReferenceInput,
    options: ProcessingOptions,
) -> ReferencePoints:
    """:func:`reference_control_points` of an archive's scenes placed by GEO (its first
    band), the points as their file records them (:meth:`ControlPointSet.as_recorded`)."""
    band = next(iter(archive.bands))
    found = reference_control_points(
        pg,
        scenes,
        raw_images(archive, band),
        given.reference,
        given.dem,
        options,
        archive.hrv,
        band,
    )
    return dataclasses.replace(found, points=found.points.as_recorded())
