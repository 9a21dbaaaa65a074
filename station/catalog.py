"""A STAC catalogue of an output directory's products (pystac), written with them.

Each run, reprocessing and campaign writes ``catalog.json`` at its root: one Item per level
product, a child catalogue per sub-directory holding products (a campaign's archives), all
links relative (``CatalogType.SELF_CONTAINED``), so the catalogue stays valid wherever the
directory is moved and is published with it, whole. Items live under ``stac/``.

An Item says, from the product alone:

- where and when: the scene's footprint on its reference surface (corners as GEO located
  them; split at the antimeridian, RFC 7946 §3.1.9) and its centre instant;
- how it was seen (``view``): the mirror's off-nadir angle, the incidence and azimuth of
  the line of sight at the scene centre, the Sun's elevation and azimuth there;
- from where (``sat``): the orbit state at the centre;
- on which grid (``proj``): the map levels' EPSG code (or WKT2), shape and transform; the
  image-geometry levels ``proj:code`` null, with their RPCs as an asset;
- how it was made (``processing``): level, facility, software, and the product's quality
  figures (``spot:quality``: the headline numbers of ``station inspect``);
- assets: the product (``data``), its RPC sidecar (``metadata``), its quicklook
  (``thumbnail``).
"""

from __future__ import annotations

import datetime as dt
import logging
from collections.abc import Iterable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from levels.kinds import Unit
from levels.products import Product, is_product_file, read_product
from levels.registry import kind_of

if TYPE_CHECKING:
    import pystac

_log = logging.getLogger(__name__)

__all__ = ["CATALOG_FILE", "EXTENSIONS", "footprint_geojson", "item_of", "write_catalog"]

CATALOG_FILE = "catalog.json"
#: The STAC extensions an Item may declare, by the prefix of their fields: an Item declares
#: those it has a field of (a validator that fetches the schemas rejects an extension
#: declared with none: a DEM has no view, a GEC no sat).
EXTENSIONS = {
    "proj:": "https://stac-extensions.github.io/projection/v2.0.0/schema.json",
    "view:": "https://stac-extensions.github.io/view/v1.0.0/schema.json",
    "sat:": "https://stac-extensions.github.io/sat/v1.0.0/schema.json",
    "processing:": "https://stac-extensions.github.io/processing/v1.2.0/schema.json",
}


def _extensions(fields: Iterable[str]) -> list[str]:
    """The schemas of the extensions of which ``fields`` (an Item's properties) hold one."""
    keys = list(fields)
    return [url for prefix, url in EXTENSIONS.items() if any(k.startswith(prefix) for k in keys)]


_MEDIA = {".nc": "application/netcdf", ".h5": "application/x-hdf5"}


def _clip(ring: list[tuple[float, float]], keep_west: bool) -> list[tuple[float, float]]:
    """Sutherland–Hodgman clip of a ring (unwrapped longitudes) to one side of 180°."""
    out: list[tuple[float, float]] = []

    def inside(p: tuple[float, float]) -> bool:
        return p[0] <= 180.0 if keep_west else p[0] >= 180.0

    for k, p in enumerate(ring):
        q = ring[k - 1]
        if inside(p) != inside(q):
            f = (180.0 - q[0]) / (p[0] - q[0])
            out.append((180.0, q[1] + f * (p[1] - q[1])))
        if inside(p):
            out.append(p)
    return out


def footprint_geojson(
    lat_deg: np.ndarray, lon_deg: np.ndarray
) -> tuple[dict[str, Any], list[float]]:
    """A GeoJSON Polygon (counter-clockwise, RFC 7946) of the corners, and its bbox; a
    MultiPolygon split at 180° for a scene across the antimeridian (bbox west > east)."""
    lon = np.asarray(lon_deg, dtype=np.float64)
    lat = np.asarray(lat_deg, dtype=np.float64)
    lon = lon[0] + (lon - lon[0] + 180.0) % 360.0 - 180.0  # continuous around the first
    lon = lon - 360.0 * np.floor((lon.mean() + 180.0) / 360.0)  # centre within ±180°
    ring = list(zip(lon.tolist(), lat.tolist(), strict=True))
    x, y = lon, lat
    if 0.5 * np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y) < 0:  # clockwise
        ring = ring[::-1]
    if lon.max() > 180.0 or lon.min() < -180.0:
        if lon.min() < -180.0:
            ring = [(a + 360.0, b) for a, b in ring]
        west = _clip(ring, keep_west=True)
        east = [(a - 360.0, b) for a, b in _clip(ring, keep_west=False)]
        polys = [[[list(p) for p in (*part, part[0])]] for part in (west, east)]
        geometry = {"type": "MultiPolygon", "coordinates": polys}
        bbox = [min(a for a, _ in west), float(lat.min()), max(a for a, _ in east)]
        return geometry, [bbox[0], bbox[1], bbox[2], float(lat.max())]
    geometry = {"type": "Polygon", "coordinates": [[list(p) for p in (*ring, ring[0])]]}
    return geometry, [float(lon.min()), float(lat.min()), float(lon.max()), float(lat.max())]


def _centre_view(product: Product) -> dict[str, Any]:
    """Incidence and azimuth of the line of sight, the Sun's elevation and azimuth, and
    the orbit state, at the scene centre (degrees)."""
    from levels.geo.scenes import models_of_tree
    from levels.geometry.frames import apply, enu_from_ecef
    from station.spacecraft.sun import sun_direction_ecef

    epoch, models = models_of_tree(product.geometry)
    model = next(iter(models.values()))
    line, col = (model.n_lines - 1) / 2.0, (model.n_columns - 1) / 2.0
    h = float(product.geometry.get("reference_height_m", 0.0))
    g = model.image_to_ground(line, col, h)
    t = model.clock.time_s(np.array([line]))
    r_sat, v_sat = model.ephemeris.interpolate(t)
    ground = model.ellipsoid.to_ecef(g.lat_rad, g.lon_rad, g.h_m)
    enu = enu_from_ecef(g.lat_rad, g.lon_rad)
    to_sat = apply(enu, r_sat - ground)[0]
    to_sun = apply(enu, sun_direction_ecef(epoch, t))[0]

    def elevation_azimuth(v: np.ndarray) -> tuple[float, float]:
        v = v / np.linalg.norm(v)
        return float(np.degrees(np.arcsin(v[2]))), float(np.degrees(np.arctan2(v[0], v[1])) % 360)

    sat_el, sat_az = elevation_azimuth(to_sat)
    sun_el, sun_az = elevation_azimuth(to_sun)
    return {
        "view:incidence_angle": 90.0 - sat_el,
        "view:azimuth": sat_az,
        "view:sun_elevation": sun_el,
        "view:sun_azimuth": sun_az,
        "sat:orbit_state": "descending" if v_sat[0, 2] < 0 else "ascending",
        "datetime": epoch.utc(t)[0],
    }


def _quality(product: Product, path: Path) -> dict[str, Any]:
    """The product's headline quality figures, numbers and words only."""
    from levels.inspect import product_summary

    out: dict[str, Any] = {}
    for k, v in product_summary(product, path).get("quality", {}).items():
        if isinstance(v, str):
            out[k] = v
        elif isinstance(v, (int, float, np.number)) and np.isfinite(v):
            out[k] = float(v)
    return out


def _grid_item(product: Product, path: Path, props: dict[str, Any]) -> Any:
    """The STAC Item of a map product without a scene's sensor model (a stereo pair's DEM,
    a SAR frame's GEC or GTC): the map grid's footprint; its instants and its own
    properties as its kind declares them (``props``: :attr:`levels.kinds.ProductKind.stac`)."""
    import pyproj
    import pystac

    grid = product.map_grid
    if grid is None or not (props.get("datetime") or props.get("start_datetime")):
        # neither a scene's sensor model nor a map grid and a time: nothing to place it by
        _log.warning(
            "%s: a %s product says neither where nor when it is; not in the catalogue",
            path.name,
            product.level,
        )
        return None
    gt, (rows, cols) = grid.geotransform, grid.shape
    x = np.array([gt[0], gt[0] + cols * gt[1], gt[0] + cols * gt[1], gt[0]])
    y = np.array([gt[3], gt[3], gt[3] + rows * gt[5], gt[3] + rows * gt[5]])
    lon, lat = pyproj.Transformer.from_crs(
        pyproj.CRS.from_wkt(grid.crs_wkt), pyproj.CRS.from_epsg(4326), always_xy=True
    ).transform(x, y)
    geometry, bbox = footprint_geojson(np.asarray(lat), np.asarray(lon))
    epsg = pyproj.CRS.from_wkt(grid.crs_wkt).to_epsg()
    when = {k: props.pop(k, None) for k in ("datetime", "start_datetime", "end_datetime")}
    description = props.pop("description", "")
    item = pystac.Item(
        id=path.stem,
        geometry=geometry,
        bbox=bbox,
        datetime=when["datetime"],
        start_datetime=when["start_datetime"],
        end_datetime=when["end_datetime"],
        properties=(
            properties := {
                "title": str(product.attrs.get("name", path.stem)),
                **props,
                "proj:code": f"EPSG:{epsg}" if epsg else None,
                "proj:shape": [rows, cols],
                "proj:transform": [gt[1], gt[2], gt[0], gt[4], gt[5], gt[3]],
                "gsd": float(abs(gt[1])),
            }
        ),
        stac_extensions=_extensions(properties),
    )
    _add_assets(item, path, f"{product.level} product of {description}".strip())
    return item


def item_of(path: Path, root: Path) -> Any:
    """The STAC Item of the product at ``path`` (module docstring); asset hrefs are made
    relative when the catalogue is saved."""
    import pystac

    from levels.geometry.sensor import mirror_angle_rad
    from station import __version__

    product = read_product(path, images=False)
    known = kind_of(product)
    declared = known.stac(product) if known is not None else {}
    if known is None or known.unit is not Unit.SCENE:  # a pair's DEM, a SAR frame's
        return _grid_item(product, path, dict(declared))
    a, scene = product.attrs, product.geometry["scene"]
    geometry, bbox = footprint_geojson(scene["corners_lat_deg"], scene["corners_lon_deg"])
    view = _centre_view(product)
    when = view.pop("datetime").astype("datetime64[us]").astype(dt.datetime)
    level = str(product.level)
    props: dict[str, object] = {
        "title": str(a.get("title", path.stem)),
        "constellation": "spot",
        **_platform(product),
        "spot:mode": str(a.get("mode", "")),
        "spot:scene_index": int(a.get("scene_index", 0)),
        "spot:mirror_step": int(a.get("mirror_step", 48)),
        "view:off_nadir": abs(float(np.degrees(mirror_angle_rad(int(a.get("mirror_step", 48)))))),
        **view,
        "processing:level": declared.get("processing:level", f"L{level}"),
        "processing:facility": "spot-station SIPC (emulated)",
        "processing:software": {"spot-station": __version__},
        "spot:quality": _quality(product, path),
    }
    props.update(_projection(product))
    item = pystac.Item(
        id=path.stem,
        geometry=geometry,
        bbox=bbox,
        datetime=when.replace(tzinfo=dt.UTC),
        properties=props,
        stac_extensions=_extensions(props),
    )
    _add_assets(item, path, f"level {level} product")
    return item


def _platform(product: Product) -> dict[str, object]:
    """The platform and instrument: an emulated pass's, or those of the real scene a
    product was made from (``levels.readers.scene1a``: ``spot-2``, ``hrv1``; its file and
    imaging date as ``spot:source``, ``spot:imaging_date``)."""
    from levels.readers.scene1a import ROUTE

    prov, a = product.provenance, product.attrs
    if prov.get("route") != ROUTE:
        return {"platform": "spot-emulated", "instruments": [f"hrv{a.get('hrv', 1)}"]}
    mission = str(prov.get("mission", "SPOT")).lower().replace(" ", "-")
    return {
        "platform": mission,
        "instruments": [str(prov.get("instrument", "")).lower()],
        "spot:source": str(prov.get("source", "")),
        "spot:imaging_date": str(prov.get("imaging_date", "")),
    }


def _projection(product: Product) -> dict[str, object]:
    """The ``proj`` properties of a scene's product: a map level's EPSG code (or WKT2),
    shape and transform; an image-geometry level's shape, ``proj:code`` null (located by
    its RPCs, the asset ``rpc``)."""
    a, grid = product.attrs, product.map_grid
    props: dict[str, object] = {"proj:shape": [int(a["n_rows"]), int(a["n_cols"])]}
    if grid is None:
        return {"proj:code": None, **props}
    import pyproj

    crs = pyproj.CRS.from_wkt(grid.crs_wkt)
    epsg = crs.to_epsg()
    props["proj:code"] = f"EPSG:{epsg}" if epsg else None
    if not epsg:
        props["proj:wkt2"] = crs.to_wkt()
    gt = grid.geotransform
    props["proj:transform"] = [gt[1], gt[2], gt[0], gt[4], gt[5], gt[3]]
    props["gsd"] = float(abs(gt[1]))
    return props


def _add_assets(item: pystac.Item, path: Path, title: str) -> None:
    """An Item's assets: the product (``data``), its RPC sidecar (``rpc``) and its
    quicklook (``thumbnail``) where they are beside it."""
    import pystac

    item.add_asset(
        "data",
        pystac.Asset(
            href=str(path.resolve()),
            media_type=_MEDIA.get(path.suffix, "application/x-hdf5"),
            roles=["data"],
            title=title,
        ),
    )
    sidecar = Path(f"{path}.aux.xml")
    if sidecar.is_file():
        item.add_asset(
            "rpc",
            pystac.Asset(
                href=str(sidecar.resolve()),
                media_type="application/xml",
                roles=["metadata"],
                title="RPCs (GDAL PAM sidecar)",
            ),
        )
    quicklook = path.parent / "quicklooks" / f"{path.stem}.png"
    if quicklook.is_file():
        item.add_asset(
            "thumbnail",
            pystac.Asset(
                href=str(quicklook.resolve()),
                media_type=pystac.MediaType.PNG,
                roles=["thumbnail"],
                title="quicklook",
            ),
        )


def _fill(catalog: pystac.Catalog, directory: Path, root: Path) -> int:
    """Add the products of ``directory`` as Items and its sub-directories holding
    products as child catalogues; the number of Items added."""
    import pystac

    n = 0
    for path in sorted(p for p in directory.iterdir() if p.is_file() and is_product_file(p)):
        item = item_of(path, root)
        if item is not None:
            catalog.add_item(item)
            n += 1
    for sub in sorted(p for p in directory.iterdir() if p.is_dir() and p.name != "stac"):
        child = pystac.Catalog(id=sub.name, description=f"the products of {sub.name}")
        if _fill(child, sub, root):
            catalog.add_child(child)
            n += 1
    return n


def write_catalog(directory: str | Path, name: str, description: str) -> Path:
    """Write the STAC catalogue of ``directory``'s products (module docstring); returns
    ``catalog.json``'s path."""
    import pystac

    root = Path(directory)
    catalog = pystac.Catalog(id=name, description=description, title=name)
    _fill(catalog, root, root)
    catalog.normalize_hrefs(str(root / "stac"))
    catalog.set_self_href(str(root / CATALOG_FILE))
    catalog.make_all_asset_hrefs_relative()
    catalog.save(pystac.CatalogType.SELF_CONTAINED)
    return root / CATALOG_FILE
