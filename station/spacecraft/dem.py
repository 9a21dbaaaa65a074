"""The emulated world's terrain exported as the DEM a station is handed (level 3, GTC):
over a pass's footprint or a frame's, with errors of a known size. The world's own terrain
from SRTM tiles is :mod:`station.spacecraft.hgt`'s.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from scipy.ndimage import gaussian_filter

from station.spacecraft.hgt import DemError

if TYPE_CHECKING:
    from station.scenario import DemConfig
    from station.spacecraft.emulator import Acquisition
    from station.spacecraft.world import World

__all__ = ["export_dem", "export_dem_over", "footprint_rad", "world_dem"]

#: Edge pixels traced per side of each strip to find its footprint.
_FOOTPRINT_SAMPLES = 64
_NODATA = -32768.0
_EARTH_RADIUS_M = 6371e3  # mean: sizes the grid and the error's correlation in nodes


def footprint_rad(acqs: Sequence[Acquisition]) -> tuple[float, float, float, float]:
    """South, north, west, east bounds (rad) of the terrain the strips truly see; across
    the antimeridian, west or east beyond ±π."""
    from station.spacecraft.imaging import trace_pixels

    lat, lon = [], []
    for acq in acqs:
        t0, t1 = acq.line_times_s[0], acq.line_times_s[-1]
        n_col = acq.hrv.n_columns - 1
        s = np.linspace(0.0, 1.0, _FOOTPRINT_SAMPLES)
        along, across, n = t0 + s * (t1 - t0), s * n_col, s.size
        # the first and last columns along the strip, the first and last lines across it
        t = np.concatenate([along, along, np.full(n, t0), np.full(n, t1)])
        col = np.concatenate([np.zeros(n), np.full(n, n_col), across, across])
        pts, ok = trace_pixels(acq.orbit, acq.attitude, acq.hrv.bands[0], acq.world, t, col)
        lat.append(pts[ok, 0])
        lon.append(pts[ok, 1])
    la, lo = np.concatenate(lat), np.concatenate(lon)
    if not la.size:
        raise DemError("[dem]: no pixel of the pass meets the world's terrain; nothing to export")
    # unwrapped around the first point: a pass across the antimeridian spans 180° ± a
    # little, not the whole globe (west or east then lies beyond ±180°, as GDAL allows)
    lo = lo[0] + (lo - lo[0] + np.pi) % (2 * np.pi) - np.pi
    return float(la.min()), float(la.max()), float(lo.min()), float(lo.max())


def export_dem(acqs: Sequence[Acquisition], cfg: DemConfig, seed: int, path: str | Path) -> Path:
    """The world's terrain under the pass as a GeoTIFF DEM of known quality (``[dem]``).

    The grid is geographic (WGS84, ellipsoidal heights, north-up), every
    ``cfg.spacing_arcsec`` over the strips' footprint plus ``cfg.margin_km``; its nodes are
    the world's heights plus an error of 1σ ``cfg.error_rms_m`` (white, or Gaussian-
    correlated over ``cfg.error_correlation_m`` and scaled back to that 1σ), drawn from the
    scenario's ``seed``. Voids of the world (outside a real tile) are no-data. Written
    atomically; returns the path.
    """
    return export_dem_over(acqs[0].world, footprint_rad(acqs), cfg, seed, path)


def export_dem_over(
    world: World,
    footprint: tuple[float, float, float, float],
    cfg: DemConfig,
    seed: int,
    path: str | Path,
) -> Path:
    """:func:`export_dem` over a footprint (south, north, west, east; radians) of ``world``:
    a SAR frame's, or the pass's strips'."""
    import rasterio
    from rasterio.transform import Affine

    from levels.files import atomic_path

    south, north, west, east = footprint
    margin = cfg.margin_km * 1e3 / _EARTH_RADIUS_M
    step = np.radians(cfg.spacing_arcsec / 3600.0)
    coslat = max(np.cos(max(abs(south), abs(north))), 1e-3)
    lat0 = np.floor((south - margin) / step) * step
    lon0 = np.floor((west - margin / coslat) / step) * step
    n_lat = int(np.ceil((north + margin - lat0) / step)) + 1
    n_lon = int(np.ceil((east + margin / coslat - lon0) / step)) + 1
    if n_lat * n_lon > 2e8:
        raise DemError(
            f'[dem]: {n_lat} × {n_lon} nodes at {cfg.spacing_arcsec:g}" is too large a grid; '
            "take a coarser spacing_arcsec"
        )
    grid = world.dem((lat0, lat0 + (n_lat - 1) * step), (lon0, lon0 + (n_lon - 1) * step), step)
    h = grid.height_m
    if cfg.error_rms_m > 0:
        rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(0x0DE3,)))
        noise = rng.standard_normal(h.shape)
        if cfg.error_correlation_m > 0:
            sigma = cfg.error_correlation_m / (step * _EARTH_RADIUS_M)  # in nodes
            noise = gaussian_filter(noise, sigma, mode="wrap")
            noise /= noise.std()
        h = h + cfg.error_rms_m * noise
    north_up = np.where(np.isnan(h), _NODATA, h)[::-1].astype(np.float32)
    deg = np.degrees(step)
    west_deg, north_deg = np.degrees(grid.lon_rad[0]), np.degrees(grid.lat_rad[-1])
    profile = {
        "driver": "GTiff",
        "width": h.shape[1],
        "height": h.shape[0],
        "count": 1,
        "dtype": "float32",
        "crs": "EPSG:4326",
        # pixel-is-area: the node (row 0, column 0) is the centre of the first pixel
        "transform": Affine(deg, 0.0, west_deg - deg / 2, 0.0, -deg, north_deg + deg / 2),
        "nodata": _NODATA,
        "tiled": True,
        "compress": "deflate",
        "predictor": 3,
    }
    out = Path(path)
    with atomic_path(out) as tmp, rasterio.open(tmp, "w", **profile) as ds:
        ds.write(north_up, 1)
        ds.update_tags(
            source="spot-station emulated world",
            vertical_datum="WGS84 ellipsoid",
            error_rms_m=str(cfg.error_rms_m),
            error_correlation_m=str(cfg.error_correlation_m),
            spacing_arcsec=str(cfg.spacing_arcsec),
        )
    return out


def world_dem(
    world: World,
    lat_range_rad: tuple[float, float],
    lon_range_rad: tuple[float, float],
    spacing_deg: float,
    error_rms_m: float,
    rng: np.random.Generator,
) -> Any:
    """The world's terrain as the processing centre reads a DEM
    (:class:`levels.geometry.dem.Dem`, WGS84 geographic, ellipsoidal heights, north-up),
    every ``spacing_deg`` over the ranges, with white errors of ``error_rms_m``: a DEM in
    memory for the geometry studies (tests, tools), as :func:`export_dem` writes one."""
    import pyproj

    from levels.geometry.dem import Dem

    grid = world.dem(lat_range_rad, lon_range_rad, np.radians(spacing_deg), error_rms_m, rng)
    d = spacing_deg
    west, north = np.degrees(grid.lon_rad[0]) - d / 2, np.degrees(grid.lat_rad[-1]) + d / 2
    return Dem(
        grid.height_m[::-1],
        (west, d, 0.0, north, 0.0, -d),
        pyproj.CRS.from_epsg(4326).to_wkt(),
        "ellipsoid",
        "the emulated world",
    )
