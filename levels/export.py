"""Export of level products as GeoTIFF (through rasterio, i.e. GDAL).

A product's bands become the bands of one GeoTIFF, uint8, tiled and DEFLATE-compressed; the
validity mask becomes the dataset's internal mask (GDAL's per-dataset mask band, which QGIS
and GDAL honour), and pixels not valid are 0. Band descriptions carry the band names; the
tags carry the level, scene, instrument and the provenance of the product.

- Map levels (2A, 2, 3): the product's CRS (its WKT) and its north-up geotransform.
- Image-geometry levels (1A, 1B): the RPCs the product carries (:mod:`levels.geo.rpc`,
  fitted to the rigorous model; the first band's, whose fit error goes in ``ERR_RAND``, in
  metres) in GDAL's RPC metadata, so that ``gdalwarp -rpc -to RPC_DEM=dem.tif``
  orthorectifies it. A product written before RPCs were is refused with a clear error.

The products themselves need no export for that: :func:`write_rpc_sidecar` writes, beside
each 1A and 1B product, the PAM sidecar in which GDAL finds each band's RPCs.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from levels.errors import ProductError
from levels.files import atomic_path
from levels.geo.rpc import Rpc
from levels.products import Product

__all__ = ["MAP_LEVELS", "RPC_LEVELS", "write_geotiff", "write_rpc_sidecar"]

#: Levels on a map grid, which a GeoTIFF's geotransform can describe.
MAP_LEVELS = ("2A", "2", "3", "DEM", "GEC", "GTC")
#: A DEM product (:mod:`levels.stereo`) is exported as its heights alone, float32, NaN
#: where it has none (GDAL's nodata): the raster level 3 and any GIS read as a DEM.
DEM_EXPORT_BAND = "height_m"
#: Levels in image geometry, exported with their RPCs.
RPC_LEVELS = ("1A", "1B")


def write_rpc_sidecar(product: Product, path: str | Path) -> Path | None:
    """Beside an image-geometry product at ``path``, GDAL's PAM sidecar ``<path>.aux.xml``
    with each band's RPCs in its ``RPC`` metadata domain, so that GDAL finds them on the
    product as written: ``gdalwarp -rpc -to RPC_DEM=dem.tif NETCDF:"<path>":P out.tif``
    (the netCDF driver names the band's subdataset ``P``, the HDF5 driver ``//P``: both are
    given). None (nothing written) for a map level or a product without RPCs."""
    from xml.sax.saxutils import escape, quoteattr

    from levels.files import write_text

    trees = product.geometry.get("rpc") if product.level in RPC_LEVELS else None
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


def write_geotiff(product: Product, path: str | Path) -> Path:
    """Write ``product`` (images loaded) as a georeferenced GeoTIFF; returns its path."""
    import rasterio
    from rasterio.crs import CRS
    from rasterio.rpc import RPC
    from rasterio.transform import Affine

    level = product.level
    georef: dict = {}
    if level in RPC_LEVELS:
        trees = product.geometry.get("rpc")
        if not trees:
            raise ProductError(
                f"level {level} is in image geometry and this product carries no RPCs "
                "(made before they were written): process its L0 again to export it"
            )
        rpc = Rpc.from_tree(next(iter(trees.values())))
        georef["rpcs"] = RPC.from_gdal(rpc.gdal_metadata())
    elif level in MAP_LEVELS:
        grid = product.map_grid
        if grid is None:
            raise ProductError(f"level {level} product without a map grid (no crs variable)")
        georef["crs"] = CRS.from_wkt(grid.crs_wkt)
        georef["transform"] = Affine.from_gdal(*grid.geotransform)
    else:
        raise ProductError(f"level {level}: no GeoTIFF export for it")
    names = [DEM_EXPORT_BAND] if level == "DEM" else list(product.bands)
    images = [product.bands[n].image for n in names]
    valid = np.logical_and.reduce([product.bands[n].valid for n in names])
    rows, cols = images[0].shape
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    profile = {
        "driver": "GTiff",
        "width": cols,
        "height": rows,
        "count": len(names),
        "dtype": str(images[0].dtype),
        **({"nodata": float("nan")} if images[0].dtype.kind == "f" else {}),
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
        for k, (name, im) in enumerate(zip(names, images, strict=True), start=1):
            ds.write(im, k)
            ds.set_band_description(k, name)
        if images[0].dtype.kind != "f":
            ds.write_mask(valid)
        ds.update_tags(
            level=level,
            scene_index=a.get("scene_index", ""),
            name=a.get("name", ""),
            hrv=a.get("hrv", ""),
            mode=a.get("mode", ""),
            pixel_size_m=a.get("pixel_size_m", ""),
            **({"vertical": a.get("vertical", "")} if level == "DEM" else {}),
            **{f"provenance_{k}": v for k, v in product.provenance.items()},
        )
    return out
