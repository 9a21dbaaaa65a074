"""The emulated ground: terrain height and reflectance as continuous functions of (φ, λ).

Because every function here is defined at any latitude and longitude, the truth exists at
any resolution: the imaging kernel samples it where each ray lands, a DEM for level 3 can be
exported at any spacing, and a checkpoint can be put anywhere.

Coordinates
    The functions are built on metric coordinates of a sinusoidal projection about the
    world's central meridian λ0: ``x = a (λ − λ0) cos φ``, ``y = a φ`` (a: WGS84 semi-major
    axis). Within a few hundred km of λ0 the projection's shear is below a degree, so
    features keep their shapes; the functions stay continuous everywhere else.

Terrain
    ``H = base + relief · Σ_k 0.5^k n(2^k x / λ_0, 2^k y / λ_0)`` over ``TERRAIN_OCTAVES``
    octaves of value noise ``n`` (hashed lattice values, quintic interpolation, analytic
    gradient), from λ_0 = 40 km down to 160 m. Its gradient, computed with it, gives the
    Newton steps of the ray intersection and the surface normal for shading.

Reflectance (per band: P, XS1 green, XS2 red, XS3 near infrared)
    Fields: a lattice of 400 m × 300 m parcels turned 17°, each of a class drawn by hash
    (bare soil, two crops, dry grass, forest) with a little texture; roads along every 5th
    and 7th parcel edge (12 m wide); rivers where a low-frequency noise crosses zero
    (distance to the contour ≈ |n| / |∇n|, 40 m wide); forest where another noise is high.
    Reflectances are typical values for those covers in SPOT's bands. With ``rows_m`` > 0
    every parcel is planted in rows of that period (±25 % of its reflectance, its fine
    texture mostly gone): a periodic field, where a correlation's peaks repeat every row.

Radiance
    Lambertian: ``L = ρ · max(0, n̂ · ŝ)`` with n̂ the terrain normal and ŝ the Sun; a flat
    field in the Sun at zenith angle θ gives ``ρ cos θ``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba as nb
import numpy as np
from numpy.typing import ArrayLike, NDArray

from levels.geometry.ellipsoid import WGS84
from levels.threads import over_blocks

__all__ = [
    "BANDS",
    "TERRAIN_OCTAVES",
    "DemGrid",
    "World",
]

#: Band names and their index in the reflectance tables.
BANDS = ("P", "XS1", "XS2", "XS3")
TERRAIN_OCTAVES = 8
_A_M = WGS84.a_m
_TERRAIN_WAVELENGTH_M = 40_000.0
_TERRAIN_NORM = 1.0 / 0.42  # value-noise fBm of 8 octaves has std ≈ 0.42: relief_m is ~1σ

# reflectance per class: bare soil, crop A, crop B, dry grass, forest, road, water
_REFLECTANCE = np.array(
    [
        # P     XS1   XS2   XS3
        [0.14, 0.12, 0.16, 0.22],
        [0.07, 0.08, 0.05, 0.42],
        [0.09, 0.10, 0.08, 0.32],
        [0.14, 0.13, 0.15, 0.26],
        [0.045, 0.05, 0.03, 0.30],
        [0.21, 0.20, 0.22, 0.24],
        [0.05, 0.06, 0.04, 0.02],
    ]
)
_PARCEL_U_M, _PARCEL_V_M = 400.0, 300.0
_PARCEL_ANGLE_RAD = np.radians(17.0)
_ROAD_HALF_WIDTH_M = 6.0
_RIVER_HALF_WIDTH_M = 20.0
_RIVER_WAVELENGTH_M = 9_000.0
_FOREST_WAVELENGTH_M = 6_000.0


@nb.njit(cache=True, inline="always")
def _hash(ix: np.int64, iy: np.int64, seed: np.int64) -> float:
    """A lattice value in [-1, 1) from integer coordinates (SplitMix64 finaliser)."""
    h = np.uint64(ix) * np.uint64(0x9E3779B97F4A7C15)
    h ^= np.uint64(iy) * np.uint64(0xC2B2AE3D27D4EB4F) + np.uint64(seed)
    h ^= h >> np.uint64(30)
    h *= np.uint64(0xBF58476D1CE4E5B9)
    h ^= h >> np.uint64(27)
    h *= np.uint64(0x94D049BB133111EB)
    h ^= h >> np.uint64(31)
    return (h >> np.uint64(11)) * (2.0 / 9007199254740992.0) - 1.0


@nb.njit(cache=True, inline="always")
def _noise(x: float, y: float, seed: np.int64) -> tuple[float, float, float]:
    """Value noise and its gradient at (x, y) in lattice units."""
    fx, fy = np.floor(x), np.floor(y)
    ix, iy = np.int64(fx), np.int64(fy)
    tx, ty = x - fx, y - fy
    u = tx * tx * tx * (tx * (tx * 6.0 - 15.0) + 10.0)
    v = ty * ty * ty * (ty * (ty * 6.0 - 15.0) + 10.0)
    du = 30.0 * tx * tx * (tx - 1.0) * (tx - 1.0)
    dv = 30.0 * ty * ty * (ty - 1.0) * (ty - 1.0)
    a = _hash(ix, iy, seed)
    b = _hash(ix + 1, iy, seed)
    c = _hash(ix, iy + 1, seed)
    d = _hash(ix + 1, iy + 1, seed)
    k = a - b - c + d
    n = a + (b - a) * u + (c - a) * v + k * u * v
    return n, du * ((b - a) + k * v), dv * ((c - a) + k * u)


@nb.njit(cache=True)
def _to_xy(lat: float, lon: float, lon0: float) -> tuple[float, float]:
    dl = lon - lon0
    dl -= 2 * np.pi * np.floor((dl + np.pi) / (2 * np.pi))
    return _A_M * dl * np.cos(lat), _A_M * lat


@nb.njit(cache=True)
def _terrain(
    x: float, y: float, base: float, relief: float, seed: np.int64
) -> tuple[float, float, float]:
    """Height (m) and its gradient (m/m) at metric (x, y)."""
    h, gx, gy = 0.0, 0.0, 0.0
    freq = 1.0 / _TERRAIN_WAVELENGTH_M
    amp = 1.0
    for k in range(TERRAIN_OCTAVES):
        n, nx, ny = _noise(x * freq + 0.31 * k, y * freq - 0.17 * k, seed + k)
        h += amp * n
        gx += amp * nx * freq
        gy += amp * ny * freq
        freq *= 2.0
        amp *= 0.5
    s = relief * _TERRAIN_NORM
    return base + s * h, s * gx, s * gy


#: The relative contrast of a periodic field's rows (``World.rows_m``).
ROWS_CONTRAST = 0.25


@nb.njit(cache=True)
def _reflectance(x: float, y: float, band: np.int64, seed: np.int64, rows_m: float) -> float:
    """Reflectance of ``band`` at metric (x, y) (module docstring); with ``rows_m`` > 0 the
    parcels are planted in rows of that period (a periodic field)."""
    # rivers: distance to the zero contour of a low-frequency noise
    rn, rx, ry = _noise(x / _RIVER_WAVELENGTH_M, y / _RIVER_WAVELENGTH_M, seed + 101)
    grad = np.sqrt(rx * rx + ry * ry) / _RIVER_WAVELENGTH_M + 1e-12
    if abs(rn) / grad < _RIVER_HALF_WIDTH_M:
        return _REFLECTANCE[6, band]
    ca, sa = np.cos(_PARCEL_ANGLE_RAD), np.sin(_PARCEL_ANGLE_RAD)
    pu = (ca * x + sa * y) / _PARCEL_U_M
    pv = (-sa * x + ca * y) / _PARCEL_V_M
    iu, iv = np.floor(pu), np.floor(pv)
    # roads along every 5th u edge and every 7th v edge
    du = (pu - 5.0 * np.floor(pu / 5.0 + 0.5)) * _PARCEL_U_M
    dv = (pv - 7.0 * np.floor(pv / 7.0 + 0.5)) * _PARCEL_V_M
    if abs(du) < _ROAD_HALF_WIDTH_M or abs(dv) < _ROAD_HALF_WIDTH_M:
        return _REFLECTANCE[5, band]
    fn, _fx, _fy = _noise(x / _FOREST_WAVELENGTH_M, y / _FOREST_WAVELENGTH_M, seed + 202)
    if fn > 0.35:
        cls = np.int64(4)
    else:
        cls = np.int64((_hash(np.int64(iu), np.int64(iv), seed + 303) + 1.0) * 2.0)  # 0..3
    tex, _tx, _ty = _noise(x / 37.0, y / 37.0, seed + 404)
    if rows_m > 0.0:  # rows across the parcels' u axis, the fine texture mostly gone
        rows = np.cos(2.0 * np.pi * (ca * x + sa * y) / rows_m)
        return _REFLECTANCE[cls, band] * (1.0 + ROWS_CONTRAST * rows + 0.02 * tex)
    return _REFLECTANCE[cls, band] * (1.0 + 0.08 * tex)


@nb.njit(cache=True, inline="always")
def _grid_height(lat, lon, grid, geo):
    """Bilinear height of a lat/lon grid (rows: lat from geo[0] by geo[2]; columns: lon from
    geo[1] by geo[3]) and its slopes in metres per metre east and north; NaN outside."""
    n_rows, n_cols = grid.shape
    fr = (lat - geo[0]) / geo[2]
    fc = (lon - geo[1]) / geo[3]
    if not (0.0 <= fr <= n_rows - 1 and 0.0 <= fc <= n_cols - 1):
        return np.nan, 0.0, 0.0
    r = min(np.int64(fr), n_rows - 2)
    c = min(np.int64(fc), n_cols - 2)
    tr, tc = fr - r, fc - c
    h00, h01 = grid[r, c], grid[r, c + 1]
    h10, h11 = grid[r + 1, c], grid[r + 1, c + 1]
    h = (1 - tr) * ((1 - tc) * h00 + tc * h01) + tr * ((1 - tc) * h10 + tc * h11)
    d_row = (1 - tc) * (h10 - h00) + tc * (h11 - h01)
    d_col = (1 - tr) * (h01 - h00) + tr * (h11 - h10)
    return h, d_col / (geo[3] * _A_M * np.cos(lat)), d_row / (geo[2] * _A_M)


@nb.njit(cache=True)
def _surface(lat, lon, x, y, base, relief, seed, grid, geo):
    """The world's terrain at a point: the DEM grid if there is one, else the fractal."""
    if grid.shape[0] > 1:
        return _grid_height(lat, lon, grid, geo)
    return _terrain(x, y, base, relief, seed)


@nb.njit(cache=True, nogil=True)
def _height_many(lo, hi, lat, lon, lon0, base, relief, seed, grid, geo, out, gx, gy):
    for k in range(lo, hi):
        x, y = _to_xy(lat[k], lon[k], lon0)
        out[k], gx[k], gy[k] = _surface(lat[k], lon[k], x, y, base, relief, seed, grid, geo)


@nb.njit(cache=True, nogil=True)
def _reflectance_many(lo, hi, lat, lon, lon0, band, seed, rows_m, out):
    for k in range(lo, hi):
        x, y = _to_xy(lat[k], lon[k], lon0)
        out[k] = _reflectance(x, y, band, seed, rows_m)


#: Points per chunk at least, below which a call runs in the calling thread (one point
#: costs a microsecond or so; a chunk on another thread about a hundred).
_POINTS_PER_CHUNK = 4096


@dataclass(frozen=True)
class DemGrid:
    """A DEM exported from the world: heights (m) on a regular latitude–longitude grid.

    ``lat_rad`` increases with the row, ``lon_rad`` with the column; ``error_rms_m`` is
    the RMS of the error that was added to the truth.
    """

    lat_rad: NDArray[np.float64]
    lon_rad: NDArray[np.float64]
    height_m: NDArray[np.float64]
    error_rms_m: float


@dataclass(frozen=True, eq=False)
class World:
    """The emulated world (module docstring). ``lon0_rad`` is its central meridian.

    With ``terrain_grid`` given, the terrain is that grid, interpolated bilinearly (a real DEM:
    :func:`station.spacecraft.dem.read_hgt`); outside it, or on its voids, heights are NaN
    and rays there are flagged. The reflectance is the synthetic one either way.
    """

    lon0_rad: float
    base_height_m: float = 450.0
    relief_m: float = 250.0
    seed: int = 7
    terrain_grid: DemGrid | None = None
    #: The period of rows planted in every parcel (m; 0: none): a periodic field, whose
    #: texture repeats every ``rows_m`` across them.
    rows_m: float = 0.0

    def terrain_args(self) -> tuple:
        """The world as the numba kernels take it:
        (lon0, base, relief, seed, grid, grid georeference)."""
        if self.terrain_grid is None:
            grid, geo = np.zeros((1, 1)), np.zeros(4)
        else:
            d = self.terrain_grid
            grid = np.ascontiguousarray(d.height_m, dtype=np.float64)
            geo = np.array(
                [
                    d.lat_rad[0],
                    d.lon_rad[0],
                    d.lat_rad[1] - d.lat_rad[0],
                    d.lon_rad[1] - d.lon_rad[0],
                ]
            )
        return (
            self.lon0_rad,
            float(self.base_height_m),
            float(self.relief_m),
            np.int64(self.seed),
            grid,
            geo,
        )

    def height(
        self, lat_rad: ArrayLike, lon_rad: ArrayLike
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """Terrain height (m) and its slopes ∂H/∂x (east), ∂H/∂y (north) at (φ, λ)."""
        lat, lon = np.broadcast_arrays(np.asarray(lat_rad, float), np.asarray(lon_rad, float))
        h, gx, gy = (np.empty(lat.size) for _ in range(3))
        over_blocks(
            _height_many,
            lat.size,
            lat.ravel(),
            lon.ravel(),
            *self.terrain_args(),
            h,
            gx,
            gy,
            grain=_POINTS_PER_CHUNK,
        )
        return h.reshape(lat.shape), gx.reshape(lat.shape), gy.reshape(lat.shape)

    def reflectance(self, lat_rad: ArrayLike, lon_rad: ArrayLike, band: str) -> NDArray:
        """Reflectance of ``band`` (one of :data:`BANDS`) at (φ, λ)."""
        lat, lon = np.broadcast_arrays(np.asarray(lat_rad, float), np.asarray(lon_rad, float))
        out = np.empty(lat.size)
        over_blocks(
            _reflectance_many,
            lat.size,
            lat.ravel(),
            lon.ravel(),
            self.lon0_rad,
            np.int64(BANDS.index(band)),
            np.int64(self.seed),
            float(self.rows_m),
            out,
            grain=_POINTS_PER_CHUNK,
        )
        return out.reshape(lat.shape)

    def dem(
        self,
        lat_range_rad: tuple[float, float],
        lon_range_rad: tuple[float, float],
        spacing_rad: float,
        error_rms_m: float = 0.0,
        rng: np.random.Generator | None = None,
    ) -> DemGrid:
        """The terrain sampled every ``spacing_rad``, with white height errors of
        ``error_rms_m`` (what a DEM of that grade would carry)."""
        lat = np.arange(lat_range_rad[0], lat_range_rad[1] + spacing_rad / 2, spacing_rad)
        lon = np.arange(lon_range_rad[0], lon_range_rad[1] + spacing_rad / 2, spacing_rad)
        h, _, _ = self.height(lat[:, None], lon[None, :])
        if error_rms_m > 0:
            if rng is None:
                raise ValueError("a DEM with errors needs an rng")
            h = h + error_rms_m * rng.standard_normal(h.shape)
        return DemGrid(lat, lon, h, error_rms_m)
