"""A SAR frame's range–Doppler model (ADRIN §5): the annotation that comes with a detected
slant-range image (state vectors, line timing, range sampling, Doppler centroid), the pixel
located by the Doppler and range equations (Newton on the state vectors, one numba kernel),
the image itself, and the frame's nominal ground cell.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numba as nb
import numpy as np
import pyproj
from numpy.typing import ArrayLike, NDArray

from levels.errors import GeometryError
from levels.geo.maps import MapGrid, map_crs
from levels.geometry.ellipsoid import WGS84
from levels.geometry.ephemeris import Ephemeris
from levels.geometry.times import Epoch
from levels.threads import over_blocks

_log = logging.getLogger(__name__)

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
        values = {
            "line interval (s)": self.line_interval_s,
            "range spacing (m)": self.range_spacing_m,
            "wavelength (m)": self.wavelength_m,
            "near range (m)": self.near_range_m,
        }
        bad = {
            k: v
            for k, v in values.items()
            if not (math.isfinite(v) and ANNOTATION_RANGES[k][0] < v <= ANNOTATION_RANGES[k][1])
        }
        if bad:  # NaN passes every `<= 0` test: said here, not as NaN products
            said = ", ".join(
                f"{k} {v!r} (expected {ANNOTATION_RANGES[k][0]:g}–{ANNOTATION_RANGES[k][1]:g})"
                for k, v in bad.items()
            )
            raise GeometryError(f"a SAR annotation out of any SAR's range: {said}")
        if not (math.isfinite(self.first_line_s) and all(map(math.isfinite, self.doppler_hz))):
            raise GeometryError(
                f"a SAR annotation's first line time {self.first_line_s!r} and Doppler "
                f"centroid {self.doppler_hz} must be finite"
            )
        if len(self.shape) != 2 or min(self.shape) < 1:
            raise GeometryError(f"a SAR image of shape {self.shape}: expected lines × samples")
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


def _to_geo(grid: MapGrid) -> pyproj.Transformer:
    return pyproj.Transformer.from_crs(
        pyproj.CRS.from_wkt(grid.crs_wkt), pyproj.CRS.from_epsg(4326), always_xy=True
    )


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


def frame_grid(
    ann: SarAnnotation, pixel_size_m: float, height_m: float = 0.0, margin_m: float = 0.0
) -> MapGrid:
    """A north-up UTM grid (the zone of the frame's centre) of ``pixel_size_m`` covering the
    frame's footprint at ``height_m``, widened by ``margin_m`` each side."""
    lat, lon = ann.edge_ground(height_m)
    ok = np.isfinite(lat) & np.isfinite(lon)
    if not ok.any():
        raise GeometryError(
            "none of the frame's edge points locates on the ellipsoid from its annotation "
            "(its state vectors, timing and range): no grid can be laid over it"
        )
    if not ok.all():
        _log.warning(
            "%d of the frame's %d edge points do not locate on the ellipsoid (beyond its "
            "state vectors?): the grid covers the others",
            int((~ok).sum()),
            ok.size,
        )
    lat, lon = lat[ok], lon[ok]
    crs = map_crs("utm", float(np.mean(lat)), float(np.mean(lon)))
    to_map = pyproj.Transformer.from_crs(pyproj.CRS.from_epsg(4326), crs, always_xy=True)
    x, y = to_map.transform(np.degrees(lon), np.degrees(lat))
    res = float(pixel_size_m)
    x0 = np.floor((np.min(x) - margin_m) / res) * res
    y1 = np.ceil((np.max(y) + margin_m) / res) * res
    n_cols = int(np.ceil((np.max(x) + margin_m - x0) / res))
    n_rows = int(np.ceil((y1 - np.min(y) + margin_m) / res))
    _check_footprint(ann, n_rows * res, n_cols * res, margin_m)
    return MapGrid.north_up(crs.to_wkt(), x0, y1, res, n_rows, n_cols)


#: What a spaceborne SAR's annotation can hold (exclusive low, inclusive high): a line
#: interval up to 10 s (ERS's 0.6 ms times its looks), a range spacing up to 1 km (7.9 m
#: times up to 100 looks), a wavelength from Ka band to P band, a near range of a low orbit.
ANNOTATION_RANGES = {
    "line interval (s)": (0.0, 10.0),
    "range spacing (m)": (0.0, 1000.0),
    "wavelength (m)": (0.005, 1.0),
    "near range (m)": (100e3, 3000e3),
}
#: The most a SAR's ground track moves a second (m/s): a low orbit's, 7.9 km/s in orbit.
MAX_GROUND_SPEED_M_PER_S = 8000.0
#: The smallest incidence a frame's ground range is taken at (rad): ERS's near edge is 19°.
MIN_INCIDENCE_RAD = math.radians(10.0)
#: A grid over a frame's footprint spans at most this times the frame's largest extent
#: (a north-up box around a frame turned by the orbit's inclination: 1.4).
FOOTPRINT_SLACK = 3.0


def _check_footprint(ann: SarAnnotation, height_m: float, width_m: float, margin_m: float) -> None:
    """Refuse a grid wider than the frame can be: its lines at most a low orbit's ground
    speed apart, its samples at most the range spacing over sin 10°; a footprint beyond
    ``FOOTPRINT_SLACK`` times that comes of an orbit or timing at odds with the frame (a
    forged state vector gave a grid of 19 GB), not of the frame."""
    along = ann.shape[0] * ann.line_interval_s * MAX_GROUND_SPEED_M_PER_S
    across = ann.shape[1] * ann.range_spacing_m / math.sin(MIN_INCIDENCE_RAD)
    most = FOOTPRINT_SLACK * max(along, across) + 2.0 * margin_m
    if max(height_m, width_m) > most:
        raise GeometryError(
            f"the frame's footprint spans {max(height_m, width_m) / 1e3:.0f} km on the ground, "
            f"its {ann.shape[0]} lines × {ann.shape[1]} samples at most "
            f"{max(along, across) / 1e3:.0f} km: its orbit or timing is at odds with it"
        )
