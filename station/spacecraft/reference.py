"""A reference ortho-image of the emulated world, as another sensor would give it
(issue 51): what a user registers a SPOT scene to (a Sentinel-2 scene on ESA's Global
Reference Image, a Landsat Collection 2 Tier 1 scene).

:func:`render_reference` renders the world's reflectance in one band onto a map grid (UTM
of the area's centre, or geographic), each pixel the mean of ``SUBPIXELS``² samples over
its area (the other sensor's integration), with:

- its **own geolocation error**: pixel ``(x, y)`` shows the ground at ``(x, y) + b``, ``b``
  a bias (east, north) drawn from ``error_ce95_m`` (per-axis σ = CE95 / 2.4477, the
  circular error's 95 % radius of a two-dimensional normal), plus ``bias_east_m``,
  ``bias_north_m``;
- a **radiometric change**: ``gain · ρ + offset``, times ``1 + season · f(x, y)``, ``f`` a
  smooth field of unit amplitude over ``SEASON_SCALE_M`` (another season, another sensor);
- **clouds** over ``cloud_fraction`` of the area (smooth blobs, bright and flat: no texture
  to match).

:func:`write_reference` writes it as a float32 GeoTIFF (NaN outside, its nodata) with its
truth beside (``<stem>.json``: the bias, the CE95, the band, the changes), so
that the control points found on it can be scored against where its pixels really are.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pyproj
from numpy.typing import NDArray

from station.scenario import ReferenceConfig

if TYPE_CHECKING:
    from collections.abc import Sequence

    from station.scenario import Scenario
    from station.spacecraft.emulator import Acquisition
    from station.spacecraft.world import World

__all__ = [
    "CE95_PER_SIGMA",
    "SUBPIXELS",
    "ReferenceImage",
    "export_reference",
    "reference_path",
    "render_reference",
    "write_reference",
]

#: A two-dimensional normal's 95 % circular radius, in per-axis σ: √(−2 ln 0.05).
CE95_PER_SIGMA = 2.4477
#: Samples per pixel side averaged into a reference pixel.
SUBPIXELS = 3
#: Rows of the reference rendered at a time.
BLOCK_ROWS = 256
#: The scale of the seasonal change's smooth field (m).
SEASON_SCALE_M = 3000.0


@dataclass(frozen=True, eq=False)
class ReferenceImage:
    """The rendered reference: its image (float32, NaN outside), map grid and truth."""

    image: NDArray[np.float32]
    crs_wkt: str
    geotransform: tuple[float, float, float, float, float, float]  # GDAL's, north up
    bias_m: tuple[float, float]
    config: ReferenceConfig

    @property
    def pixel_size_m(self) -> float:
        return self.geotransform[1]

    @property
    def sigma_m(self) -> float:
        """Its stated accuracy, per axis (m): CE95 / 2.4477."""
        return self.config.error_ce95_m / CE95_PER_SIGMA

    def truth(self) -> dict[str, object]:
        return {  # the configuration's own biases are in the drawn ones: those replace them
            **asdict(self.config),
            "bias_east_m": self.bias_m[0],
            "bias_north_m": self.bias_m[1],
            "sigma_m": self.sigma_m,
            "rule": "pixel (x, y) shows the ground at (x + bias_east_m, y + bias_north_m)",
        }


def _smooth_field(shape: tuple[int, int], scale_px: float, rng: np.random.Generator) -> NDArray:
    """A smooth random field of unit standard deviation, correlated over ``scale_px``."""
    from scipy.ndimage import gaussian_filter

    f = gaussian_filter(rng.standard_normal(shape), max(scale_px / 2.0, 1.0), mode="wrap")
    return np.asarray(f / max(float(f.std()), 1e-12))


def render_reference(
    world: World,
    lat_range_rad: tuple[float, float],
    lon_range_rad: tuple[float, float],
    config: ReferenceConfig,
    seed: int,
) -> ReferenceImage:
    """The reference image of the world over the ranges (module docstring)."""
    rng = np.random.default_rng(seed)
    lat_c, lon_c = float(np.mean(lat_range_rad)), float(np.mean(lon_range_rad))
    if config.projection == "utm":  # the zone of the area's centre, north or south
        zone = int(np.floor((np.degrees(lon_c) + 180.0) / 6.0)) % 60 + 1
        crs = pyproj.CRS.from_epsg((32600 if lat_c >= 0 else 32700) + zone)
    else:
        crs = pyproj.CRS.from_user_input(config.projection)
    to_map = pyproj.Transformer.from_crs("EPSG:4326", crs, always_xy=True)
    lons, lats = np.meshgrid(np.degrees(lon_range_rad), np.degrees(lat_range_rad))
    x, y = to_map.transform(lons.ravel(), lats.ravel())
    px = config.pixel_size_m
    x0, y1 = np.floor(min(x) / px) * px, np.ceil(max(y) / px) * px
    n_cols = int(np.ceil((max(x) - x0) / px))
    n_rows = int(np.ceil((y1 - min(y)) / px))
    gt = (float(x0), float(px), 0.0, float(y1), 0.0, -float(px))
    sigma = config.error_ce95_m / CE95_PER_SIGMA
    drawn = sigma * rng.standard_normal(2)
    bias = (config.bias_east_m + drawn[0], config.bias_north_m + drawn[1])
    rho = _integrated(world, crs.to_wkt(), gt, (n_rows, n_cols), config.band, bias)
    image = config.gain * rho + config.offset
    if config.season:
        image *= 1.0 + config.season * _smooth_field(image.shape, SEASON_SCALE_M / px, rng)
    if config.cloud_fraction > 0:
        blobs = _smooth_field(image.shape, 2000.0 / px, rng)
        cloud = blobs > np.quantile(blobs, 1.0 - config.cloud_fraction)
        image = np.where(cloud, 0.9 * float(np.nanmax(image)), image)
    bias_m = (float(bias[0]), float(bias[1]))
    return ReferenceImage(image.astype(np.float32), crs.to_wkt(), gt, bias_m, config)


def _integrated(
    world: World,
    crs_wkt: str,
    gt: tuple[float, ...],
    shape: tuple[int, int],
    band: str,
    bias: tuple[float, float],
) -> NDArray:
    """The world's reflectance averaged over each pixel (``SUBPIXELS``² samples), each
    pixel showing the ground ``bias`` (east, north) from its nominal place; by blocks of
    ``BLOCK_ROWS`` rows (a full scene at 10 m is 324 million samples)."""
    to_geo = pyproj.Transformer.from_crs(crs_wkt, "EPSG:4326", always_xy=True)
    px, k = gt[1], SUBPIXELS
    n_rows, n_cols = shape
    offsets = (np.arange(k) + 0.5) / k * px - 0.5 * px
    x_centres = gt[0] + (np.arange(n_cols) + 0.5) * px
    xs = (x_centres[:, None] + offsets[None, :]).ravel() + bias[0]  # (n_cols · k)
    ys = gt[3] - (np.arange(n_rows) + 0.5) * px + bias[1]
    out = np.empty(shape)
    for r0 in range(0, n_rows, BLOCK_ROWS):
        y = (ys[r0 : r0 + BLOCK_ROWS, None] + offsets[None, :]).ravel()  # (rows · k)
        x2, y2 = np.meshgrid(xs, y)
        lon, lat = to_geo.transform(x2.ravel(), y2.ravel())
        rho = world.reflectance(np.radians(lat), np.radians(lon), band)
        n = y.size // k
        out[r0 : r0 + n] = rho.reshape(n, k, n_cols, k).mean(axis=(1, 3))
    return out


def write_reference(path: str | Path, ref: ReferenceImage) -> Path:
    """The reference as a float32 GeoTIFF (atomically) and its truth beside it
    (``<stem>.json``); returns the GeoTIFF's path."""
    import rasterio
    from rasterio.transform import Affine

    from levels.files import atomic_path

    target = Path(path)
    profile = {
        "driver": "GTiff",
        "width": ref.image.shape[1],
        "height": ref.image.shape[0],
        "count": 1,
        "dtype": "float32",
        "crs": ref.crs_wkt,
        "transform": Affine.from_gdal(*ref.geotransform),
        "nodata": float("nan"),
        "compress": "deflate",
    }
    with atomic_path(target) as tmp, rasterio.open(tmp, "w", **profile) as ds:
        ds.write(ref.image[None])
        ds.set_band_description(1, f"reference {ref.config.band}")
    truth = target.with_suffix(".json")
    truth.write_text(json.dumps(ref.truth(), indent=2) + "\n", encoding="utf-8")
    return target


def reference_path(scn: Scenario, out: Path) -> Path:
    """Where a run's reference image is: the scenario's ``[reference] file``, else the
    one the run renders (``<name>.reference.tif`` in ``out``)."""
    cfg = scn.reference
    if cfg is not None and cfg.file:
        return Path(scn.path(cfg.file))
    return out / f"{scn.name}.reference.tif"


def export_reference(scn: Scenario, acqs: Sequence[Acquisition], out: Path) -> Path | None:
    """The scenario's ``[reference]`` over its pass (the strips' footprint and the
    section's margin) written as ``<name>.reference.tif`` into ``out``; its ``file`` as it
    is (checked to exist: two passes registered to one reference); None without."""
    from station.spacecraft.dem import footprint_rad

    cfg = scn.reference
    if cfg is None:
        return None
    if cfg.file:
        path = reference_path(scn, out)
        if not path.is_file():
            from station.errors import ScenarioError

            raise ScenarioError(f"[reference] file = {cfg.file!r}: no such file ({path})")
        return path
    south, north, west, east = footprint_rad(acqs)
    m = cfg.margin_km * 1e3 / 6.371e6
    mlon = m / max(np.cos(0.5 * (south + north)), 0.1)
    ref = render_reference(
        acqs[0].world, (south - m, north + m), (west - mlon, east + mlon), cfg, scn.seed + 51
    )
    return write_reference(out / f"{scn.name}.reference.tif", ref)
