"""Imaging: every raw pixel dated, its line of sight traced and met with the terrain exactly.

For each line, the truth orbit and attitude give the projection centre ``P`` and the
rotation ``ecef_from_sensor = ecef_from_orbital(P, V) · orbital_from_body(roll, pitch, yaw)``
(``V`` the platform's reference velocity: inertial for SPOT 1–4, Earth-fixed for SPOT 5)
at the line's time (the same frame conventions as the model: :mod:`levels.geometry.frames`).
Each detector's truth look direction turns into an ECEF ray ``P + s d``.

Ray and terrain
    The ray meets the surface ``h(P + s d) = H(φ, λ)`` where ``h`` is the geodetic height
    and ``H`` the world's terrain. Starting from the ellipsoid inflated by the height of the
    previous pixel of the line, Newton's method on ``s`` (the slope of ``H`` enters the
    derivative) runs until ``|h − H| < 1 mm`` — the issue asks for 1 cm. A ray that does not
    converge in 30 steps is flagged and its pixel set to 0 counts, never silently kept.

Radiance and PSF
    The pixel's response is the detector's square aperture (1 px across, and 1 line along
    track: the integration time) convolved with a Gaussian optical PSF of the given FWHM.
    It is integrated by a product midpoint rule on ``psf_samples²`` points spanning the
    response. Sub-pixel sample points are placed on the ground with the local Jacobian of the
    pixel-to-ground map (central differences of the exactly traced neighbours), where the
    reflectance is evaluated; the Lambertian shading uses the pixel's own terrain normal.

Everything runs in numba kernels, parallel over lines; Python loops only over blocks of a
few hundred lines.
"""

from __future__ import annotations

from dataclasses import dataclass
from math import erf

import numba as nb
import numpy as np
from numpy.typing import ArrayLike, NDArray

from levels.geometry.attitude import Attitude
from levels.geometry.ellipsoid import WGS84
from levels.geometry.frames import apply, ecef_from_orbital, orbital_from_body
from levels.threads import over_blocks
from station.spacecraft.instrument import COUNTS_PER_RADIANCE, BandModel, Hrv
from station.spacecraft.orbit import TruthOrbit
from station.spacecraft.world import BANDS, World, _reflectance, _surface, _to_xy

__all__ = [
    "HEIGHT_TOL_M",
    "LineGeometry",
    "RenderedBand",
    "line_geometry",
    "psf_quadrature",
    "render_band",
    "trace_pixels",
]

#: Convergence of the ray–terrain intersection (the issue asks for < 1 cm).
HEIGHT_TOL_M = 1e-3
_MAX_NEWTON = 30
_A = WGS84.a_m
_B = WGS84.b_m
_E2 = WGS84.e2


@dataclass(frozen=True)
class LineGeometry:
    """Projection centre ``(N, 3)`` and ``ecef_from_sensor`` ``(N, 3, 3)`` at times ``t_s``."""

    t_s: NDArray[np.float64]
    position_ecef_m: NDArray[np.float64]
    ecef_from_sensor: NDArray[np.float64]


def line_geometry(orbit: TruthOrbit, attitude: Attitude, t_s: ArrayLike) -> LineGeometry:
    """The truth geometry of the lines acquired at ``t_s`` (seconds since the orbit's epoch)."""
    t = np.atleast_1d(np.asarray(t_s, dtype=np.float64))
    r, v = orbit.frame_state_ecef(t)  # the velocity the attitude's frame follows
    ang = attitude.angles_rad(t)
    rot = ecef_from_orbital(r, v) @ orbital_from_body(ang[:, 0], ang[:, 1], ang[:, 2])
    return LineGeometry(t, r, rot)


def psf_quadrature(fwhm_px: float, n: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Offsets (px) and weights of an ``n``-point midpoint rule over one axis of the pixel
    response (a 1-px box convolved with a Gaussian of ``fwhm_px``); weights sum to 1."""
    if n == 1:
        return np.zeros(1), np.ones(1)
    sigma = fwhm_px / (2 * np.sqrt(2 * np.log(2)))
    half = 0.5 + 2.0 * sigma
    offsets = (np.arange(n) + 0.5) / n * 2 * half - half
    if sigma == 0:
        weights = (np.abs(offsets) <= 0.5).astype(float)
    else:
        s = sigma * np.sqrt(2)
        weights = np.array([0.5 * (erf((o + 0.5) / s) - erf((o - 0.5) / s)) for o in offsets])
    return offsets, weights / weights.sum()


@nb.njit(cache=True, inline="always")
def _geodetic(x: float, y: float, z: float) -> tuple[float, float, float]:
    """Bowring's latitude and one Newton refinement: sub-µm for |h| < 10 km."""
    p = np.sqrt(x * x + y * y)
    lon = np.arctan2(y, x)
    ep2 = _E2 * _A * _A / (_B * _B)
    th = np.arctan2(z * _A, p * _B)
    st, ct = np.sin(th), np.cos(th)
    lat = np.arctan2(z + ep2 * _B * st * st * st, p - _E2 * _A * ct * ct * ct)
    sl = np.sin(lat)
    n = _A / np.sqrt(1.0 - _E2 * sl * sl)
    h = p * np.cos(lat) + z * sl - _A * _A / n
    lat = np.arctan2(z, p * (1.0 - _E2 * n / (n + h)))
    sl, cl = np.sin(lat), np.cos(lat)
    n = _A / np.sqrt(1.0 - _E2 * sl * sl)
    h = p * cl + z * sl - _A * _A / n
    return lat, lon, h


@nb.njit(cache=True)
def _intersect(px, py, pz, dx, dy, dz, h_guess, lon0, base, relief, seed, grid, geo):
    """Ray ``P + s d`` met with the terrain: (lat, lon, h, x, y, ∂H/∂x, ∂H/∂y, iterations).

    ``iterations`` is −1 if the ray misses or Newton does not converge.
    """
    a = _A + h_guess
    b = _B + h_guess
    qa = (dx * dx + dy * dy) / (a * a) + dz * dz / (b * b)
    qb = 2.0 * ((px * dx + py * dy) / (a * a) + pz * dz / (b * b))
    qc = (px * px + py * py) / (a * a) + pz * pz / (b * b) - 1.0
    disc = qb * qb - 4.0 * qa * qc
    nan = np.nan
    if disc < 0.0:
        return nan, nan, nan, nan, nan, nan, nan, -1
    s = (-qb - np.sqrt(disc)) / (2.0 * qa)
    for it in range(_MAX_NEWTON):
        lat, lon, h = _geodetic(px + s * dx, py + s * dy, pz + s * dz)
        x, y = _to_xy(lat, lon, lon0)
        hh, gx, gy = _surface(lat, lon, x, y, base, relief, seed, grid, geo)
        g = h - hh
        if abs(g) < HEIGHT_TOL_M:
            return lat, lon, h, x, y, gx, gy, it
        sl, cl = np.sin(lat), np.cos(lat)
        so, co = np.sin(lon), np.cos(lon)
        d_up = dx * cl * co + dy * cl * so + dz * sl
        d_east = -dx * so + dy * co
        d_north = -dx * sl * co - dy * sl * so + dz * cl
        slope = d_up - gx * d_east - gy * d_north
        if slope == 0.0:
            break
        s -= g / slope
    return nan, nan, nan, nan, nan, nan, nan, -1


@nb.njit(cache=True, nogil=True)
def _trace_grid(
    lo, hi, pos, rot, look, lon0, base, relief, seed, grid, geo, lat, lon, h, x, y, gx, gy, iters
):
    n_det = lat.shape[1]
    for li in range(lo, hi):
        r = rot[li]
        hg = base
        for d in range(n_det):
            u0, u1, u2 = look[d, 0], look[d, 1], look[d, 2]
            dx = r[0, 0] * u0 + r[0, 1] * u1 + r[0, 2] * u2
            dy = r[1, 0] * u0 + r[1, 1] * u1 + r[1, 2] * u2
            dz = r[2, 0] * u0 + r[2, 1] * u1 + r[2, 2] * u2
            out = _intersect(
                pos[li, 0],
                pos[li, 1],
                pos[li, 2],
                dx,
                dy,
                dz,
                hg,
                lon0,
                base,
                relief,
                seed,
                grid,
                geo,
            )
            lat[li, d], lon[li, d], h[li, d] = out[0], out[1], out[2]
            x[li, d], y[li, d], gx[li, d], gy[li, d], iters[li, d] = (
                out[3],
                out[4],
                out[5],
                out[6],
                out[7],
            )
            if out[7] >= 0:
                hg = out[2]


@nb.njit(cache=True, nogil=True)
def _trace_rays(lo, hi, pos, dirs, lon0, base, relief, seed, grid, geo, out, iters):
    for k in range(lo, hi):
        r = _intersect(
            pos[k, 0],
            pos[k, 1],
            pos[k, 2],
            dirs[k, 0],
            dirs[k, 1],
            dirs[k, 2],
            base,
            lon0,
            base,
            relief,
            seed,
            grid,
            geo,
        )
        out[k, 0], out[k, 1], out[k, 2], iters[k] = r[0], r[1], r[2], r[7]


@nb.njit(cache=True, nogil=True)
def _radiance(lo, hi, lat, lon, x, y, gx, gy, sun, band, seed, rows_m, offsets, weights, out):
    """Radiance of the interior lines 1..L of a traced block (lines 0 and L+1 are halo)."""
    n_det = out.shape[1]
    n_s = offsets.size
    for li in range(lo, hi):
        k = li + 1
        for d in range(n_det):
            if np.isnan(x[k, d]):
                out[li, d] = np.nan
                continue
            d0, d1 = max(d - 1, 0), min(d + 1, n_det - 1)
            xl = 0.5 * (x[k + 1, d] - x[k - 1, d])  # ground displacement per line
            yl = 0.5 * (y[k + 1, d] - y[k - 1, d])
            xc = (x[k, d1] - x[k, d0]) / (d1 - d0)  # … per column
            yc = (y[k, d1] - y[k, d0]) / (d1 - d0)
            if np.isnan(xl + yl + xc + yc):
                xl = yl = xc = yc = 0.0
            sl, cl = np.sin(lat[k, d]), np.cos(lat[k, d])
            so, co = np.sin(lon[k, d]), np.cos(lon[k, d])
            nx = cl * co + gx[k, d] * so + gy[k, d] * sl * co
            ny = cl * so - gx[k, d] * co + gy[k, d] * sl * so
            nz = sl - gy[k, d] * cl
            cos_i = (nx * sun[0] + ny * sun[1] + nz * sun[2]) / np.sqrt(nx * nx + ny * ny + nz * nz)
            if cos_i <= 0.0:
                out[li, d] = 0.0
                continue
            acc = 0.0
            for i in range(n_s):
                for j in range(n_s):
                    px = x[k, d] + offsets[i] * xl + offsets[j] * xc
                    py = y[k, d] + offsets[i] * yl + offsets[j] * yc
                    acc += weights[i] * weights[j] * _reflectance(px, py, band, seed, rows_m)
            out[li, d] = acc * cos_i


@dataclass(frozen=True)
class RenderedBand:
    """One rendered band: raw counts (lines × detectors), the truth radiance behind them, and
    the pixels whose ray did not meet the terrain (counts 0 there)."""

    name: str
    counts: NDArray[np.uint8]
    radiance: NDArray[np.float32]
    failed: NDArray[np.bool_]
    newton_max: int


def trace_pixels(
    orbit: TruthOrbit,
    attitude: Attitude,
    band: BandModel,
    world: World,
    line_time_s: ArrayLike,
    column: ArrayLike,
) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """Ground points (lat, lon, h) of pixels acquired at ``line_time_s`` by (fractional)
    ``column``, shape (N, 3), and whether each ray met the terrain."""
    t, col = np.broadcast_arrays(
        np.atleast_1d(np.asarray(line_time_s, float)), np.atleast_1d(np.asarray(column, float))
    )
    geo = line_geometry(orbit, attitude, t)
    dirs = apply(geo.ecef_from_sensor, band.look_true.directions(col))
    n = dirs.shape[0]
    out, iters = np.empty((n, 3)), np.empty(n, dtype=np.int64)
    over_blocks(
        _trace_rays, n, geo.position_ecef_m, dirs, *world.terrain_args(), out, iters, grain=256
    )
    return out, iters >= 0


def render_band(
    orbit: TruthOrbit,
    attitude: Attitude,
    hrv: Hrv,
    band: BandModel,
    world: World,
    line_times_s: NDArray[np.float64],
    sun_ecef: NDArray[np.float64],
    rng: np.random.Generator,
    block_lines: int = 256,
) -> RenderedBand:
    """Raw counts of one band over the lines acquired at ``line_times_s`` (module docstring)."""
    n_lines = line_times_s.size
    period = hrv.line_period_s
    look = band.look_true.directions(np.arange(band.look_true.n_columns))
    n_det = look.shape[0]
    offsets, weights = psf_quadrature(hrv.psf_fwhm_px, hrv.psf_samples)
    radiance = np.empty((n_lines, n_det), dtype=np.float32)
    newton_max = 0
    band_index = np.int64(BANDS.index(band.name))
    wargs = world.terrain_args()
    for l0 in range(0, n_lines, block_lines):
        l1 = min(l0 + block_lines, n_lines)
        t = np.concatenate(
            [[line_times_s[l0] - period], line_times_s[l0:l1], [line_times_s[l1 - 1] + period]]
        )
        geo = line_geometry(orbit, attitude, t)
        shape = (t.size, n_det)
        lat, lon, h, x, y, gx, gy = (np.empty(shape) for _ in range(7))
        iters = np.empty(shape, dtype=np.int64)
        over_blocks(
            _trace_grid,
            t.size,
            geo.position_ecef_m,
            geo.ecef_from_sensor,
            look,
            *wargs,
            lat,
            lon,
            h,
            x,
            y,
            gx,
            gy,
            iters,
        )
        newton_max = max(newton_max, int(iters.max()))
        out = np.empty((l1 - l0, n_det))
        over_blocks(
            _radiance,
            l1 - l0,
            lat,
            lon,
            x,
            y,
            gx,
            gy,
            np.asarray(sun_ecef, float),
            band_index,
            wargs[3],
            float(world.rows_m),
            offsets,
            weights,
            out,
        )
        radiance[l0:l1] = out
    failed = ~np.isfinite(radiance)
    signal = band.gain * COUNTS_PER_RADIANCE * np.nan_to_num(radiance) + band.offset_counts
    noisy = signal + hrv.noise_counts * rng.standard_normal(radiance.shape, dtype=np.float32)
    counts = np.clip(np.rint(noisy), 0, 255).astype(np.uint8)
    counts[failed] = 0
    return RenderedBand(band.name, counts, radiance, failed, newton_max)
