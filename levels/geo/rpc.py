"""The algebraic sensor model: rational polynomial coefficients (RPC00B) fitted to the
rigorous one, as GDAL, QGIS, OTB, ASP and s2p read them.

An RPC gives the image position of a ground point as ratios of cubic polynomials in its
normalised latitude ``P``, longitude ``L`` and height ``H`` (Tao & Hu 2001; the NITF RPC00B
term order, which GDAL's ``RPC`` metadata domain uses)::

    line   = LINE_OFF + LINE_SCALE · Num_L(P, L, H) / Den_L(P, L, H)
    sample = SAMP_OFF + SAMP_SCALE · Num_S(P, L, H) / Den_S(P, L, H)

with ``P = (lat − LAT_OFF) / LAT_SCALE`` (degrees), the same for the longitude and the
height (metres above the ellipsoid), and (line, sample) = (0, 0) the centre of the first
pixel: the project's own (line, column) convention.

**The fit** (terrain-independent, Tao & Hu's "terrain-independent scenario"): the rigorous
model puts a lattice of image points on several heights spanning the terrain; each of line
and sample is then a linear least-squares problem in the 39 unknowns (the denominator's
constant term is 1) once both sides are multiplied by the denominator, solved again with
each equation weighted by the last denominator (which makes the residual the image error),
with a Tikhonov term that keeps the nearly collinear cubic terms bounded. Of a few Tikhonov
weights and the plain cubic polynomial, the fit with the smallest largest error on a
choice lattice (a third of a cell off the fitting one) is kept, for line and sample apart:
a denominator that crosses zero between the fitting points is caught there. The fit's
error is measured, never assumed: on a third lattice, half a cell off the fitting one in
every axis (image and height), against the rigorous model, in pixels, and it is stored
with the coefficients.

PHOTOMOD (paper ``003_…``) compares the physical and the algebraic model of a scene:
:func:`fit_rpc` and :meth:`Rpc.image_of` are that comparison's algebraic side.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from levels.errors import GeometryError
from levels.geo.level1b import Level1BGeometry
from levels.geometry.ellipsoid import WGS84
from levels.geometry.model import PushbroomModel
from levels.threads import one_blas_thread

if TYPE_CHECKING:
    from levels.geometry.dem import Dem

__all__ = [
    "RPC_CHECK_LATTICE",
    "RPC_FIT_LATTICE",
    "RPC_HEIGHT_LEVELS",
    "RPC_HEIGHT_MARGIN_M",
    "Rpc",
    "fit_rpc",
    "ground_on_dem",
    "rpc_of_1b",
    "rpc_of_model",
    "rpc_terms",
]

#: The inverse (:meth:`Rpc.ground_of`) stops once the image position is this close (px),
#: or after this many Newton steps (it takes 3–4 from the RPC's centre).
INVERSE_TOL_PX = 1e-8
INVERSE_MAX_ITERATIONS = 20
#: Heights the DEM intersection (:func:`ground_on_dem`) iterates to (m), in at most so many
#: steps: each takes the DEM's height under the last ground point.
DEM_TOL_M = 1e-3
DEM_MAX_ITERATIONS = 30

#: Height range of a product's RPCs without a DEM: the reference height ± this (m).
RPC_HEIGHT_MARGIN_M = 1000.0
#: Image points per side of the fitting lattice, and its height levels.
RPC_FIT_LATTICE = 21
RPC_HEIGHT_LEVELS = 7
#: Image points per side of the check lattice (half a cell off the fitting one).
RPC_CHECK_LATTICE = 20
#: The fits tried, each line and sample apart (module docstring): rational with these
#: Tikhonov weights (relative to the normalised problem, unknowns of order 1), and the
#: cubic polynomial (``None``). Too light a weight lets a denominator cross zero between
#: lattice points (tens of pixels there); too heavy biases the fit.
_RIDGES = (1e-9, 1e-7, 1e-5, None)
#: Image points per side of the lattice that chooses among the fits (a third of a cell off
#: the fitting one: the check lattice stays apart from the choice).
_CHOICE_LATTICE = 16
_SCALARS = (
    "line_off",
    "samp_off",
    "lat_off",
    "lon_off",
    "height_off",
    "line_scale",
    "samp_scale",
    "lat_scale",
    "lon_scale",
    "height_scale",
)
#: GDAL's RPC metadata names of the scalars above, in the same order.
_GDAL_NAMES = (
    "LINE_OFF",
    "SAMP_OFF",
    "LAT_OFF",
    "LONG_OFF",
    "HEIGHT_OFF",
    "LINE_SCALE",
    "SAMP_SCALE",
    "LAT_SCALE",
    "LONG_SCALE",
    "HEIGHT_SCALE",
)
_COEFFS = ("line_num", "line_den", "samp_num", "samp_den")
_GDAL_COEFFS = ("LINE_NUM_COEFF", "LINE_DEN_COEFF", "SAMP_NUM_COEFF", "SAMP_DEN_COEFF")


def rpc_terms(
    p: NDArray[np.float64], lon: NDArray[np.float64], h: NDArray[np.float64]
) -> NDArray[np.float64]:
    """The 20 RPC00B terms of normalised latitude ``p``, longitude ``lon``, height ``h``,
    shape ``(20, *p.shape)``, in the standard's order."""
    one = np.ones_like(p)
    return np.stack(
        [
            one,
            lon,
            p,
            h,
            lon * p,
            lon * h,
            p * h,
            lon * lon,
            p * p,
            h * h,
            p * lon * h,
            lon**3,
            lon * p * p,
            lon * h * h,
            lon * lon * p,
            p**3,
            p * h * h,
            lon * lon * h,
            p * p * h,
            h**3,
        ]
    )


@dataclass(frozen=True, eq=False)
class Rpc:
    """An RPC00B model: offsets and scales (degrees, metres, pixels), the four sets of 20
    coefficients, and the fit's measured error against the rigorous model (pixels, over
    the image and the height range it was fitted on)."""

    line_off: float
    samp_off: float
    lat_off: float
    lon_off: float
    height_off: float
    line_scale: float
    samp_scale: float
    lat_scale: float
    lon_scale: float
    height_scale: float
    line_num: NDArray[np.float64]
    line_den: NDArray[np.float64]
    samp_num: NDArray[np.float64]
    samp_den: NDArray[np.float64]
    fit_error_px: dict[str, float]

    def image_of(
        self, lat_deg: ArrayLike, lon_deg: ArrayLike, height_m: ArrayLike
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Image (line, sample) of ground points (degrees, metres above the ellipsoid); a
        longitude is taken within 180° of ``lon_off`` whichever turn it is given in
        (179.99° E is −180.01°: a scene across the antimeridian), as GDAL does."""
        lat, lon, h = np.broadcast_arrays(
            *(np.asarray(x, dtype=np.float64) for x in (lat_deg, lon_deg, height_m))
        )
        t = rpc_terms(
            (lat - self.lat_off) / self.lat_scale,
            wrap_degrees(lon - self.lon_off) / self.lon_scale,
            (h - self.height_off) / self.height_scale,
        )
        line = np.tensordot(self.line_num, t, 1) / np.tensordot(self.line_den, t, 1)
        samp = np.tensordot(self.samp_num, t, 1) / np.tensordot(self.samp_den, t, 1)
        return self.line_off + self.line_scale * line, self.samp_off + self.samp_scale * samp

    def ground_of(
        self, line: ArrayLike, sample: ArrayLike, height_m: ArrayLike
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Latitude and longitude (degrees) of image points at heights (m above the
        ellipsoid): :meth:`image_of` inverted by Newton's method (its Jacobian by finite
        differences, all points at once), from the RPC's centre, until the image position
        is within ``INVERSE_TOL_PX``; NaN where it does not converge (off the RPC's
        validity, a denominator's zero). Longitudes within [−180°, 180°)."""
        ln, sm, h = np.broadcast_arrays(
            *(np.asarray(x, dtype=np.float64) for x in (line, sample, height_m))
        )
        lat = np.full(ln.shape, self.lat_off)
        lon = np.full(ln.shape, self.lon_off)
        d_lat, d_lon = 1e-7 * abs(self.lat_scale), 1e-7 * abs(self.lon_scale)
        done = np.zeros(ln.shape, dtype=bool)
        for _ in range(INVERSE_MAX_ITERATIONS):
            l0, s0 = self.image_of(lat, lon, h)
            el, es = ln - l0, sm - s0
            done = np.abs(el) + np.abs(es) < INVERSE_TOL_PX
            if done.all():
                break
            l1, s1 = self.image_of(lat + d_lat, lon, h)
            l2, s2 = self.image_of(lat, lon + d_lon, h)
            a, b = (l1 - l0) / d_lat, (l2 - l0) / d_lon
            c, d = (s1 - s0) / d_lat, (s2 - s0) / d_lon
            det = a * d - b * c
            with np.errstate(divide="ignore", invalid="ignore"):
                lat = np.where(done, lat, lat + (d * el - b * es) / det)
                lon = np.where(done, lon, lon + (a * es - c * el) / det)
        bad = ~done | ~np.isfinite(lat) | ~np.isfinite(lon)
        return np.where(bad, np.nan, lat), np.where(bad, np.nan, wrap_degrees(lon))

    def gdal_metadata(self) -> dict[str, str]:
        """GDAL's ``RPC`` metadata domain (what ``rasterio``'s ``RPC.to_gdal`` gives), with
        the validity box and the fit's error: ``ERR_RAND`` is RPC00B's random error in
        metres on the ground (:meth:`random_error_m`); ``ERR_BIAS`` −1, unknown (the bias is
        the rigorous model's, not the fit's)."""
        md = {
            name: repr(float(getattr(self, attr)))
            for name, attr in zip(_GDAL_NAMES, _SCALARS, strict=True)
        }
        for name, attr in zip(_GDAL_COEFFS, _COEFFS, strict=True):
            md[name] = " ".join(repr(float(c)) for c in getattr(self, attr))
        md["MIN_LAT"] = repr(self.lat_off - self.lat_scale)
        md["MAX_LAT"] = repr(self.lat_off + self.lat_scale)
        md["MIN_LONG"] = repr(self.lon_off - self.lon_scale)
        md["MAX_LONG"] = repr(self.lon_off + self.lon_scale)
        md["ERR_BIAS"] = "-1.0"
        md["ERR_RAND"] = repr(self.random_error_m())
        return md

    def ground_sample_m(self) -> float:
        """The ground size of a pixel at the RPC's centre (m): the square root of the area
        one pixel covers, from the RPC's own Jacobian over the local east and north."""
        lat, lon, h = self.lat_off, self.lon_off, self.height_off
        d = 1e-5  # degrees: a metre or so, well inside the rational function's smoothness
        # metres per degree north and east: WGS84's meridian and prime-vertical radii
        w = 1.0 - WGS84.e2 * np.sin(np.radians(lat)) ** 2
        m_lat = np.radians(WGS84.a_m * (1.0 - WGS84.e2) / w**1.5)
        m_lon = np.radians(WGS84.a_m / np.sqrt(w) * np.cos(np.radians(lat)))
        l0, s0 = self.image_of(lat, lon, h)
        ln, sn = self.image_of(lat + d, lon, h)
        le, se = self.image_of(lat, lon + d, h)
        jac = np.array([[le - l0, ln - l0], [se - s0, sn - s0]]) / (d * np.array([m_lon, m_lat]))
        return float(1.0 / np.sqrt(abs(np.linalg.det(jac))))

    def random_error_m(self) -> float:
        """The fit's RMS error on the ground (m): its RMS in pixels (``fit_error_px``) times
        :meth:`ground_sample_m`; −1 (RPC00B's "unknown") when the fit was not measured."""
        rms = self.fit_error_px.get("rms_px")
        if rms is None:
            return -1.0
        return float(rms) * self.ground_sample_m()

    def ossim_geom(self, n_lines: int, n_samples: int, bands: Sequence[str] = ("P",)) -> str:
        """The OSSIM keyword list of these RPCs (``type: ossimRpcModel``, RPC00B's
        ``polynomial_format: B``, GDAL's names in lower case, ``line_num_coeff_00`` …): the
        ``<image>.geom`` OTB 8 reads beside an image (its ``GeomMetadataSupplier``; it
        reads RPC tags only from the GeoTIFFs it wrote itself). Every line ``key: value``,
        none empty (OTB's reader splits each on ``:``)."""
        lines = [
            "type: ossimRpcModel",
            "polynomial_format: B",
            f"bias_error: {0.0!r}",
            f"rand_error: {max(self.random_error_m(), 0.0)!r}",
            f"image_size: {n_samples} {n_lines}",
            f"support_data.number_bands: {len(bands)}",
            f"support_data.band_name_list: {' '.join(bands)}",
        ]
        for name, attr in zip(_GDAL_NAMES, _SCALARS, strict=True):
            lines.append(f"{name.lower()}: {float(getattr(self, attr))!r}")
        for name, attr in zip(_GDAL_COEFFS, _COEFFS, strict=True):
            lines += [
                f"{name.lower()}_{k:02d}: {float(c)!r}" for k, c in enumerate(getattr(self, attr))
            ]
        return "\n".join(lines) + "\n"

    def rpc_txt(self) -> str:
        """The ``<image>_RPC.TXT`` sidecar GDAL reads next to an image (``KEY: value``)."""
        units = {"LINE": "pixels", "SAMP": "pixels", "LAT": "degrees", "LONG": "degrees"}
        lines = []
        for name, attr in zip(_GDAL_NAMES, _SCALARS, strict=True):
            unit = units.get(name.split("_")[0], "meters")
            lines.append(f"{name}: {float(getattr(self, attr))!r} {unit}")
        for name, attr in zip(_GDAL_COEFFS, _COEFFS, strict=True):
            for k, c in enumerate(getattr(self, attr), start=1):
                lines.append(f"{name}_{k}: {float(c)!r}")
        return "\n".join(lines) + "\n"

    def rpb(self) -> str:
        """The ``<image>.RPB`` sidecar (DigitalGlobe's keyword file, which GDAL reads too);
        ``errRand`` in metres as :meth:`gdal_metadata`'s ``ERR_RAND``."""
        keys = (
            "lineOffset",
            "sampOffset",
            "latOffset",
            "longOffset",
            "heightOffset",
            "lineScale",
            "sampScale",
            "latScale",
            "longScale",
            "heightScale",
        )
        rows = ['satId = "SPOT";', 'SpecId = "RPC00B";', "BEGIN_GROUP = IMAGE"]
        rows.append("\terrBias = -1.0;")
        rows.append(f"\terrRand = {self.random_error_m()!r};")
        for key, attr in zip(keys, _SCALARS, strict=True):
            rows.append(f"\t{key} = {float(getattr(self, attr))!r};")
        for key, attr in zip(
            ("lineNumCoef", "lineDenCoef", "sampNumCoef", "sampDenCoef"), _COEFFS, strict=True
        ):
            values = ",\n".join(f"\t\t\t{float(c):+.15e}" for c in getattr(self, attr))
            rows.append(f"\t{key} = (\n{values});")
        rows += ["END_GROUP = IMAGE", "END;"]
        return "\n".join(rows) + "\n"

    def product_tree(self) -> dict[str, object]:
        tree: dict[str, object] = {k: float(getattr(self, k)) for k in _SCALARS}
        tree.update({k: np.asarray(getattr(self, k), dtype=np.float64) for k in _COEFFS})
        tree["fit_error_px"] = {k: float(v) for k, v in self.fit_error_px.items()}
        tree["convention"] = "RPC00B; (line, sample) = (0, 0) at the centre of the first pixel"
        return tree

    @classmethod
    def from_tree(cls, tree: dict[str, Any]) -> Rpc:
        fields: dict[str, Any] = {k: float(tree[k]) for k in _SCALARS}
        fields.update({k: np.asarray(tree[k], dtype=np.float64) for k in _COEFFS})
        errors = {k: float(v) for k, v in tree.get("fit_error_px", {}).items()}
        return cls(**fields, fit_error_px=errors)


def ground_on_dem(
    rpc: Rpc, line: ArrayLike, sample: ArrayLike, dem: Dem, start_m: float | None = None
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Latitude, longitude (degrees) and height (m) where image points' rays meet a DEM
    (:class:`levels.geometry.dem.Dem`, ellipsoidal heights through its datum): the ground
    point at a height, then the DEM's height there, again, until the height moves less
    than ``DEM_TOL_M`` (it contracts when the terrain's slope times the view angle's
    tangent is under 1, as everywhere a satellite sees). NaN on voids and off the DEM."""
    ln, sm = np.broadcast_arrays(np.asarray(line, float), np.asarray(sample, float))
    h = np.full(ln.shape, rpc.height_off if start_m is None else float(start_m))
    lat = lon = np.full(ln.shape, np.nan)
    for _ in range(DEM_MAX_ITERATIONS):
        lat, lon = rpc.ground_of(ln, sm, h)
        new = dem.heights(np.radians(lat), np.radians(lon))
        moved = np.abs(new - h)
        h = new
        if not np.any(moved > DEM_TOL_M):  # NaN (voids) compare False: done there
            break
    lat, lon = rpc.ground_of(ln, sm, h)
    bad = ~np.isfinite(h)
    return np.where(bad, np.nan, lat), np.where(bad, np.nan, lon), h


def wrap_degrees(angle: ArrayLike) -> Any:
    """An angle in degrees within [-180°, 180°)."""
    return (np.asarray(angle, dtype=np.float64) + 180.0) % 360.0 - 180.0


def _solve(
    t: NDArray[np.float64], target: NDArray[np.float64], ridge: float | None
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Numerator and denominator (constant term 1) with ``target ≈ Num / Den`` at the
    points whose terms are ``t`` (20 × N): linearised, then reweighted by the denominator,
    with a Tikhonov term of weight ``ridge``; ``None``: a cubic polynomial (``Den = 1``)."""
    x: NDArray[np.float64]
    if ridge is None:
        x = np.linalg.lstsq(t.T, target, rcond=None)[0].astype(np.float64, copy=False)
        return x, np.concatenate([[1.0], np.zeros(19)])
    a = np.concatenate([t.T, -target[:, None] * t[1:].T], axis=1)  # N × 39
    damp = np.sqrt(ridge * a.shape[0]) * np.eye(a.shape[1])
    w = np.ones(target.size)
    for _ in range(3):
        aw = np.concatenate([a * w[:, None], damp])
        bw = np.concatenate([target * w, np.zeros(a.shape[1])])
        x = np.linalg.lstsq(aw, bw, rcond=None)[0].astype(np.float64, copy=False)
        w = 1.0 / np.abs(1.0 + x[20:] @ t[1:])
    return x[:20], np.concatenate([[1.0], x[20:]])


@one_blas_thread
def fit_rpc(
    to_ground: Callable[
        [NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]],
        tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_]],
    ],
    n_lines: int,
    n_columns: int,
    heights_m: tuple[float, float],
) -> Rpc:
    """RPCs of an image of ``n_lines × n_columns`` whose rigorous model ``to_ground(line,
    column, height)`` gives (lat, lon in degrees, ok), over the height range ``heights_m``
    (module docstring); their error measured on the check lattice."""
    h_lo, h_hi = float(heights_m[0]), float(heights_m[1])
    if not (np.isfinite(h_lo) and np.isfinite(h_hi) and h_hi >= h_lo):
        raise GeometryError(f"RPC fit: height range {heights_m} is not a range")
    if h_hi - h_lo < 1.0:  # a flat scene: the height terms still need a span
        h_lo, h_hi = h_lo - 50.0, h_hi + 50.0
    box = (n_lines, n_columns, h_lo, h_hi)
    line, col, h = _lattice(RPC_FIT_LATTICE, RPC_HEIGHT_LEVELS, 0.0, box)
    lat, lon, ok = to_ground(line, col, h)
    if ok.sum() < 100:
        raise GeometryError(f"RPC fit: only {int(ok.sum())} lattice points reach the ground")
    line, col, h, lat, lon = (x[ok] for x in (line, col, h, lat, lon))
    # longitudes unwrapped around the first point (a scene across the antimeridian has
    # them on both sides of ±180°), the offset then back within [-180°, 180°)
    lon = lon[0] + wrap_degrees(lon - lon[0])
    lat_off, lon_off = float(np.mean(lat)), float(wrap_degrees(np.mean(lon)))
    lon = lon_off + wrap_degrees(lon - lon_off)
    scales = {
        "lat_scale": float(np.max(np.abs(lat - lat_off))),
        "lon_scale": float(np.max(np.abs(lon - lon_off))),
        "height_scale": 0.5 * (h_hi - h_lo),
        "line_scale": 0.5 * (n_lines - 1) if n_lines > 1 else 1.0,
        "samp_scale": 0.5 * (n_columns - 1) if n_columns > 1 else 1.0,
    }
    offsets = {
        "lat_off": lat_off,
        "lon_off": lon_off,
        "height_off": 0.5 * (h_lo + h_hi),
        "line_off": 0.5 * (n_lines - 1),
        "samp_off": 0.5 * (n_columns - 1),
    }

    def normalised(lat: NDArray, lon: NDArray, h: NDArray) -> Any:
        return rpc_terms(
            (lat - lat_off) / scales["lat_scale"],
            wrap_degrees(lon - lon_off) / scales["lon_scale"],
            (h - offsets["height_off"]) / scales["height_scale"],
        )

    t = normalised(lat, lon, h)
    sl, sc, sh = _lattice(_CHOICE_LATTICE, RPC_HEIGHT_LEVELS - 1, 1.0 / 3.0, box)
    slat, slon, sok = to_ground(sl, sc, sh)
    st = normalised(slat[sok], slon[sok], sh[sok])
    fitted = {}
    for axis, target, choice in (
        ("line", (line - offsets["line_off"]) / scales["line_scale"], sl[sok]),
        ("samp", (col - offsets["samp_off"]) / scales["samp_scale"], sc[sok]),
    ):
        off, scale = offsets[f"{axis}_off"], scales[f"{axis}_scale"]
        fitted[f"{axis}_num"], fitted[f"{axis}_den"] = _best_ratio(
            t, target, st, off, scale, choice
        )
    parts: dict[str, Any] = {**offsets, **scales, **fitted}
    rpc = Rpc(**parts, fit_error_px={})
    return replace(rpc, fit_error_px=_fit_error(rpc, to_ground, box))


def _lattice(
    n: int, n_h: int, offset: float, box: tuple[int, int, float, float]
) -> tuple[NDArray, NDArray, NDArray]:
    """Lines, columns and heights of an ``n × n × n_h`` lattice over the image and the
    height range ``box = (n_lines, n_columns, h_lo, h_hi)``: its ends on the box's edges
    (``offset`` 0), or ``offset`` of a cell inside them."""
    n_lines, n_columns, h_lo, h_hi = box
    f = (np.arange(n) + offset) / (n - 1 + 2 * offset) if offset else np.linspace(0, 1, n)
    fh = (np.arange(n_h) + offset) / (n_h - 1 + 2 * offset) if offset else np.linspace(0, 1, n_h)
    ll, cc, hh = np.meshgrid(
        f * (n_lines - 1), f * (n_columns - 1), h_lo + fh * (h_hi - h_lo), indexing="ij"
    )
    return ll.ravel(), cc.ravel(), hh.ravel()


def _best_ratio(
    t: NDArray[np.float64],
    target: NDArray[np.float64],
    st: NDArray[np.float64],
    off: float,
    scale: float,
    choice: NDArray[np.float64],
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Numerator and denominator of one image axis: of the fits over :data:`_RIDGES`, the
    one whose worst error on the choice lattice (terms ``st``, true coordinate ``choice``)
    is least; a denominator near zero or changing sign there rules a fit out."""
    best = None
    for ridge in _RIDGES:
        num, den = _solve(t, target, ridge)
        d = den @ st
        worst = (
            np.inf
            if np.min(np.abs(d)) < 0.1 or np.any(np.sign(d) != np.sign(d[0]))
            else np.max(np.abs(off + scale * (num @ st) / d - choice))
        )
        if best is None or worst < best[0]:
            best = (worst, num, den)
    assert best is not None
    return best[1], best[2]


def _fit_error(
    rpc: Rpc,
    to_ground: Callable[
        [NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]],
        tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_]],
    ],
    box: tuple[int, int, float, float],
) -> dict[str, float]:
    """The RPCs' error against the rigorous model, half a cell off the fitting lattice in
    every axis."""
    cl, cc, ch = _lattice(RPC_CHECK_LATTICE, RPC_HEIGHT_LEVELS - 1, 0.5, box)
    clat, clon, cok = to_ground(cl, cc, ch)
    pl, pc = rpc.image_of(clat[cok], clon[cok], ch[cok])
    e = np.hypot(pl - cl[cok], pc - cc[cok])
    return {
        "rms_px": float(np.sqrt(np.mean(e**2))),
        "max_px": float(np.max(e)),
        "line_max_px": float(np.max(np.abs(pl - cl[cok]))),
        "sample_max_px": float(np.max(np.abs(pc - cc[cok]))),
        "n_points": int(cok.sum()),
        "height_min_m": box[2],
        "height_max_m": box[3],
    }


def _ground_of(
    model: PushbroomModel,
    raw_of: Callable[[NDArray, NDArray], tuple[NDArray, NDArray]] | None = None,
) -> Callable[[NDArray, NDArray, NDArray], tuple[NDArray, NDArray, NDArray]]:
    """:func:`fit_rpc`'s ``to_ground`` of an image whose (line, column) ``raw_of`` takes to
    the model's raw image (the raw image itself by default)."""

    def to_ground(line: NDArray, col: NDArray, h: NDArray) -> tuple[NDArray, NDArray, NDArray]:
        if raw_of is not None:
            line, col = raw_of(line, col)
        g = model.image_to_ground(line, col, h)
        return np.degrees(g.lat_rad), np.degrees(g.lon_rad), g.ok

    return to_ground


def rpc_of_model(model: PushbroomModel, heights_m: tuple[float, float]) -> Rpc:
    """RPCs of a rigorous model's image (its lines and columns) over ``heights_m``."""
    return fit_rpc(_ground_of(model), model.n_lines, model.n_columns, heights_m)


def rpc_of_1b(model: PushbroomModel, g1b: Level1BGeometry, heights_m: tuple[float, float]) -> Rpc:
    """RPCs of a level 1B image: its (I, J) to the raw image through INPE's polynomials
    (:class:`levels.geo.level1b.Level1BGeometry`), then to the ground by the model."""
    return fit_rpc(_ground_of(model, g1b.raw_of), g1b.n_rows, g1b.n_cols, heights_m)
