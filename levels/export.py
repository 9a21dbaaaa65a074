"""Export of level products as GeoTIFF (through rasterio, i.e. GDAL).

How a product is exported is its kind's declaration (:class:`levels.kinds.ProductKind`:
``export``, ``export_bands``, ``export_tags``). Its bands (those the kind exports) become
the bands of one GeoTIFF, tiled and DEFLATE-compressed: counts as uint8, the validity mask
the dataset's internal mask (GDAL's per-dataset mask band, which QGIS and GDAL honour), and
pixels not valid 0; a float quantity (a DEM's heights) as float32, NaN its nodata. Band
descriptions carry the band names; the tags carry the level, scene, instrument, the
attributes the kind names and the provenance of the product.

- Kinds on a map grid (``Export.MAP``: 2A, 2, 3, DEM, GEC, GTC): the product's CRS (its
  WKT) and its north-up geotransform.
- Kinds in image geometry (``Export.RPC``: 1A, 1B): the RPCs the product carries
  (:mod:`levels.geo.rpc`, fitted to the rigorous model; the first band's, whose fit error
  goes in ``ERR_RAND``, in metres) in GDAL's RPC metadata, so that ``gdalwarp -rpc -to
  RPC_DEM=dem.tif`` orthorectifies it. A product written before RPCs were is refused with
  a clear error.

The products themselves need no export for that: :func:`write_rpc_sidecar` writes, beside
each 1A and 1B product, the PAM sidecar in which GDAL finds each band's RPCs.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from levels.errors import ProductError
from levels.files import atomic_path, write_text
from levels.geo.rpc import Rpc
from levels.kinds import Export
from levels.products import Product, band_spec, units_of, with_fill
from levels.registry import kind_of
from levels.spot import band_description

__all__ = ["export_identity", "exported_identity", "write_geotiff", "write_rpc_sidecar"]


#: Overviews are built down to this size (px): a viewer shows a whole scene from them.
OVERVIEW_MIN_PX = 256


def _overviews(ds: Any, rows: int, cols: int, flags: bool) -> None:
    """Internal overviews at 2, 4, 8 … until the smaller one fits ``OVERVIEW_MIN_PX``
    (QGIS and gdalinfo show a scene at once, not reading it whole): the average of the
    pixels, the nearest for flags (a mask's classes are not averaged)."""
    from rasterio.enums import Resampling

    factors: list[int] = []
    while max(rows, cols) // (2 ** (len(factors) + 1)) >= OVERVIEW_MIN_PX:
        factors.append(2 ** (len(factors) + 1))
    if factors:
        how = Resampling.nearest if flags else Resampling.average
        ds.build_overviews(factors, how)
        ds.update_tags(ns="rio_overview", resampling=how.name)


def export_identity(product: Product) -> tuple[str, str, str]:
    """What a GeoTIFF export of ``product`` is of: its pass's name, its scene and level (the
    tags :func:`write_geotiff` writes)."""
    a = product.attrs
    return (str(a.get("name", "")), str(a.get("scene_index", "")), str(a.get("level", "")))


def exported_identity(path: str | Path) -> tuple[str, str, str] | None:
    """:func:`export_identity` of the product a GeoTIFF was exported from, from its tags;
    None for a file that is not such an export."""
    import rasterio

    from levels.readers.bounded import gdal_image_alone

    with gdal_image_alone(), rasterio.open(path) as ds:
        if ds.driver != "GTiff":
            return None
        t = ds.tags()
    if "level" not in t or "name" not in t:
        return None
    return (t["name"], t.get("scene_index", ""), t["level"])


def _export(product: Product) -> Export:
    """How the product's kind is exported (:class:`levels.kinds.Export`); a product of a
    kind not known here: by what it holds (a map grid, RPCs, or neither)."""
    known = kind_of(product)
    if known is not None:
        return known.export
    if product.map_grid is not None:
        return Export.MAP
    return Export.RPC if product.geometry.get("rpc") else Export.NONE


def write_rpc_sidecar(product: Product, path: str | Path) -> Path | None:
    """Beside an image-geometry product at ``path``, GDAL's PAM sidecar ``<path>.aux.xml``
    with each band's RPCs in its ``RPC`` metadata domain, so that GDAL finds them on the
    product as written: ``gdalwarp -rpc -to RPC_DEM=dem.tif NETCDF:"<path>":P out.tif``
    (the netCDF driver names the band's subdataset ``P``, the HDF5 driver ``//P``: both are
    given). None (nothing written) for a map level or a product without RPCs."""
    from xml.sax.saxutils import escape, quoteattr

    from levels.files import write_text

    trees = product.geometry.get("rpc") if _export(product) is Export.RPC else None
    if not trees:
        return None
    parts = ["<PAMDataset>"]
    for band, tree in trees.items():
        md = Rpc.from_tree(tree).gdal_metadata()
        items = "".join(f"<MDI key={quoteattr(k)}>{escape(v)}</MDI>" for k, v in md.items())
        for name in (band, f"//{band}"):
            parts.append(
                f"  <Subdataset name={quoteattr(name)}><PAMDataset>"
                f'<Metadata domain="RPC">{items}</Metadata></PAMDataset></Subdataset>'
            )
    parts.append("</PAMDataset>")
    return write_text(Path(f"{path}.aux.xml"), "\n".join(parts) + "\n")


def _georeferencing(product: Product, names: list[str]) -> tuple[dict[str, object], str | None]:
    """How the export is placed: a map level's CRS and transform, or an image-geometry
    level's RPCs (with their OSSIM keyword list, for OTB, :meth:`Rpc.ossim_geom`)."""
    from rasterio.crs import CRS
    from rasterio.rpc import RPC
    from rasterio.transform import Affine

    level, how = product.level, _export(product)
    if how is Export.RPC:
        trees = product.geometry.get("rpc")
        if not trees:
            raise ProductError(
                f"level {level} is in image geometry and this product carries no RPCs "
                "(made before they were written): process its L0 again to export it"
            )
        rpc = Rpc.from_tree(next(iter(trees.values())))
        shape = int(product.attrs["n_rows"]), int(product.attrs["n_cols"])
        return {"rpcs": RPC.from_gdal(rpc.gdal_metadata())}, rpc.ossim_geom(*shape, names)
    if how is Export.MAP:
        grid = product.map_grid
        if grid is None:
            raise ProductError(f"level {level} product without a map grid (no crs variable)")
        return {
            "crs": CRS.from_wkt(grid.crs_wkt),
            "transform": Affine.from_gdal(*grid.geotransform),
        }, None
    raise ProductError(f"level {level}: no GeoTIFF export for it")


def _images(
    product: Product, names: list[str], specs: list[Any]
) -> tuple[list[NDArray[Any]], NDArray[np.bool_], int | None]:
    """The bands as written, where every one is valid, and the fill: the counts' fill where
    not valid (as the product writes it); a quantity beside flags (a GTC's) all float32,
    NaN where not valid."""
    valid = np.logical_and.reduce([product.bands[n].valid for n in names])
    images = [product.bands[n].image for n in names]
    if len({im.dtype for im in images}) > 1:
        return (
            [np.where(valid, im.astype(np.float32), np.float32(np.nan)) for im in images],
            valid,
            None,
        )
    fills = {sp.fill for sp in specs if not sp.quantity and sp.fill is not None}
    fill = int(fills.pop()) if len(fills) == 1 else None
    if fill is not None:
        images = [with_fill(im, valid, fill) for im in images]
    return images, valid, fill


def write_geotiff(product: Product, path: str | Path) -> Path:
    """Write ``product`` (images loaded) as a georeferenced GeoTIFF; returns its path."""
    import rasterio

    known = kind_of(product)
    names = list(known.export_bands) if known and known.export_bands else list(product.bands)
    georef, geom = _georeferencing(product, names)
    tags = known.export_tags if known else ()
    specs = [band_spec(product, n, product.bands[n].image.dtype) for n in names]
    images, valid, fill = _images(product, names, specs)
    rows, cols = images[0].shape
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    profile = {
        "driver": "GTiff",
        "width": cols,
        "height": rows,
        "count": len(names),
        "dtype": str(images[0].dtype),
        # NaN or the counts' fill: what OTB masks (GDAL and QGIS read the internal mask too)
        **({"nodata": float("nan")} if images[0].dtype.kind == "f" else {}),
        **({"nodata": fill} if fill is not None else {}),
        # bands of their own, not a picture: XS1–3 are green, red, near-infrared
        "photometric": "MINISBLACK",
        **georef,
        "tiled": True,
        "blockxsize": 256,
        "blockysize": 256,
        "compress": "deflate",
    }
    a = product.attrs
    with (
        atomic_path(out) as tmp,
        rasterio.Env(GDAL_TIFF_INTERNAL_MASK=True),
        rasterio.open(tmp, "w", **profile) as ds,
    ):
        for k, (name, im, spec) in enumerate(zip(names, images, specs, strict=True), start=1):
            ds.write(im, k)
            ds.set_band_description(k, band_description(name))
            if spec.quantity:  # a DEM's metres: what GDAL and QGIS say of its values
                ds.set_band_unit(k, spec.units or units_of(name))
            if spec.flags:
                ds.update_tags(
                    k,
                    flag_values=" ".join(str(v) for v in range(len(spec.flags))),
                    flag_meanings=" ".join(spec.flags),
                )
        if images[0].dtype.kind != "f":
            ds.write_mask(valid)
        _overviews(ds, rows, cols, flags=any(sp.flags for sp in specs))
        ds.update_tags(
            level=product.level,
            scene_index=a.get("scene_index", ""),
            name=a.get("name", ""),
            hrv=a.get("hrv", ""),
            mode=a.get("mode", ""),
            pixel_size_m=a.get("pixel_size_m", ""),
            **{k: a.get(k, "") for k in tags},
            **{f"provenance_{k}": v for k, v in product.provenance.items()},
        )
    if geom is not None:
        write_text(out.with_suffix(".geom"), geom)
    return out
