"""SAR geocoding by range–Doppler (ADRIN, paper ``001_…`` §5): a detected slant-range image
and its annotation onto a map, on the ellipsoid (GEC) or over a DEM (GTC).

**Pixel location** (ground → image). A ground point ``p`` (ECEF, fixed on the Earth) is
imaged on the line whose time ``t`` solves the Doppler equation

    Fdc − 2 (p − s)·(ṗ − ṡ) / (λ |p − s|) = 0,        ṗ = 0 in the Earth-fixed frame,

(``s``, ``ṡ`` the satellite's position and Earth-fixed velocity from the annotation's state
vectors, 8-point Lagrange; ``Fdc`` the Doppler centroid the image was focused to, a
polynomial in slant range; ``λ`` the wavelength), and on the column ``j`` of the range
equation ``r0 + mr·j − |p − s(t)| = 0`` (``r0`` the near range, ``mr`` the range spacing).
The time is found by Newton's method (the derivative with the acceleration from the
velocity's difference over 1 ms), from the frame's middle: converged to 1e-10 s (a
millionth of a line) in four to five steps.

**Image location** (image → ground, for footprints): the point at slant range ``R`` on the
Doppler cone of line ``t``, at a given height: its look angle about the velocity found by
Newton's method on the geodetic height.

**Geocoding** (the indirect method, as level 3): an output map grid; at anchors every
``ANCHOR_STEP_PX`` output pixels and at ``HEIGHT_LEVELS`` heights spanning the terrain
(one, the reference height, for GEC), the exact (line, column) of the map point; per
output pixel its height (GEC: the reference; GTC: the DEM bilinearly in its own grid,
:mod:`levels.geo.level3`'s sampling), the anchors bilinearly, the levels by Lagrange in
height (as a polynomial), and the slant image bilinearly there. The anchor grid's error
against the exact location is measured on a lattice between the anchors and returned.

**Layover and shadow** over a DEM (:func:`layover_and_shadow`'s definitions): the
terrain's zero-Doppler profiles sampled along the image's lines (:func:`_profiles`), each
output pixel judged against them inside the geocoding kernel; :func:`layover_and_shadow`
itself, on continuous profiles of scattered terrain points, is the truth's.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from typing import Any

import numba as nb
import numpy as np
import pyproj
from numpy.typing import ArrayLike, NDArray

from levels.errors import GeometryError
from levels.geo.inverse_grid import bilinear_grid
from levels.geo.maps import MapGrid, map_crs
from levels.geometry.dem import Dem
from levels.geometry.ellipsoid import WGS84
from levels.geometry.ephemeris import Ephemeris
from levels.geometry.times import Epoch
from levels.threads import over_blocks

__all__ = [
    "ANCHOR_STEP_PX",
    "HEIGHT_LEVELS",
    "MASK_TOLERANCE_PX",
    "SPEED_OF_LIGHT_M_PER_S",
    "Geocoded",
    "SarAnnotation",
    "SarImage",
    "frame_grid",
    "geocode",
    "layover_and_shadow",
    "line_spacing_m",
    "mask_oversample",
    "nominal_cell_m2",
    "splat_bilinear",
    "terrain_flattening",
]

SPEED_OF_LIGHT_M_PER_S = 299_792_458.0
#: Output pixels between anchors of the geocoding grid.
ANCHOR_STEP_PX = 16
#: Heights of the anchors over a DEM (Lagrange in height through them).
HEIGHT_LEVELS = 3
#: Range (and look angle, as range at the near range) by which terrain must fold before
#: it is layover (or shadow), in range samples: the profiles' interpolation between lines
#: errs by less, the anchors' by a thousandth of a sample.
MASK_TOLERANCE_PX = 0.05
#: Newton's steps at most, and the time step at which it stops (s).
_ITERATIONS, _T_TOL_S = 12, 1e-10


@nb.njit(cache=True, nogil=True)
def _kernel_locate(lo, hi, p, t_nodes, states, n_points, doppler, r0, lam, t, r, ok, s):
    """Points ``lo … hi − 1``: the time ``t`` (in: first guesses) solving the Doppler
    equation by Newton's method, the slant range ``r`` and the antenna's position ``s``
    then, ``ok`` where it converged (module docstring). The states (position, velocity)
    by ``n_points``-point Lagrange on the window of nodes about the instant (as
    :func:`levels.geometry.ephemeris.lagrange_interpolate`, NaN outside the nodes); the
    acceleration (Newton's derivative) from the velocity's difference over 1 ms at the
    first step, kept after (it changes by nothing over the next steps); the position at
    the last step's end to first order (a step of 1e-10 s moves it by 1e-6 m)."""
    n = t_nodes.size
    m = min(n_points, n)
    w = np.empty(m)
    st = np.empty(6)
    acc = np.zeros(3)
    for q in range(lo, hi):
        tq = t[q]
        step = np.inf
        rq = np.nan
        for it in range(_ITERATIONS):
            for e in range(2 if it == 0 else 1):  # at t, and 1 ms on for the acceleration
                te = tq + 1e-3 * e
                if not (t_nodes[0] <= te <= t_nodes[n - 1]):
                    if e == 0:
                        st[:] = np.nan
                    else:
                        acc[:] = np.nan
                else:
                    a, b = 0, n  # the first node after te
                    while a < b:
                        c = (a + b) // 2
                        if t_nodes[c] <= te:
                            a = c + 1
                        else:
                            b = c
                    k0 = min(max(a - m // 2, 0), n - m)
                    for j in range(m):
                        wj = 1.0
                        for i in range(m):
                            if i != j:
                                wj *= (te - t_nodes[k0 + i]) / (t_nodes[k0 + j] - t_nodes[k0 + i])
                        w[j] = wj
                    for c in range(6):
                        v = 0.0
                        for j in range(m):
                            v += w[j] * states[k0 + j, c]
                        if e == 0:
                            st[c] = v
                        elif c >= 3:
                            acc[c - 3] = (v - st[c]) / 1e-3
            dx, dy, dz = p[q, 0] - st[0], p[q, 1] - st[1], p[q, 2] - st[2]
            rq = np.sqrt(dx * dx + dy * dy + dz * dz)
            x = (rq - r0) / 1000.0
            fdc = 0.0
            for c in range(doppler.size - 1, -1, -1):
                fdc = fdc * x + doppler[c]
            f = fdc + 2.0 * (dx * st[3] + dy * st[4] + dz * st[5]) / (lam * rq)
            dfdt = (
                2.0
                * (
                    dx * acc[0]
                    + dy * acc[1]
                    + dz * acc[2]
                    - (st[3] * st[3] + st[4] * st[4] + st[5] * st[5])
                )
                / (lam * rq)
            )
            step = f / dfdt
            tq -= step
            for c in range(3):
                st[c] -= st[c + 3] * step
            if not abs(step) > _T_TOL_S:
                break
        dx, dy, dz = p[q, 0] - st[0], p[q, 1] - st[1], p[q, 2] - st[2]
        rq = np.sqrt(dx * dx + dy * dy + dz * dz)
        t[q] = tq
        r[q] = rq
        ok[q] = rq == rq and abs(step) <= _T_TOL_S
        for c in range(3):
            s[q, c] = st[c]


@dataclass(frozen=True, eq=False)
class SarAnnotation:
    """What comes with a detected slant-range image (ADRIN's input): state vectors (ECEF,
    Earth-fixed velocity, seconds since ``epoch``), the first line's time and the line
    interval, the near range and the range spacing, the wavelength, the Doppler centroid
    (``Fdc = Σ c_k ((R − r0) / 1 km)^k``, Hz), the image's shape and its looks."""

    epoch: Epoch
    state_t_s: NDArray[np.float64]
    state_r_m: NDArray[np.float64]
    state_v_m_per_s: NDArray[np.float64]
    first_line_s: float
    line_interval_s: float
    near_range_m: float
    range_spacing_m: float
    wavelength_m: float
    doppler_hz: tuple[float, ...]
    shape: tuple[int, int]
    looks: float = 1.0
    right_looking: bool = True

    def __post_init__(self) -> None:
        if self.line_interval_s <= 0 or self.range_spacing_m <= 0 or self.wavelength_m <= 0:
            raise GeometryError(
                "a SAR annotation needs a positive line interval, range spacing and wavelength"
            )
        object.__setattr__(
            self,
            "_ephemeris",
            Ephemeris(self.state_t_s, self.state_r_m, self.state_v_m_per_s),
        )

    @property
    def ephemeris(self) -> Ephemeris:
        """The state vectors, interpolated by 8-point Lagrange."""
        return self._ephemeris  # type: ignore[attr-defined]

    def doppler_at(self, r_m: ArrayLike) -> NDArray[np.float64]:
        """The Doppler centroid (Hz) at slant ranges ``r_m``."""
        x = (np.asarray(r_m, dtype=np.float64) - self.near_range_m) / 1000.0
        out = np.zeros_like(x)
        for c in reversed(self.doppler_hz):
            out = out * x + c
        return out

    def line_of(self, t_s: ArrayLike) -> NDArray[np.float64]:
        """Image line of times (s since the epoch)."""
        return (np.asarray(t_s, dtype=np.float64) - self.first_line_s) / self.line_interval_s

    def column_of(self, r_m: ArrayLike) -> NDArray[np.float64]:
        """Image column of slant ranges (m)."""
        return (np.asarray(r_m, dtype=np.float64) - self.near_range_m) / self.range_spacing_m

    def locate(
        self, p_ecef: ArrayLike, t0_s: ArrayLike | None = None
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_]]:
        """Time (s since the epoch), slant range (m) and convergence of ground points
        ``p`` (N, 3): the Doppler and range equations (module docstring), Newton's method
        from ``t0_s`` (first guesses, NaN for none) or the frame's middle."""
        t, r, ok, _ = self._solve(np.atleast_2d(np.asarray(p_ecef, dtype=np.float64)), t0_s)
        return t, r, ok

    def _solve(
        self, p: NDArray, t0_s: ArrayLike | None
    ) -> tuple[NDArray, NDArray, NDArray, NDArray]:
        """:meth:`locate`, and the antenna's positions then (:func:`_kernel_locate`)."""
        middle = self.first_line_s + 0.5 * self.shape[0] * self.line_interval_s
        t = np.full(p.shape[0], middle) if t0_s is None else np.ravel(t0_s).astype(np.float64)
        t = np.where(np.isfinite(t), t, middle)
        eph = self.ephemeris
        states = np.ascontiguousarray(np.hstack([eph.r_ecef_m, eph.v_ecef_m_per_s]))
        r = np.empty(p.shape[0])
        ok = np.empty(p.shape[0], dtype=np.bool_)
        s = np.empty(p.shape)
        over_blocks(
            _kernel_locate,
            p.shape[0],
            np.ascontiguousarray(p, dtype=np.float64),
            np.asarray(eph.t_s, dtype=np.float64),
            states,
            int(eph.n_points),
            np.asarray(self.doppler_hz, dtype=np.float64),
            self.near_range_m,
            self.wavelength_m,
            t,
            r,
            ok,
            s,
            grain=4096,
        )
        return t, r, ok, s

    def image_of(
        self, lat_rad: ArrayLike, lon_rad: ArrayLike, h_m: ArrayLike
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(line, column) of geodetic points; NaN where the location did not converge."""
        p = WGS84.to_ecef(lat_rad, lon_rad, h_m)
        shape = p.shape[:-1]
        t, r, ok = self.locate(p.reshape(-1, 3))
        line = np.where(ok, self.line_of(t), np.nan).reshape(shape)
        return line, np.where(ok, self.column_of(r), np.nan).reshape(shape)

    def incidence(
        self, lat_rad: ArrayLike, lon_rad: ArrayLike, h_m: ArrayLike
    ) -> NDArray[np.float64]:
        """Incidence on the ellipsoid (rad): between the geodetic vertical of ground points
        and their line of sight to the antenna when it images them."""
        p = WGS84.to_ecef(lat_rad, lon_rad, h_m)
        shape = p.shape[:-1]
        t, r, _ = self.locate(p.reshape(-1, 3))
        s, _ = self.ephemeris.interpolate(t)
        los = (s - p.reshape(-1, 3)) / r[:, None]
        up = WGS84.up(np.ravel(lat_rad), np.ravel(lon_rad))
        return np.arccos(np.clip(np.sum(los * up, axis=1), -1.0, 1.0)).reshape(shape)

    def edge_ground(self, height_m: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Latitude and longitude (rad) of 9 points along each of the image's four edges,
        at ``height_m``: its footprint's outline."""
        n_l, n_s = self.shape
        e = np.linspace(0.0, 1.0, 9)
        lines = np.concatenate([e * (n_l - 1), e * (n_l - 1), 0 * e, 0 * e + n_l - 1])
        cols = np.concatenate([0 * e, 0 * e + n_s - 1, e * (n_s - 1), e * (n_s - 1)])
        return self.ground_of_image(lines, cols, height_m)

    def ground_of_image(
        self, line: ArrayLike, column: ArrayLike, h_m: ArrayLike
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Geodetic (lat, lon) (rad) seen at image (line, column), at height ``h_m``: the
        point at that slant range on the line's Doppler cone, on the side the antenna
        looks (module docstring)."""
        ln, col, h = np.broadcast_arrays(
            *(np.asarray(x, dtype=np.float64) for x in (line, column, h_m))
        )
        t = self.first_line_s + ln.ravel() * self.line_interval_s
        r = self.near_range_m + col.ravel() * self.range_spacing_m
        s, sd = self.ephemeris.interpolate(t)
        speed = np.linalg.norm(sd, axis=1)
        vh = sd / speed[:, None]
        # along the velocity: from Fdc = −2 (p − s)·ṡ / (λ r)... (p − s)·v̂ = −Fdc λ r / (2 |ṡ|)
        along = -self.doppler_at(r) * self.wavelength_m * r / (2.0 * speed)
        down = -s / np.linalg.norm(s, axis=1, keepdims=True)
        down -= np.sum(down * vh, axis=1, keepdims=True) * vh
        down /= np.linalg.norm(down, axis=1, keepdims=True)
        side = np.cross(vh, -down) * (1.0 if self.right_looking else -1.0)
        across = np.sqrt(np.maximum(r * r - along * along, 0.0))
        alt = np.linalg.norm(s, axis=1) - WGS84.a_m
        look = np.arccos(np.clip(alt / np.maximum(r, alt + 1.0), -1.0, 1.0))  # flat Earth
        target = h.ravel()
        for _ in range(20):
            p = (
                s
                + along[:, None] * vh
                + across[:, None] * (np.cos(look)[:, None] * down + np.sin(look)[:, None] * side)
            )
            lat_p, lon_p, hp = WGS84.to_geodetic(p)
            dp = across[:, None] * (-np.sin(look)[:, None] * down + np.cos(look)[:, None] * side)
            dh = np.sum(dp * WGS84.up(lat_p, lon_p), axis=1)
            move = (hp - target) / dh
            look = look - move
            if np.max(np.abs(move)) < 1e-12:
                break
        lat, lon, _ = WGS84.to_geodetic(p)
        return lat.reshape(ln.shape), lon.reshape(ln.shape)


@dataclass(frozen=True, eq=False)
class SarImage:
    """A detected slant-range image (intensity, lines × samples) and its annotation."""

    annotation: SarAnnotation
    intensity: NDArray[np.float32]

    def __post_init__(self) -> None:
        if self.intensity.shape != tuple(self.annotation.shape):
            raise GeometryError(
                f"a SAR image {self.intensity.shape} for an annotation of {self.annotation.shape}"
            )


@dataclass(frozen=True, eq=False)
class _Model:
    """The geocoding's model of an image: its anchors' (line, column, look) every ``step``
    output pixels as polynomials in the scaled height (:func:`_in_height`) through the
    height ``levels``, and the image's shape."""

    coef: NDArray[np.float64]
    step: int
    levels: NDArray[np.float64]
    image_shape: tuple[int, int]

    @property
    def h_mid(self) -> float:
        return float(np.mean(self.levels))

    @property
    def inv_span(self) -> float:
        return 1.0 / _half_span(self.levels)

    def at(self, i: NDArray, j: NDArray, h: NDArray) -> tuple[NDArray, NDArray]:
        """(line, column) of output pixels ``(i, j)`` at heights ``h``: the kernel's
        arithmetic in numpy (the anchors bilinearly, the polynomial at ``h``)."""
        rows, cols = (np.arange(n, dtype=np.float64) * self.step for n in self.coef.shape[2:])
        x = (np.asarray(h, dtype=np.float64) - self.h_mid) * self.inv_span
        out = []
        for q in range(2):
            v = np.zeros(np.shape(i))
            for k in range(self.coef.shape[0] - 1, -1, -1):  # Horner
                v = v * x + bilinear_grid(rows, cols, self.coef[k, q], i, j)
            out.append(v)
        return out[0], out[1]


def _geocode_rows(
    model: _Model,
    height: NDArray[np.float32],
    surface: tuple[NDArray, NDArray, float, float] | None = None,
    image: NDArray | None = None,
    out: NDArray[np.float32] | None = None,
    located: tuple[NDArray, NDArray] | None = None,
    masks: tuple[NDArray, NDArray, float, float] | None = None,
) -> tuple[NDArray[np.bool_], NDArray[np.bool_]]:
    """:func:`_kernel_geocode` over the output's rows on threads: the heights from the DEM
    ``surface`` (:func:`_dem_surface`) into ``height``, or read from it; the ``image``
    into ``out``; the location into ``located``; the layover and shadow masks against
    ``masks`` (profiles, frame, tolerances: :func:`_profiles`), returned (1 × 1
    without)."""
    n_rows, n_cols = height.shape
    none2, none3 = np.empty((1, 1)), np.empty((2, 2, 3), dtype=np.float32)
    nodes, z = (surface[0], surface[1]) if surface is not None else (np.zeros((2, 2, 2)), none2)
    profiles, frame, tol_r, tol_look = masks or (none3, np.array([0.0, 1.0, 0.0, 1.0]), 0.0, 0.0)
    shape = (n_rows, n_cols) if masks is not None else (1, 1)
    layover, shadow = np.zeros(shape, dtype=np.bool_), np.zeros(shape, dtype=np.bool_)
    image32 = none2.astype(np.float32) if image is None else image
    from levels.geo.level3 import DEM_COORD_STEP

    over_blocks(
        _kernel_geocode,
        n_rows,
        model.step,
        model.coef,
        model.h_mid,
        model.inv_span,
        (model.levels - model.h_mid) * model.inv_span,
        model.image_shape,
        nodes,
        DEM_COORD_STEP,
        z,
        surface is not None,
        height,
        np.ascontiguousarray(image32, dtype=np.float32),
        out is not None,
        out if out is not None else image32,
        located is not None,
        *(located or (none2, none2)),
        masks is not None,
        profiles,
        frame,
        tol_r,
        tol_look,
        layover,
        shadow,
        grain=64,
    )
    return layover, shadow


@dataclass(frozen=True, eq=False)
class Geocoded:
    """A geocoded SAR image: intensity on a map grid (NaN outside the frame or over a
    void), each pixel's height (float32: a millimetre; NaN outside the frame over a DEM),
    the anchor grid's error (slant pixels), and the layover and shadow masks of the
    terrain the DEM gives (:func:`layover_and_shadow`'s definitions; none on the
    ellipsoid); each pixel's (line, column) in the slant image on first asking (the
    geocoding's own arithmetic, from its anchors: 1.5 GB for a full frame that the
    product does not hold)."""

    grid: MapGrid
    intensity: NDArray[np.float32]
    height_m: NDArray[np.float32]
    kind: str  # "GEC" or "GTC"
    anchor_error: dict[str, float]
    layover: NDArray[np.bool_]
    shadow: NDArray[np.bool_]
    #: the anchors' polynomials in height (the geocoding's model of the image)
    model: _Model = field(repr=False)

    @cached_property
    def _located(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        line, col = (np.empty(self.grid.shape) for _ in range(2))
        _geocode_rows(self.model, self.height_m, located=(line, col))
        return line, col

    @property
    def line(self) -> NDArray[np.float64]:
        """Each pixel's line in the slant image (NaN over a void)."""
        return self._located[0]

    @property
    def column(self) -> NDArray[np.float64]:
        """Each pixel's column in the slant image (NaN over a void)."""
        return self._located[1]


def frame_grid(
    ann: SarAnnotation, pixel_size_m: float, height_m: float = 0.0, margin_m: float = 0.0
) -> MapGrid:
    """A north-up UTM grid (the zone of the frame's centre) of ``pixel_size_m`` covering the
    frame's footprint at ``height_m``, widened by ``margin_m`` each side."""
    lat, lon = ann.edge_ground(height_m)
    crs = map_crs("utm", float(np.mean(lat)), float(np.mean(lon)))
    to_map = pyproj.Transformer.from_crs(pyproj.CRS.from_epsg(4326), crs, always_xy=True)
    x, y = to_map.transform(np.degrees(lon), np.degrees(lat))
    res = float(pixel_size_m)
    x0 = np.floor((np.min(x) - margin_m) / res) * res
    y1 = np.ceil((np.max(y) + margin_m) / res) * res
    n_cols = int(np.ceil((np.max(x) + margin_m - x0) / res))
    n_rows = int(np.ceil((y1 - np.min(y) + margin_m) / res))
    return MapGrid.north_up(crs.to_wkt(), x0, y1, res, n_rows, n_cols)


def _to_geo(grid: MapGrid) -> pyproj.Transformer:
    return pyproj.Transformer.from_crs(
        pyproj.CRS.from_wkt(grid.crs_wkt), pyproj.CRS.from_epsg(4326), always_xy=True
    )


def _exact(
    ann: SarAnnotation,
    grid: MapGrid,
    i: NDArray,
    j: NDArray,
    h: NDArray,
    t0_s: NDArray | None = None,
) -> tuple[NDArray, NDArray, NDArray, NDArray]:
    """The exact (line, column) of output pixels ``(i, j)`` at heights ``h``, the look
    angle there (rad, at the antenna from its geocentric nadir) and the time (s), from
    first guesses ``t0_s`` of it."""
    x, y = grid.map_of(i, j)
    lon, lat = _to_geo(grid).transform(np.ravel(x), np.ravel(y))
    return _exact_geo(ann, np.radians(lat), np.radians(lon), np.ravel(h), np.shape(i), t0_s)


def _exact_geo(
    ann: SarAnnotation,
    lat: NDArray,
    lon: NDArray,
    h: NDArray,
    shape: tuple[int, ...],
    t0_s: NDArray | None = None,
) -> tuple[NDArray, NDArray, NDArray, NDArray]:
    """:func:`_exact` of geodetic points (rad, flat), shaped ``shape``."""
    p = WGS84.to_ecef(lat, lon, h)
    t, r, ok, s = ann._solve(p, t0_s)
    cos_look = np.sum(-s * (p - s), axis=1) / (np.linalg.norm(s, axis=1) * r)
    look = np.arccos(np.clip(cos_look, -1.0, 1.0))
    line = np.where(ok, ann.line_of(t), np.nan).reshape(shape)
    col = np.where(ok, ann.column_of(r), np.nan).reshape(shape)
    return line, col, np.where(ok, look, np.nan).reshape(shape), t.reshape(shape)


def _anchors(
    ann: SarAnnotation, grid: MapGrid, step_px: int, levels: NDArray
) -> NDArray[np.float64]:
    """The exact (line, column, look) of the anchors (every ``step_px`` output pixels, one
    step beyond the grid) at each height level, ``(levels, 3, rows, columns)``. Newton's
    first guesses: every eighth anchor solved from the frame's middle, the times between
    bilinearly; each level then from the level before."""
    na = -(-(grid.n_rows - 1) // step_px) + 2
    nb = -(-(grid.n_cols - 1) // step_px) + 2
    ai, aj = np.meshgrid(
        np.arange(na, dtype=np.float64) * step_px,
        np.arange(nb, dtype=np.float64) * step_px,
        indexing="ij",
    )
    x, y = grid.map_of(ai, aj)
    lon, lat = (np.radians(v) for v in _to_geo(grid).transform(np.ravel(x), np.ravel(y)))
    coarse = (slice(None, None, 8), slice(None, None, 8))
    lat_c, lon_c = (v.reshape(ai.shape)[coarse] for v in (lat, lon))
    h_c = np.full(lat_c.size, levels[0])
    t_c = _exact_geo(ann, lat_c.ravel(), lon_c.ravel(), h_c, lat_c.shape)[3]
    t = None
    if min(t_c.shape) > 1:
        t = bilinear_grid(ai[coarse][:, 0], aj[coarse][0], t_c, ai, aj)
    out = []
    for h in levels:
        *q, t = _exact_geo(ann, lat, lon, np.full(lat.shape, h), ai.shape, t)
        out.append(q)
    return np.array(out, dtype=np.float64)


#: Lattice lines about a strip whose nodes are visited for it (an edge spans at most two
#: lattice lines: one profile per node along the track, the diagonal two).
_STRIP_MARGIN = 4
#: Columns walked together (a row of them is contiguous in memory).
_BLOCK = 16


@nb.njit(cache=True, nogil=True)
def _near(a, b, f):
    """The profile's value between two lattice lines (``f`` of the way to ``b``); one
    lattice line's if the other has none there; NaN if neither."""
    if np.isfinite(a) and np.isfinite(b):
        return (1.0 - f) * a + f * b
    if np.isfinite(a):
        return a
    if np.isfinite(b):
        return b
    return np.nan


@nb.njit(cache=True, nogil=True)
def _reaches(row, j0, j1, inv, l0, first):
    """Whether any line of ``row[j0:j1]`` (scaled) is at ``first`` or beyond."""
    for j in range(j0, j1):
        if row[j] * inv - l0 >= first:
            return True
    return False


@nb.njit(cache=True, nogil=True)
def _kernel_profiles(
    lo, hi, strip, line, u, r, look, ql, qu, qr, qlook, per, l0, u0, bw, n_bins, tol_r,
    tol_look, layover, shadow,
):  # fmt: skip
    """Strips ``lo … hi − 1`` of ``strip`` lattice lines: the profiles of the node grid
    where its edges (right, down) cross each lattice line, binned along the
    ground range ``u``; then each query of the strip against the two lattice lines about
    it (:func:`layover_and_shadow`); lattice line ``k`` is image line ``(k + l0) · per``.
    The lines grow down every column (along the track): each block of ``_BLOCK`` columns
    is walked from where the last strip left it."""
    n_rows, n_cols = line.shape
    q_rows, q_cols = ql.shape
    inv = 1.0 / per
    ptr = np.zeros(-(-n_cols // _BLOCK), dtype=np.int64)
    qptr = np.zeros(-(-q_cols // _BLOCK), dtype=np.int64)
    rmax = np.empty((strip + 1, n_bins), dtype=np.float32)
    rmin = np.empty((strip + 1, n_bins), dtype=np.float32)
    lmax = np.empty((strip + 1, n_bins), dtype=np.float32)
    for s in range(lo, hi):
        base = s * strip
        first, last = base - _STRIP_MARGIN, base + strip + _STRIP_MARGIN
        rmax[:] = -np.inf
        rmin[:] = np.inf
        lmax[:] = -np.inf
        for jb in range(ptr.size):  # blocks of columns: rows of them are contiguous
            j0, j1 = jb * _BLOCK, min((jb + 1) * _BLOCK, n_cols)
            i = ptr[jb]
            while i < n_rows and not _reaches(line[i], j0, j1, inv, l0, first):
                i += 1  # rows wholly before the strip
            ptr[jb] = i
            while i < n_rows:
                seen, beyond = False, True
                for a_j in range(j0, j1):
                    la = line[i, a_j] * inv - l0
                    if not np.isfinite(la):
                        continue
                    seen = True
                    if la <= last:
                        beyond = False
                    if la < first or la > last:
                        continue
                    for e in range(2):  # the right and the lower neighbour
                        c_i = i + e
                        c_j = a_j + 1 - e
                        if c_i >= n_rows or c_j >= n_cols or not np.isfinite(line[c_i, c_j]):
                            continue
                        lc = line[c_i, c_j] * inv - l0
                        k0 = max(int(np.ceil(min(la, lc))), base)
                        k1 = min(int(np.floor(max(la, lc))), base + strip)
                        for k in range(k0, k1 + 1):
                            t = 0.0 if lc == la else (k - la) / (lc - la)
                            uu = u[i, a_j] + t * (u[c_i, c_j] - u[i, a_j])
                            b = int(np.floor((uu - u0) / bw))
                            if b < 0 or b >= n_bins:
                                continue
                            rr = r[i, a_j] + t * (r[c_i, c_j] - r[i, a_j])
                            ll = look[i, a_j] + t * (look[c_i, c_j] - look[i, a_j])
                            row = k - base
                            rmax[row, b] = max(rmax[row, b], rr)
                            rmin[row, b] = min(rmin[row, b], rr)
                            lmax[row, b] = max(lmax[row, b], ll)
                if seen and beyond:
                    break
                i += 1
        for row in range(strip + 1):  # nearer than each bin; farther than each bin
            for b in range(1, n_bins):
                rmax[row, b] = max(rmax[row, b], rmax[row, b - 1])
                lmax[row, b] = max(lmax[row, b], lmax[row, b - 1])
            for b in range(n_bins - 2, -1, -1):
                rmin[row, b] = min(rmin[row, b], rmin[row, b + 1])
        for jb in range(qptr.size):
            j0, j1 = jb * _BLOCK, min((jb + 1) * _BLOCK, q_cols)
            i = qptr[jb]
            while i < q_rows and not _reaches(ql[i], j0, j1, inv, l0, base):
                i += 1
            qptr[jb] = i
            while i < q_rows:
                seen, beyond = False, True
                for j in range(j0, j1):
                    x = ql[i, j] * inv - l0 - base
                    if not np.isfinite(x):
                        continue
                    seen = True
                    if x < strip:
                        beyond = False
                    if x < 0 or x >= strip or not np.isfinite(qu[i, j]):
                        continue
                    row = min(int(np.floor(x)), strip - 1)
                    f = x - row
                    b = int(np.floor((qu[i, j] - u0) / bw))
                    if 0 <= b - 2 < n_bins:  # a bin between: the query's own slope
                        near_r = _near(rmax[row, b - 2], rmax[row + 1, b - 2], f)
                        near_look = _near(lmax[row, b - 2], lmax[row + 1, b - 2], f)
                        if near_r == near_r and qr[i, j] < near_r - tol_r:
                            layover[i, j] = True
                        if near_look == near_look and qlook[i, j] < near_look - tol_look:
                            shadow[i, j] = True
                    if 0 <= b + 2 < n_bins:
                        far_r = _near(rmin[row, b + 2], rmin[row + 1, b + 2], f)
                        if far_r == far_r and qr[i, j] > far_r + tol_r:
                            layover[i, j] = True
                if seen and beyond:
                    break
                i += 1


def _median_step(a: NDArray, axis: int) -> float:
    """The median step of ``a`` between neighbours along ``axis`` (every 8th row or column
    across it: the median of a grid's every step sorts it whole)."""
    a = a[:, ::8] if axis == 0 else a[::8, :]
    return float(np.nanmedian(np.diff(a, axis=axis)))


def layover_and_shadow(
    line: NDArray,
    u: NDArray,
    r: NDArray,
    look_rad: NDArray,
    bin_width: float,
    tol_r: float,
    tol_look_rad: float,
    queries: tuple[NDArray, NDArray, NDArray, NDArray] | None = None,
    lines_per_profile: float = 1.0,
    strip: int = 64,
) -> tuple[NDArray[np.bool_], NDArray[np.bool_]]:
    """Layover and shadow of terrain points by their zero-Doppler profiles, the standard
    definitions (e.g. Kropatsch & Strobl 1990) on a grid of terrain points (2-D, NaN where
    none; the lines growing down its columns, along the track): each point's image
    ``line`` (one profile every ``lines_per_profile`` lines), a ground-range
    coordinate ``u`` (any that grows away from the track), its slant range ``r`` and look
    angle. Along the terrain's profile at the point's line, ordered by ``u``, a point is

    * in **layover** if terrain nearer the track returns from a longer range (beyond
      ``tol_r``) or terrain farther from a shorter one: its range cell also holds another
      patch of terrain (a slope facing the radar steeper than the incidence, the ground
      before it and the slope behind its top);
    * in **shadow** if terrain nearer the track is seen at a larger look angle (beyond
      ``tol_look_rad``): the ray to it passes under that terrain.

    The profiles are the grid's, continuous: for each integer line, where the edges of
    the grid's cells (right, down) cross it, interpolated linearly, binned
    by ``bin_width`` of ``u`` (running maxima of the range and look angle from the track
    outwards, minima of the range inwards); a point reads the two profiles about its
    line, interpolated, beyond the bin next to its own (folds shorter than a bin or two
    are not seen). ``queries``: other points (a 2-D grid of ``line, u, r, look`` turned as
    the nodes' grid) judged on the grid's profiles, else the grid's own nodes. A numba
    kernel over strips of ``strip`` lines on threads, the grids turned so that the lines
    grow down their columns (along the track), each column walked once per chunk of
    strips."""
    line = np.asarray(line, dtype=np.float64)
    # the kernel walks the lines down the columns: the grids turned so that they grow so
    along = [_median_step(line, ax) for ax in (0, 1)]
    axis = int(abs(along[1]) > abs(along[0]))

    def turned(a: NDArray) -> NDArray:
        a = np.asarray(a, dtype=np.float64)
        a = a.T if axis else a
        return np.ascontiguousarray(a[::-1] if along[axis] < 0 else a)

    def back(a: NDArray) -> NDArray:
        a = a[::-1] if along[axis] < 0 else a
        return np.ascontiguousarray(a.T if axis else a)

    nodes = [turned(a) for a in (line, u, r, look_rad)]
    ok = np.isfinite(nodes[0]) & np.isfinite(nodes[1])
    qs = nodes if queries is None else [turned(a) for a in queries]
    layover = np.zeros(qs[0].shape, dtype=np.bool_)
    shadow = np.zeros(qs[0].shape, dtype=np.bool_)
    if ok.any():
        per = float(lines_per_profile)
        l0 = float(np.floor(np.min(nodes[0], where=ok, initial=np.inf) / per))
        n_strips = int((np.max(nodes[0], where=ok, initial=-np.inf) / per - l0) // strip) + 1
        u0 = float(np.min(nodes[1], where=ok, initial=np.inf))
        n_bins = int((np.max(nodes[1], where=ok, initial=-np.inf) - u0) / bin_width) + 1
        over_blocks(
            _kernel_profiles,
            n_strips,
            int(strip),
            *nodes,
            *qs,
            per,
            l0,
            u0,
            float(bin_width),
            n_bins,
            float(tol_r),
            float(tol_look_rad),
            layover,
            shadow,
            grain=4,
        )
    return back(layover), back(shadow)


def _dem_surface(
    dem: Dem, grid: MapGrid
) -> tuple[NDArray[np.float64], NDArray[np.float64], float, float]:
    """The DEM as the geocoding reads it (as level 3 does): its (row, column) through PROJ
    at output pixels every ``DEM_COORD_STEP``, its heights above the ellipsoid, and their
    lowest and highest over the DEM's cells under the grid; :class:`GeometryError` if it
    has none there."""
    from levels.geo.level3 import DEM_COORD_STEP, _dem_coordinates, _ellipsoidal

    nodes = np.ascontiguousarray(_dem_coordinates(dem, grid, DEM_COORD_STEP), dtype=np.float64)
    z = np.ascontiguousarray(_ellipsoidal(dem), dtype=np.float64)
    nr, nc = z.shape
    r0, c0 = (
        int(np.clip(np.floor(np.nanmin(a)), 0, n - 1)) for a, n in zip(nodes, z.shape, strict=True)
    )
    r1, c1 = (
        int(np.clip(np.ceil(np.nanmax(a)), 0, n - 1)) for a, n in zip(nodes, z.shape, strict=True)
    )
    under = z[r0 : r1 + 1, c0 : c1 + 1]
    covers = (
        np.nanmax(nodes[0]) >= 0 and np.nanmin(nodes[0]) <= nr - 1
        and np.nanmax(nodes[1]) >= 0 and np.nanmin(nodes[1]) <= nc - 1
    )  # fmt: skip
    if not covers or not np.isfinite(under).any():
        raise GeometryError("GTC: the DEM does not cover the output grid")
    return nodes, z, float(np.nanmin(under)), float(np.nanmax(under))


def _in_height(values: NDArray[np.float64], levels: NDArray[np.float64]) -> NDArray[np.float64]:
    """The polynomial through ``values`` (one per height level, first axis) in the scaled
    height ``x = (h − centre) / half-span`` of the levels: its coefficients, lowest power
    first (Lagrange's interpolant in the monomial basis; at ``x = 0``, the middle height,
    the constant term)."""
    x = (levels - np.mean(levels)) / _half_span(levels)
    flat = values.reshape(levels.size, -1)
    coef = np.linalg.solve(np.vander(x, increasing=True), flat)
    return np.asarray(coef, dtype=np.float64).reshape(values.shape)


def _half_span(levels: NDArray[np.float64]) -> float:
    return max(0.5 * float(levels[-1] - levels[0]), 1.0)


@nb.njit(cache=True, nogil=True)
def _kernel_geocode(
    lo, hi, step, anchors, h_mid, inv_span, xs, image_shape, dem_nodes, dem_step, z,
    from_dem, height, image, imaged, out, located, line, col, masks, profiles, frame,
    tol_r, tol_look, layover, shadow,
):  # fmt: skip
    """Rows ``lo … hi − 1`` of the output: each pixel's (line, column, look) from the
    anchors (bilinear, then the polynomial in height through the levels,
    :func:`_in_height`: ``anchors`` its coefficients, ``x = (h − h_mid) · inv_span``), the
    slant image bilinearly there (NaN outside it or over a void). The anchors are
    interpolated down the row once for each anchor column, then along the row per pixel.
    What is written: the image (``imaged``: ``out``), the location (``located``:
    ``line`` and ``col``), the masks (``masks``).

    ``from_dem``: each pixel's height is the DEM's, written to ``height``, read as level 3
    samples a DEM (its (row, column) bilinearly from ``dem_nodes`` every ``dem_step``
    output pixels, the ellipsoidal heights ``z`` bilinearly there), NaN outside the DEM,
    over a void, or outside the frame: beyond the anchor cells where no height level
    (``xs``, scaled as ``x``) lands within ``_FRAME_MARGIN_PX`` of the slant image of
    ``image_shape`` (a third of a frame's bounding box, not sampled, located nor judged);
    else ``height`` is read.

    ``masks``: each pixel also judged against the terrain's profiles (:func:`_profiles`:
    ``profiles`` their running maxima of the range and look angle outwards and minima
    of the range inwards, rows of lines ``frame[0] + k·frame[1]``, columns of ground
    range ``frame[2] + m·frame[3]``: the column at the middle height): the two rows about
    its line, interpolated, up to the sample before it (from there on after it):
    :func:`layover_and_shadow`'s definitions, ``tol_r`` and ``tol_look`` their
    tolerances; none where a row has no terrain there (the grid's or the DEM's edge)."""
    n_lev, _, na, nb = anchors.shape
    n_l, n_s = image_shape
    n_p, n_u = profiles.shape[0], profiles.shape[1]
    nda, ndb = dem_nodes.shape[1], dem_nodes.shape[2]
    nr, nc = z.shape
    n_cols = height.shape[1]
    at_row = np.empty((n_lev, 3, nb))
    dem_row = np.empty((2, ndb))
    inv_step, inv_dem = 1.0 / step, 1.0 / dem_step
    inv_per, inv_du = 1.0 / frame[1], 1.0 / frame[3]
    m = _FRAME_MARGIN_PX
    for i in range(lo, hi):
        a = min(i // step, na - 2)
        fu = (i - a * step) * inv_step
        for k in range(n_lev):
            for c in range(3):
                for b in range(nb):
                    at_row[k, c, b] = (1.0 - fu) * anchors[k, c, a, b] + fu * anchors[
                        k, c, a + 1, b
                    ]
        j_lo, j_hi = 0, n_cols
        if from_dem:  # the anchor columns where the frame is, at some height
            b_lo, b_hi = nb, -1
            for b in range(nb):
                for x in xs:
                    q0 = q1 = 0.0
                    for k in range(n_lev - 1, -1, -1):
                        q0 = q0 * x + at_row[k, 0, b]
                        q1 = q1 * x + at_row[k, 1, b]
                    if -m <= q0 <= n_l - 1 + m and -m <= q1 <= n_s - 1 + m:
                        b_lo, b_hi = min(b_lo, b), max(b_hi, b)
            j_lo = min(max((b_lo - 1) * step, 0), n_cols)
            j_hi = max(min((b_hi + 1) * step + 1, n_cols), j_lo)
        if from_dem:
            da = min(i // dem_step, nda - 2)
            su = (i - da * dem_step) * inv_dem
            for c in range(2):
                for b in range(ndb):
                    dem_row[c, b] = (1.0 - su) * dem_nodes[c, da, b] + su * dem_nodes[c, da + 1, b]
        b = db = 0  # the anchor and DEM node columns about j, and j's offsets from them
        jb = jd = -1
        for j in range(n_cols):
            jb += 1  # (counted, not divided: an integer division per pixel costs)
            if jb == step and b < nb - 2:
                b, jb = b + 1, 0
            jd += 1
            if jd == dem_step and db < ndb - 2:
                db, jd = db + 1, 0
            if j < j_lo or j >= j_hi:
                h = np.nan
            elif from_dem:
                sv = jd * inv_dem
                drow = (1.0 - sv) * dem_row[0, db] + sv * dem_row[0, db + 1]
                dcol = (1.0 - sv) * dem_row[1, db] + sv * dem_row[1, db + 1]
                h = np.nan
                if 0.0 <= drow <= nr - 1 and 0.0 <= dcol <= nc - 1:
                    p0 = min(int(drow), nr - 2)
                    r0 = min(int(dcol), nc - 2)
                    s, t = drow - p0, dcol - r0
                    h = (1 - s) * ((1 - t) * z[p0, r0] + t * z[p0, r0 + 1]) + s * (
                        (1 - t) * z[p0 + 1, r0] + t * z[p0 + 1, r0 + 1]
                    )
            else:
                h = height[i, j]
            if from_dem:
                height[i, j] = h
            if not (h == h):
                if imaged:
                    out[i, j] = np.nan
                if located:
                    line[i, j] = np.nan
                    col[i, j] = np.nan
                continue
            fv = jb * inv_step
            gv = 1.0 - fv
            x = (h - h_mid) * inv_span
            q0 = q1 = q2 = 0.0
            for k in range(n_lev - 1, -1, -1):  # Horner
                q0 = q0 * x + (gv * at_row[k, 0, b] + fv * at_row[k, 0, b + 1])
                q1 = q1 * x + (gv * at_row[k, 1, b] + fv * at_row[k, 1, b + 1])
                q2 = q2 * x + (gv * at_row[k, 2, b] + fv * at_row[k, 2, b + 1])
            if located:
                line[i, j] = q0
                col[i, j] = q1
            if masks:
                y = (q0 - frame[0]) * inv_per
                mid = gv * at_row[0, 1, b] + fv * at_row[0, 1, b + 1]
                x = (mid - frame[2]) * inv_du
                if 0.0 <= y < n_p - 1 and 0.0 <= x < n_u - 1:
                    r0 = int(y)
                    f = y - r0
                    m0 = int(x)
                    g0 = 1.0 - f
                    near_r = g0 * profiles[r0, m0, 0] + f * profiles[r0 + 1, m0, 0]
                    far_r = g0 * profiles[r0, m0 + 1, 1] + f * profiles[r0 + 1, m0 + 1, 1]
                    near_look = g0 * profiles[r0, m0, 2] + f * profiles[r0 + 1, m0, 2]
                    layover[i, j] = q1 < near_r - tol_r or q1 > far_r + tol_r
                    shadow[i, j] = q2 < near_look - tol_look
            if not imaged:
                continue
            if not (0.0 <= q0 <= n_l - 1 and 0.0 <= q1 <= n_s - 1):
                out[i, j] = np.nan
                continue
            l0 = min(int(q0), n_l - 2)
            c0 = min(int(q1), n_s - 2)
            fl, fc = q0 - l0, q1 - c0
            out[i, j] = (1.0 - fl) * ((1.0 - fc) * image[l0, c0] + fc * image[l0, c0 + 1]) + fl * (
                (1.0 - fc) * image[l0 + 1, c0] + fc * image[l0 + 1, c0 + 1]
            )


@nb.njit(cache=True, nogil=True)
def _kernel_profile_rows(
    lo, hi, lattice, s_a, s_b, per, line0, n_rows, n_cols, z, h_mid, inv_span, profiles
):  # fmt: skip
    """Rows ``lo … hi − 1`` of the terrain's profiles (:func:`_profiles`): row ``k`` the
    zero-Doppler line ``line0 + k·per``, its samples the terrain there at ground ranges
    evenly spaced. ``lattice`` (every ``s_a`` rows and ``s_b`` samples), bilinearly: each
    sample's output pixel (row, column) and DEM (row, column) at the middle height, and
    the anchors' (line, column, look) there as polynomials in height (:func:`_in_height`,
    the coefficients of each after the four). The DEM's height read there (bilinearly;
    outside or over a void, none), the sample is moved along the lattice by what that
    height shifts its line (the zero-Doppler plane leans a little from the vertical:
    0.14 line a kilometre for ERS-1), its height following the DEM cell's bilinear
    surface; its column and look angle at that height. Then each row's running maxima
    outwards (range, look: ``profiles[..., 0]``, ``[..., 2]``) and minima inwards (range:
    ``[..., 1]``); −∞ and +∞ where no terrain is yet; samples outside the output grid or
    the DEM skipped."""
    n_q, nla, nlb = lattice.shape
    n_lev = (n_q - 4) // 3
    nr, nc = z.shape
    n_u = profiles.shape[1]
    raw = np.empty((2, n_u))  # the row's ranges and looks
    val = np.empty((n_q, nlb))  # the lattice down to the row, and its change per row
    dval = np.empty((n_q, nlb))
    inv_a, inv_b = 1.0 / s_a, 1.0 / s_b
    inv_per = 1.0 / per
    for kr in range(lo, hi):
        a = min(kr // s_a, nla - 2)
        fu = (kr - a * s_a) * inv_a
        for q in range(n_q):
            for b in range(nlb):
                val[q, b] = (1.0 - fu) * lattice[q, a, b] + fu * lattice[q, a + 1, b]
                dval[q, b] = (lattice[q, a + 1, b] - lattice[q, a, b]) * inv_a
        target = line0 + kr * per
        b, mb = 0, -1  # the lattice column about m, and m's offset from it (counted)
        for m in range(n_u):
            mb += 1
            if mb == s_b and b < nlb - 2:
                b, mb = b + 1, 0
            fv = mb * inv_b
            gv = 1.0 - fv
            r_out = np.nan
            look_out = np.nan
            pi = gv * val[0, b] + fv * val[0, b + 1]
            pj = gv * val[1, b] + fv * val[1, b + 1]
            drow = gv * val[2, b] + fv * val[2, b + 1]
            dcol = gv * val[3, b] + fv * val[3, b + 1]
            if (
                0.0 <= pi <= n_rows - 1
                and 0.0 <= pj <= n_cols - 1
                and 0.0 <= drow <= nr - 1
                and 0.0 <= dcol <= nc - 1
            ):
                p0 = min(int(drow), nr - 2)
                q0 = min(int(dcol), nc - 2)
                s, t = drow - p0, dcol - q0
                z00, z01 = z[p0, q0], z[p0, q0 + 1]
                z10, z11 = z[p0 + 1, q0], z[p0 + 1, q0 + 1]
                h = (1 - s) * ((1 - t) * z00 + t * z01) + s * ((1 - t) * z10 + t * z11)
                if h == h:
                    x = (h - h_mid) * inv_span
                    line_h = 0.0
                    for k in range(n_lev - 1, -1, -1):
                        line_h = line_h * x + (gv * val[4 + k, b] + fv * val[4 + k, b + 1])
                    shift = (target - line_h) * inv_per  # rows along the lattice onto the line
                    ds = shift * (gv * dval[2, b] + fv * dval[2, b + 1])
                    dt = shift * (gv * dval[3, b] + fv * dval[3, b + 1])
                    h += ds * ((1 - t) * (z10 - z00) + t * (z11 - z01)) + dt * (
                        (1 - s) * (z01 - z00) + s * (z11 - z10)
                    )
                    x = (h - h_mid) * inv_span
                    r_out = 0.0
                    look_out = 0.0
                    for k in range(n_lev - 1, -1, -1):
                        c = 4 + n_lev + k
                        r_out = r_out * x + (
                            gv * (val[c, b] + shift * dval[c, b])
                            + fv * (val[c, b + 1] + shift * dval[c, b + 1])
                        )
                        c += n_lev
                        look_out = look_out * x + (
                            gv * (val[c, b] + shift * dval[c, b])
                            + fv * (val[c, b + 1] + shift * dval[c, b + 1])
                        )
            raw[0, m] = r_out
            raw[1, m] = look_out
        near_r = near_look = -np.inf
        for m in range(n_u):  # outwards: the farthest range and the largest look so far
            v = raw[0, m]
            if v == v:
                near_r = max(near_r, v)
                near_look = max(near_look, raw[1, m])
            profiles[kr, m, 0] = near_r
            profiles[kr, m, 2] = near_look
        far_r = np.inf
        for m in range(n_u - 1, -1, -1):  # inwards: the nearest range so far
            v = raw[0, m]
            if v == v:
                far_r = min(far_r, v)
            profiles[kr, m, 1] = far_r


def mask_oversample(dem: Dem, grid: MapGrid, most: int = 4) -> int:
    """Profile samples per output pixel (each way) that the layover and shadow profiles
    take to follow the DEM's own resolution: the output pixel over half the DEM's spacing
    (metres; degrees at the grid's latitude; the bilinear surface bends at the DEM's
    nodes, and samples twice as fine catch a cliff's edge), rounded up, at most ``most``."""
    sx, sy = dem.spacing
    if pyproj.CRS.from_wkt(dem.crs_wkt).is_geographic:
        x, y = grid.map_of(np.array([grid.n_rows / 2]), np.array([grid.n_cols / 2]))
        _, lat = _to_geo(grid).transform(x, y)
        m = np.radians(1.0) * WGS84.a_m
        sx, sy = sx * m * np.cos(np.radians(float(lat[0]))), sy * m
    return int(min(most, max(1, np.ceil(2 * grid.pixel_size_m / min(sx, sy) - 1e-6))))


#: Slant pixels beyond the image within which an output pixel is still geocoded (and
#: an anchor cell more about it): the frame's edge and its interpolation.
_FRAME_MARGIN_PX = 2.0
#: Profile rows and samples between the exact points of the profiles' lattice (the
#: ground under a line is nearly straight, across it a hyperbola: 2e-3 px at most
#: interpolated on ERS-1's 100 km frame at 12.5 m).
PROFILE_LATTICE_STEP = (64, 16)


def _profiles(
    ann: SarAnnotation,
    grid: MapGrid,
    coef: NDArray[np.float64],
    levels: NDArray[np.float64],
    dem: Dem,
    z: NDArray[np.float64],
    per_node: int,
    step_px: int,
) -> tuple[NDArray[np.float32], NDArray[np.float64]]:
    """The terrain's zero-Doppler profiles for the layover and shadow masks: a row per
    image line ``line0 + k·per`` (one per output pixel along the track, ``per_node`` times
    finer: :func:`mask_oversample`), the terrain along it sampled at ground ranges
    ``u0 + m·du`` (``u``: the column at the middle height, ``per_node`` samples per output
    pixel across the track); each sample's range (columns) and look angle, as running
    maxima and minima (:func:`_kernel_profile_rows`). The rows cover the image's lines;
    the samples its columns and, beyond them, what the relief can fold onto them or hide
    them with (below).
    Returns the profiles ``(rows, samples, 3)`` and ``(line0, per, u0, du)``."""
    n_l, n_s = ann.shape
    u = coef[0, 1]  # the column at the middle height
    du_px = np.hypot(np.diff(u, axis=0)[:, :-1], np.diff(u, axis=1)[:-1, :]) / step_px
    line_px = (
        np.hypot(np.diff(coef[0, 0], axis=0)[:, :-1], np.diff(coef[0, 0], axis=1)[:-1, :]) / step_px
    )
    inside = (u[:-1, :-1] >= 0) & (u[:-1, :-1] <= n_s - 1)
    du = float(np.nanmedian(du_px[inside] if inside.any() else du_px)) / per_node
    per = float(np.nanmax(line_px)) / per_node
    # what can fold onto or hide a pixel of the image, in columns (flat Earth, 10 % over):
    # a pixel's column lies within half the relief of its column at the middle height;
    # a fold's range lies in the image; what hides a pixel stands within relief · tan θ
    # of it on the ground, relief · tan θ · sin θ in range (θ the incidence, largest at
    # the far range)
    h_mid = float(np.mean(levels))
    far = ann.ground_of_image(np.array([0.5 * (n_l - 1)]), np.array([n_s - 1.0]), h_mid)
    inc = float(ann.incidence(*far, np.array([h_mid]))[0])
    relief = 1.1 * float(levels[-1] - levels[0]) / ann.range_spacing_m
    u_lo = max(float(np.nanmin(u)), -(0.5 + np.tan(inc) * np.sin(inc)) * relief - 4.0)
    u_hi = min(float(np.nanmax(u)), n_s - 1 + 0.5 * relief + 4.0)
    line0, u0 = -per, u_lo - 2.0 * du
    n_p = int(np.ceil((n_l - 1 - line0) / per)) + 2
    n_u = int(np.ceil((u_hi - u0) / du)) + 3
    s_a, s_b = PROFILE_LATTICE_STEP
    la = line0 + np.arange(-(-(n_p - 1) // s_a) + 2) * s_a * per
    lb = u0 + np.arange(-(-(n_u - 1) // s_b) + 2) * s_b * du
    ll, uu = np.meshgrid(la, lb, indexing="ij")
    lat, lon = ann.ground_of_image(ll, uu, h_mid)
    to_map = pyproj.Transformer.from_crs(
        pyproj.CRS.from_epsg(4326), pyproj.CRS.from_wkt(grid.crs_wkt), always_xy=True
    )
    e, n = to_map.transform(np.degrees(lon), np.degrees(lat))
    li, lj = grid.ij_of_map(e, n)
    to_dem = pyproj.Transformer.from_crs(
        pyproj.CRS.from_epsg(4326), pyproj.CRS.from_wkt(dem.crs_wkt), always_xy=True
    )
    dr, dc = dem.pixel_of(
        *(np.asarray(v) for v in to_dem.transform(np.degrees(lon), np.degrees(lat)))
    )
    rows = np.arange(coef.shape[2], dtype=np.float64) * step_px
    cols = np.arange(coef.shape[3], dtype=np.float64) * step_px
    at_anchors = [
        bilinear_grid(rows, cols, coef[k, c], li, lj) for c in range(3) for k in range(levels.size)
    ]
    lattice = np.ascontiguousarray(np.stack([li, lj, dr, dc, *at_anchors]), dtype=np.float64)
    profiles = np.empty((n_p, n_u, 3), dtype=np.float32)
    over_blocks(
        _kernel_profile_rows,
        n_p,
        lattice,
        s_a,
        s_b,
        per,
        line0,
        grid.n_rows,
        grid.n_cols,
        z,
        h_mid,
        1.0 / _half_span(levels),
        profiles,
        grain=16,
    )
    return profiles, np.array([line0, per, u0, du])


def geocode(
    image: SarImage,
    grid: MapGrid,
    dem: Dem | None = None,
    reference_height_m: float = 0.0,
    step_px: int = ANCHOR_STEP_PX,
    masks: bool = True,
) -> Geocoded:
    """``image`` on ``grid``: over ``dem`` (GTC), or on the ellipsoid raised to
    ``reference_height_m`` (GEC) (module docstring); ``masks=False``: no layover and
    shadow (all false), the geometry alone. On the ellipsoid nothing folds: no masks."""
    ann = image.annotation
    if dem is None:
        height = np.full(grid.shape, float(reference_height_m), dtype=np.float32)
        levels = np.array([float(reference_height_m)])
        surface = None
        kind = "GEC"
    else:
        surface = _dem_surface(dem, grid)
        height = np.empty(grid.shape, dtype=np.float32)
        levels = np.linspace(surface[2] - 10.0, surface[3] + 10.0, HEIGHT_LEVELS)
        kind = "GTC"
    anchors = _anchors(ann, grid, step_px, levels)
    # (levels, 3, na, nb): the anchors' (line, column, look) as polynomials in height
    model = _Model(
        np.ascontiguousarray(_in_height(anchors, levels)), int(step_px), levels, ann.shape
    )
    del anchors
    intensity = np.empty(grid.shape, dtype=np.float32)
    judged = None
    if masks and dem is not None and surface is not None:
        profiles, frame = _profiles(
            ann,
            grid,
            model.coef,
            levels,
            dem,
            surface[1],
            mask_oversample(dem, grid),
            step_px,
        )
        tol = (MASK_TOLERANCE_PX, MASK_TOLERANCE_PX * ann.range_spacing_m / ann.near_range_m)
        judged = (profiles, frame, *tol)
    layover, shadow = _geocode_rows(
        model, height, surface, image=image.intensity, out=intensity, masks=judged
    )
    if judged is None:  # nothing folds on the ellipsoid, or nothing was asked
        layover = shadow = np.zeros(grid.shape, dtype=np.bool_)
    # the anchor grid's error: a lattice between the anchors, at each pixel's height
    ci, cj = np.meshgrid(
        np.linspace(0.5 * step_px, grid.n_rows - 1, 23),
        np.linspace(0.5 * step_px, grid.n_cols - 1, 23),
        indexing="ij",
    )
    ch = bilinear_grid(
        np.arange(grid.n_rows, dtype=np.float64),
        np.arange(grid.n_cols, dtype=np.float64),
        height,
        ci,
        cj,
    )
    gl, gc = model.at(ci, cj, ch)
    el, ec, _, _ = _exact(ann, grid, ci, cj, ch)
    e = np.hypot(gl - el, gc - ec)
    e = e[np.isfinite(e)]
    err: dict[str, Any] = {
        "points": int(e.size),
        "rms_px": float(np.sqrt(np.mean(e**2))) if e.size else float("nan"),
        "max_px": float(np.max(e)) if e.size else float("nan"),
    }
    return Geocoded(grid, intensity, height, kind, err, layover, shadow, model)


def splat_bilinear(
    out: NDArray[np.float64], line: NDArray, col: NDArray, value: NDArray, n_l: int, n_s: int
) -> None:
    """Add each point's ``value`` to the four cells of an ``n_l`` × ``n_s`` image (``out``,
    flat) around its (line, column), bilinearly; what falls outside is dropped."""
    l0, c0 = np.floor(line).astype(np.int64), np.floor(col).astype(np.int64)
    fl, fc = line - l0, col - c0
    for dl, dc, w in (
        (0, 0, (1 - fl) * (1 - fc)),
        (1, 0, fl * (1 - fc)),
        (0, 1, (1 - fl) * fc),
        (1, 1, fl * fc),
    ):
        ll, cc = l0 + dl, c0 + dc
        ok = (ll >= 0) & (ll < n_l) & (cc >= 0) & (cc < n_s)
        idx = ll[ok] * n_s + cc[ok]
        out += np.bincount(idx, weights=(w * value)[ok], minlength=n_l * n_s)


def nominal_cell_m2(ann: SarAnnotation, height_m: float) -> NDArray[np.float64]:
    """Each column's slant-range cell as ground on the ellipsoid raised to ``height_m``,
    mid-frame (m²): the range spacing over the sine of the incidence, times the ground
    distance between lines (the antenna's speed brought down to the Earth's radius): the
    area a detected image's σ⁰ is reckoned on."""
    n_l, n_s = ann.shape
    cols = np.arange(n_s, dtype=np.float64)
    lat, lon = ann.ground_of_image(np.full(n_s, 0.5 * n_l), cols, height_m)
    inc = ann.incidence(lat, lon, np.full(n_s, float(height_m)))
    return np.asarray(ann.range_spacing_m / np.sin(inc) * line_spacing_m(ann))


def line_spacing_m(ann: SarAnnotation) -> float:
    """Ground distance between lines at the frame's centre (m): the antenna's speed
    brought down to the Earth's radius, times the line interval."""
    t = ann.first_line_s + 0.5 * ann.shape[0] * ann.line_interval_s
    s, v = ann.ephemeris.interpolate(np.array([t]))
    return float(np.linalg.norm(v) * WGS84.a_m / np.linalg.norm(s) * ann.line_interval_s)


#: Cells where the terrain shows the radar less than this share of their nominal area
#: (seen edge-on, or all hidden) are not flattened: NaN.
FLATTEN_MIN_AREA = 0.05


@nb.njit(cache=True, nogil=True)
def _kernel_facets(height, shadow, line, col, los, step, px, n_l, n_s, shown):
    """Every output pixel a facet of the terrain (:func:`terrain_flattening`): its
    ``A·cos θ_loc = px² · n · l`` (``n`` from central differences of ``height``, one-sided
    at the grid's edges; ``l`` east, north, up from ``los`` every ``step`` pixels,
    bilinearly) added into ``shown`` (the slant image's cells, flat) about its (line,
    column), bilinearly; nothing for a facet turned away, in shadow, or off the DEM.
    Serial: facets of any rows add into the same cells."""
    n_rows, n_cols = height.shape
    na, nb = los.shape[1], los.shape[2]
    inv = 1.0 / step
    for i in range(n_rows):
        a = min(i // step, na - 2)
        fu = (i - a * step) * inv
        i0, i1 = max(i - 1, 0), min(i + 1, n_rows - 1)
        b, jb = 0, -1
        for j in range(n_cols):
            jb += 1
            if jb == step and b < nb - 2:
                b, jb = b + 1, 0
            q_l, q_c = line[i, j], col[i, j]
            if shadow[i, j] or not (q_l == q_l and q_c == q_c):
                continue
            j0, j1 = max(j - 1, 0), min(j + 1, n_cols - 1)
            d_south = (height[i1, j] - height[i0, j]) / ((i1 - i0) * px)
            d_east = (height[i, j1] - height[i, j0]) / ((j1 - j0) * px)
            fv = jb * inv
            w00, w10 = (1.0 - fu) * (1.0 - fv), fu * (1.0 - fv)
            w01, w11 = (1.0 - fu) * fv, fu * fv
            area = 0.0
            for c in range(3):  # n · l, n = (−∂h/∂E, ∂h/∂S, 1)
                lc = (
                    w00 * los[c, a, b]
                    + w10 * los[c, a + 1, b]
                    + w01 * los[c, a, b + 1]
                    + w11 * los[c, a + 1, b + 1]
                )
                area += lc * (-d_east if c == 0 else (d_south if c == 1 else 1.0))
            area *= px * px
            if not area > 0.0:
                continue
            l0, c0 = int(np.floor(q_l)), int(np.floor(q_c))
            fl, fc = q_l - l0, q_c - c0
            for dl in range(2):
                for dc in range(2):
                    ll, cc = l0 + dl, c0 + dc
                    if 0 <= ll < n_l and 0 <= cc < n_s:
                        wl = fl if dl else 1.0 - fl
                        wc = fc if dc else 1.0 - fc
                        shown[ll * n_s + cc] += wl * wc * area


@nb.njit(cache=True, nogil=True)
def _kernel_read(lo, hi, image, line, col, valid, out):
    """Rows ``lo … hi − 1``: ``image`` bilinearly at each valid pixel's (line, column)."""
    n_l, n_s = image.shape
    for i in range(lo, hi):
        for j in range(out.shape[1]):
            if not valid[i, j]:
                continue
            l0 = min(max(int(np.floor(line[i, j])), 0), n_l - 2)
            c0 = min(max(int(np.floor(col[i, j])), 0), n_s - 2)
            fl, fc = line[i, j] - l0, col[i, j] - c0
            out[i, j] = (1.0 - fl) * ((1.0 - fc) * image[l0, c0] + fc * image[l0, c0 + 1]) + fl * (
                (1.0 - fc) * image[l0 + 1, c0] + fc * image[l0 + 1, c0 + 1]
            )


def terrain_flattening(g: Geocoded, image: SarImage) -> NDArray[np.float32]:
    """γ⁰ of each output pixel of a GTC by radiometric terrain flattening (Small 2011,
    "Flattening Gamma", IEEE TGRS 49(8); what sarsen does): the slant image's intensity (σ⁰
    reckoned on the ellipsoid's nominal cell, :func:`nominal_cell_m2`) times that cell's
    area over the area the terrain presents to the radar in it, ``A_γ = Σ A·cos θ_loc``
    over the terrain imaged there; on flat ground ``σ⁰ / cos θ``. The terrain is the
    output's pixels over the DEM (``g.height_m``), each of area ``A = px² · |n|`` with
    ``n = (−∂h/∂E, −∂h/∂N, 1)``, so that ``A·cos θ_loc = px² · n · l`` (``l`` the unit
    vector to the antenna, exact at the anchors); facets turned away or in shadow count
    nothing; each is added into the cells about its (line, column) bilinearly
    (:func:`_kernel_facets`). The flattened image is then read at each pixel's (line,
    column) as the intensity is. NaN where the GTC is, or where a cell shows less than
    ``FLATTEN_MIN_AREA`` of its nominal area."""
    ann, grid = image.annotation, g.grid
    n_l, n_s = ann.shape
    step = g.model.step
    ai, aj = np.meshgrid(
        *(np.arange(n, dtype=np.float64) * step for n in g.model.coef.shape[2:]), indexing="ij"
    )
    x, y = grid.map_of(ai, aj)
    lon, lat = (np.radians(v) for v in _to_geo(grid).transform(np.ravel(x), np.ravel(y)))
    p = WGS84.to_ecef(lat, lon, np.full(lat.shape, g.model.h_mid))
    _, r, _, s = ann._solve(p, None)
    to_antenna = (s - p) / r[:, None]
    east = np.stack([-np.sin(lon), np.cos(lon), np.zeros_like(lon)], axis=-1)
    north = np.stack([-np.sin(lat) * np.cos(lon), -np.sin(lat) * np.sin(lon), np.cos(lat)], axis=-1)
    los = np.stack(
        [
            np.sum(to_antenna * axis, axis=1).reshape(ai.shape)
            for axis in (east, north, WGS84.up(lat, lon))
        ]
    )
    shown = np.zeros(n_l * n_s)
    _kernel_facets(
        np.asarray(g.height_m, dtype=np.float32),
        g.shadow,
        g.line,
        g.column,
        np.ascontiguousarray(los),
        int(step),
        float(grid.pixel_size_m),
        n_l,
        n_s,
        shown,
    )
    cell = nominal_cell_m2(ann, g.model.h_mid)[None, :]
    a_gamma = shown.reshape(n_l, n_s)
    flat = np.full((n_l, n_s), np.nan)
    np.divide(image.intensity * cell, a_gamma, out=flat, where=a_gamma > FLATTEN_MIN_AREA * cell)
    out = np.full(grid.shape, np.nan, dtype=np.float32)
    over_blocks(
        _kernel_read, grid.n_rows, flat, g.line, g.column, np.isfinite(g.intensity), out, grain=64
    )
    return out
