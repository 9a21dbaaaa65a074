"""Level products: one netCDF-4 / CF file (HDF5) per scene and level, written atomically.

The layout is documented in ``docs/products.md``. A :class:`Product` is what COR made of a
scene at a level: one image and validity mask per band, the map grid of a map-projected
level (:class:`MapGrid`), and four trees of metadata, ``geometry`` (everything needed to
redo the geometry), ``quality`` (figures measured against the truth), ``provenance`` (what
made it) and root ``attrs``. Trees are nested dicts of arrays, numbers and strings: a dict
becomes an HDF5 group, an array a dataset, a scalar or string an attribute of its group.

Format version 2 is netCDF-4 as the netCDF library, GDAL and xarray read it: each band is a
root variable ``<band>`` (uint8) with its mask ``<band>_valid``, on dimension scales; a
map-projected product (2A, 2 and 3) has CF coordinates ``x`` and ``y`` (pixel
centres, metres) and a ``crs`` grid-mapping variable (its WKT, GDAL's ``spatial_ref`` and
``GeoTransform``), so that ``NETCDF:"<file>":P`` opens georeferenced in GDAL and QGIS, and
``xarray.open_dataset`` gives the image with its coordinates, with no export step. Products
in image geometry (1A, 1B) have index dimensions ``row`` and ``column``. Version 1 products
(bands under ``bands/<name>/``) are still read.

Every dataset carries CF-style ``units`` and ``long_name`` attributes; the unit is read off
the name's suffix (``_m`` → ``m``, ``_rad`` → ``rad``, …), the project's naming rule.
Files are written through :func:`levels.hdf5.new_hdf5`: no reader ever sees half a
product.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import h5py
import numba as nb
import numpy as np
import pyproj
from numpy.typing import NDArray

from levels.errors import GeometryError, ProductError
from levels.geo.maps import MapGrid
from levels.hdf5 import (
    ATTRS_DIGEST,
    DEFLATE_LEVEL,
    all_attrs,
    check_attrs_digest,
    checksummed,
    damage_as,
    deflated_dataset,
    new_hdf5,
)
from levels.kinds import BandSpec, Unit, counts_band
from levels.product import BandImage, Product
from levels.threads import over_blocks

__all__ = [
    "PRODUCT_FORMAT",
    "PRODUCT_VERSION",
    "BandImage",
    "MapGrid",
    "Product",
    "band_spec",
    "product_name",
    "read_product",
    "with_fill",
    "write_product",
]

PRODUCT_FORMAT = "SPOT-LEVEL"
PRODUCT_VERSION = 2  # 2: netCDF-4 / CF layout (module docstring); 1 is still read
_READABLE_VERSIONS = (1, 2)
#: What ``geometry/scene`` holds (``docs/products.md``).
SCENE_KEYS = (
    "first_line",
    "n_lines",
    "t_centre_s",
    "centre_lat_deg",
    "centre_lon_deg",
    "corners_lat_deg",
    "corners_lon_deg",
)
_CHUNK = 512
#: Metadata arrays of at least this many numbers (anchor grids, the DEM a level 3 product
#: carries) are stored shuffled and deflated: a third to a half of their size.
_PACKED_SIZE = 4096
_UNITS = (
    ("_m_per_s", "m s-1"),
    ("_rad_per_s", "rad s-1"),
    ("_rad", "rad"),
    ("_deg", "degree"),
    ("_px", "1"),
    ("_m", "m"),
    ("_s", "s"),
    ("_counts", "1"),
)


#: File name extensions: a map level is ``.nc`` (netCDF-4, as CF §2.1 asks: GDAL, QGIS
#: and xarray take it by its netCDF driver, georeferenced); an image-geometry level keeps
#: ``.h5``, which GDAL opens with its HDF5 driver, as stored (its netCDF driver reads an
#: image without a decreasing y coordinate bottom-up: a 1A upside down under its RPCs).
MAP_SUFFIX, IMAGE_SUFFIX = ".nc", ".h5"
#: What a directory of products holds (``compare``, ``inspect``): both, L0 archives aside.
PRODUCT_SUFFIXES = (MAP_SUFFIX, IMAGE_SUFFIX)


def product_name(name: str, scene_index: int, level: str, on_map: bool = False) -> str:
    """The file name of a scene's product at a level: ``<name>_s<scene>_<level>.nc`` on a
    map grid (``on_map``), ``….h5`` in image geometry (:data:`MAP_SUFFIX`)."""
    return f"{name}_s{scene_index:03d}_{level}{MAP_SUFFIX if on_map else IMAGE_SUFFIX}"


#: Files of HDF5 that are inputs, not products: an L0 archive, a SAR frame.
INPUT_SUFFIXES = (".l0.h5", ".frame.h5")


def is_product_file(path: str | Path) -> bool:
    """A file named as a product (``.nc`` or ``.h5``, not an input: an L0 archive
    ``.l0.h5``, a SAR frame ``.frame.h5``)."""
    n = Path(path).name
    return n.endswith(PRODUCT_SUFFIXES) and not n.endswith(INPUT_SUFFIXES) and not n.startswith(".")


def units_of(name: str) -> str:
    """CF units of a quantity named by the project's rule (suffix); ``"1"`` if none."""
    for suffix, unit in _UNITS:
        if name.endswith(suffix):
            return unit
    return "1"


def _attr(value: Any) -> Any:
    if isinstance(value, str):
        return str(value)  # an enum's member (levels.choices) as its plain spelling
    if isinstance(value, bool | int | float | np.integer | np.floating | np.bool_):
        return value
    if value is None:
        return "null"
    return json.dumps(value)


def _write_tree(group: h5py.Group, tree: dict[str, object]) -> None:
    for key, value in tree.items():
        name = str(key)
        if isinstance(value, dict):
            _write_tree(group.create_group(name), value)
        elif isinstance(value, np.ndarray):
            if value.size >= _PACKED_SIZE and value.dtype.kind in "fiu":
                ds = deflated_dataset(group, name, value, _metadata_chunks(value.shape), True)
            else:
                ds = group.create_dataset(name, data=value, **checksummed(value))
            ds.attrs["units"] = units_of(name)
            ds.attrs["long_name"] = name.replace("_", " ")
            for k, n in enumerate(value.shape):  # named, not netCDF's phony_dim_N
                ds.dims[k].attach_scale(_pure_dimension(group, f"{name}_dim{k}", n))
        else:
            group.attrs[name] = _attr(value)


#: netCDF-C's mark of a dimension that is not a variable (its HDF5 dimension scale's NAME).
_PURE_DIMENSION = "This is a netCDF dimension but not a netCDF variable."


def _pure_dimension(group: h5py.Group, name: str, size: int) -> h5py.Dataset:
    """A named netCDF dimension of ``size`` in ``group``: an HDF5 dimension scale with no
    data written (no storage), as netCDF-C writes a dimension without a coordinate."""
    d = group.create_dataset(name, shape=(size,), dtype="f4")
    d.make_scale(f"{_PURE_DIMENSION}{size:10d}")
    return d


def _metadata_chunks(shape: tuple[int, ...]) -> tuple[int, ...]:
    """Chunks of a packed metadata array: up to ``_CHUNK`` × ``_CHUNK`` over its last two
    axes, one along the others (a grid per segment, the DEM in 1 MB pieces)."""
    if len(shape) == 1:
        return (min(shape[0], _CHUNK * _CHUNK),)
    return (*(1 for _ in shape[:-2]), *(min(n, _CHUNK) for n in shape[-2:]))


def _read_tree(group: h5py.Group, attrs: dict[str, dict[str, Any]]) -> dict[str, Any]:
    """A group's attributes (from ``attrs``, :func:`levels.hdf5.all_attrs` of its file) and
    its members, as nested dicts."""
    out: dict[str, object] = {}
    for name, value in attrs[group.name[1:]].items():
        out[name] = value.item() if isinstance(value, np.generic) else value
    for name, item in group.items():
        if isinstance(item, h5py.Group):
            out[name] = _read_tree(item, attrs)
        elif attrs[item.name[1:]].get("CLASS") != b"DIMENSION_SCALE":  # named dimensions
            out[name] = item[()]
    return out


def _dimension(f: h5py.File, name: str, values: NDArray, attrs: dict[str, str]) -> h5py.Dataset:
    ds = f.create_dataset(name, data=values, **checksummed(values))
    ds.make_scale(name)
    for k, v in attrs.items():
        ds.attrs[k] = v
    return ds


def _grid_mapping(f: h5py.File, grid: MapGrid) -> None:
    """The CF grid-mapping variable ``crs``: pyproj's CF attributes, the WKT, and GDAL's
    ``spatial_ref`` and ``GeoTransform`` (which GDAL's netCDF driver reads first)."""
    crs = pyproj.CRS.from_wkt(grid.crs_wkt)
    var = f.create_dataset("crs", data=np.int32(0))
    cf = crs.to_cf()
    for k, v in cf.items():
        var.attrs[k] = v
    var.attrs["crs_wkt"] = grid.crs_wkt
    var.attrs["spatial_ref"] = grid.crs_wkt
    var.attrs["GeoTransform"] = " ".join(repr(float(v)) for v in grid.geotransform)
    var.attrs["long_name"] = "map projection of the product"


#: The CF version the products declare (1.9 and later allow the unsigned ``uint8`` images).
CF_CONVENTIONS = "CF-1.11"


def cf_global_attrs(product: Product) -> dict[str, str]:
    """CF's global attributes (§2.6.2) of a product, from what it holds: ``Conventions``,
    ``title``, ``institution``, ``source``, ``history``. Deterministic (no clock): a rerun
    writes the same bytes; the software that wrote it is in ``history``."""
    a, prov = product.attrs, product.provenance
    what = f"level {a.get('level')}"
    scene = f", scene {a['scene_index']}" if "scene_index" in a else ""
    hrv = f"SPOT HRV{a['hrv']} {a.get('mode', '')}".strip() if "hrv" in a else "SPOT HRV"
    hrv = str(a.get("instrument", hrv))  # another sensor's product names its own
    origin = "pass, L0 archive" if _unit(product) != Unit.FRAME else "frame"
    return {
        "Conventions": CF_CONVENTIONS,
        "title": f"{hrv} {what} product{scene} of {a.get('name', 'a pass')}",
        "institution": "spot-station: an emulated SPOT direct-receiving station and "
        "processing centre (levels)",
        "source": f"{hrv} {origin} {prov.get('inputs', '')}".rstrip(),
        "history": f"{prov.get('software', 'levels')}: {what} made from "
        f"{prov.get('inputs', 'its ' + origin)}",
    }


@nb.njit(cache=True, nogil=True)
def _kernel_fill(lo, hi, image, valid, fill, out):
    """Rows ``lo … hi − 1``: the count where valid (the fill's own value one above), the
    fill where not."""
    for r in range(lo, hi):
        for c in range(image.shape[1]):
            v = image[r, c]
            out[r, c] = (v if v != fill else fill + 1) if valid[r, c] else fill


def with_fill(image: NDArray[Any], valid: NDArray[np.bool_], fill: int) -> NDArray[Any]:
    """A counts band as written (``_FillValue = fill``): ``fill`` where not valid, and a
    valid pixel of that count one above (1 DN), so that viewers mask exactly the pixels
    that are not valid. On every core (a full P band in a few hundredths of a second)."""
    out = np.empty_like(image)
    over_blocks(_kernel_fill, image.shape[0], image, valid, image.dtype.type(fill), out, grain=64)
    return out


def _unit(product: Product) -> Unit | None:
    """The unit of work of a product's kind (None for a level no registry declares)."""
    from levels.registry import kind_of

    known = kind_of(product)
    return known.unit if known is not None else None


def write_product(path: str | Path, product: Product, deflate_level: int = DEFLATE_LEVEL) -> Path:
    """Write a product atomically (module docstring); returns its path. Its image bands
    are deflated at ``deflate_level`` (:func:`levels.hdf5.deflate`; 0: stored: the zlib
    stream any reader inflates, without compression), their validity masks at
    :data:`levels.hdf5.DEFLATE_LEVEL` whatever it is (0.11 MB for a full P 2A mask, in 13
    ms on 2 cores)."""
    target = Path(path)
    with new_hdf5(target) as f:
        f.attrs["format"] = PRODUCT_FORMAT
        f.attrs["format_version"] = PRODUCT_VERSION
        f.attrs["band_names"] = json.dumps(list(product.bands))
        for k, v in {**product.attrs, **cf_global_attrs(product)}.items():
            f.attrs[k] = _attr(v)
        rows, cols = next(iter(product.bands.values())).image.shape
        dims = _dimensions(f, product.map_grid, rows, cols)
        chunks = (min(_CHUNK, rows), min(_CHUNK, cols))
        for name, band in product.bands.items():
            _write_band(f, product, name, band, dims, chunks, deflate_level)
        for name in ("geometry", "quality", "provenance"):
            _write_tree(f.create_group(name), getattr(product, name))
    return target


def _dimensions(
    f: h5py.File, grid: MapGrid | None, rows: int, cols: int
) -> tuple[h5py.Dataset, h5py.Dataset]:
    """The images' dimension scales: map coordinates (and the grid mapping) for a map
    level, row and column numbers for an image-geometry level."""
    if grid is None:
        return (
            _dimension(
                f,
                "row",
                np.arange(rows, dtype=np.int32),
                {"units": "1", "long_name": "image row (line)"},
            ),
            _dimension(
                f,
                "column",
                np.arange(cols, dtype=np.int32),
                {"units": "1", "long_name": "image column"},
            ),
        )
    dims = (
        _dimension(
            f,
            "y",
            grid.y_m(),
            {
                "standard_name": "projection_y_coordinate",
                "axis": "Y",
                "units": "m",
                "long_name": "northing of the pixel centre",
            },
        ),
        _dimension(
            f,
            "x",
            grid.x_m(),
            {
                "standard_name": "projection_x_coordinate",
                "axis": "X",
                "units": "m",
                "long_name": "easting of the pixel centre",
            },
        ),
    )
    _grid_mapping(f, grid)
    return dims


def band_spec(product: Product, name: str, dtype: np.dtype[Any] | None = None) -> BandSpec:
    """How band ``name`` of ``product`` is declared by its kind (:mod:`levels.registry`);
    for a kind not known here, counts if its values are bytes, else a quantity named by
    the project's rule (its units from the name's suffix, NaN its fill)."""
    from levels.registry import kind_of

    known = kind_of(product)
    if known is not None:
        return known.band(name)
    if dtype is None or dtype == np.uint8:
        return counts_band(product.level, name)
    return BandSpec(name, name.replace("_", " "))


def _write_band(
    f: h5py.File,
    product: Product,
    name: str,
    band: BandImage,
    dims: tuple[h5py.Dataset, h5py.Dataset],
    chunks: tuple[int, int],
    deflate_level: int,
) -> None:
    """One band's image and validity mask, on the dimension scales, CF-described as its
    kind declares it (:meth:`levels.kinds.ProductKind.band`: counts, or a quantity with
    its units, standard name and fill value)."""
    spec = band_spec(product, name, band.image.dtype)
    image = band.image
    if not spec.quantity and spec.fill is not None:
        # the fill only where not valid: a valid pixel of that count one above (1 DN)
        fill_count = np.asarray(spec.fill, dtype=image.dtype)
        image = np.where(
            band.valid, np.where(image == fill_count, fill_count + 1, image), fill_count
        )
    for var, data, long_name in (
        (name, image, spec.long_name),
        (
            f"{name}_valid",
            band.valid.view(np.uint8),
            f"pixel of band {name} is valid (every raw pixel it uses arrived)",
        ),
    ):
        level = deflate_level if var == name else DEFLATE_LEVEL
        # the fill where not valid (a quantity's NaN, a resampled level's count 0) declared:
        # GDAL's netCDF driver read a DEM's holes as 0 m and a 2A's borders as data without
        declared = np.issubdtype(data.dtype, np.floating) or not spec.quantity
        fill = spec.fill if var == name and declared else None
        ds = deflated_dataset(f, var, data, chunks, level=level, fillvalue=fill)
        if fill is not None:
            ds.attrs["_FillValue"] = np.array(fill, dtype=data.dtype)
        for axis, dim in enumerate(dims):
            ds.dims[axis].attach_scale(dim)
        ds.attrs["units"] = (spec.units or units_of(name)) if var == name else "1"
        ds.attrs["long_name"] = long_name
        if var == name and spec.standard_name:
            ds.attrs["standard_name"] = spec.standard_name
        if product.map_grid is not None:
            ds.attrs["grid_mapping"] = "crs"
            # the grid mapping also as a (scalar) coordinate: xarray then opens it as one,
            # which is where rioxarray looks for the CRS (``ds.rio.crs``)
            ds.attrs["coordinates"] = "crs"
        if var == name:
            ds.attrs["ancillary_variables"] = f"{name}_valid"
            if spec.flags:  # a mask: its classes, as CF says them
                ds.attrs["flag_values"] = np.arange(len(spec.flags), dtype=data.dtype)
                ds.attrs["flag_meanings"] = " ".join(spec.flags)
        else:
            ds.attrs["flag_values"] = np.array([0, 1], np.uint8)
            ds.attrs["flag_meanings"] = "invalid valid"


def _required_trees(level: str) -> tuple[str, ...]:
    """The geometry trees a product of kind ``level`` must carry (none for a kind not
    known here)."""
    from levels.registry import kind, kind_names

    return kind(level).geometry_trees if level in kind_names() else ()


def _upgrade_v1_geometry(geometry: dict[str, Any], attrs: dict[str, Any]) -> None:
    """Version 1 trees lacked the grid sizes that version 2 keeps beside the grids."""
    scene = geometry.get("scene", {})
    look: dict[str, object] = next(iter(geometry.get("look_angles", {}).values()), {})
    sizes = {
        "n_rows": attrs.get("n_rows"),
        "n_cols": attrs.get("n_cols"),
        "n_raw_lines": scene.get("n_lines"),
        "n_raw_columns": int(np.asarray(look["column"])[-1]) + 1 if "column" in look else None,
    }
    for key in ("level_1b", "level_2a"):
        if key in geometry:
            for k, v in sizes.items():
                if v is not None:
                    geometry[key].setdefault(k, v)


def _check_scene(scene: dict[str, object]) -> None:
    """The scene's figures are finite numbers, its lines whole and its corners four."""
    for k in SCENE_KEYS:
        try:
            v = np.asarray(scene[k], dtype=np.float64)
        except (TypeError, ValueError):
            v = np.array(np.nan)
        whole = k in ("first_line", "n_lines")
        shape = (4,) if k.startswith("corners") else ()
        if v.shape != shape or not np.all(np.isfinite(v)) or (whole and v != np.rint(v)):
            raise ProductError(
                f"geometry/scene/{k} = {scene[k]!r} is not "
                f"{'a whole number' if whole else 'finite numbers'}; damaged"
            )


def _check_geometry_trees(geometry: dict[str, Any], bands: list[str]) -> None:
    """Every band's 1B or 2A geometry rebuilds from its tree (each object checks its own:
    ``from_tree`` raises :class:`ProductError` naming what is missing or malformed)."""
    from levels.geo.level1b import Level1BGeometry
    from levels.geo.level2a import Level2AGeometry
    from levels.geo.level3 import Level3Geometry

    for key, check in (
        ("level_1b", Level1BGeometry.from_tree),
        ("level_2a", Level2AGeometry.from_tree),
        ("level_3", Level3Geometry.check_tree),
    ):
        if key in geometry:
            for band in bands:
                check(geometry[key], band)


def _read_bands(f: h5py.File, names: list[str], version: int, images: bool) -> dict[str, BandImage]:
    bands = {}
    for name in names:
        image_ds, valid_ds = (
            (f[f"bands/{name}/image"], f[f"bands/{name}/valid"])
            if version == 1
            else (f[name], f[f"{name}_valid"])
        )
        valid = valid_ds[()].astype(bool)
        image = image_ds[()] if images else np.zeros(valid.shape, np.uint8)
        bands[name] = BandImage(image, valid)
    return bands


def _read_map_grid(
    f: h5py.File, version: int, geometry: dict[str, Any], shape: tuple[int, int]
) -> MapGrid | None:
    """The product's map grid (its ``crs`` variable; version 1: its 2A tree) over its
    images' ``shape``; :class:`ProductError` when it is damaged."""
    try:
        if version == 1:
            g = geometry.get("level_2a")
            if not g:
                return None
            gt = tuple(np.asarray(g["geotransform"], float))
            return MapGrid(str(g["crs_wkt"]), gt, *shape).check_crs()
        if "crs" not in f:
            return None
        a = f["crs"].attrs
        gt = tuple(float(v) for v in str(a["GeoTransform"]).split())
        return MapGrid(str(a["crs_wkt"]), gt, *shape).check_crs()
    except GeometryError as exc:
        raise ProductError(str(exc)) from None


#: How far a product's ``x`` and ``y`` coordinates may lie from its ``GeoTransform``'s
#: pixel centres, in pixels: both are written from one grid (float64), so only storage
#: round-off; GDAL georeferences from the one, xarray from the other.
COORDINATE_TOLERANCE_PX = 1e-6


def _check_coordinates(f: h5py.File, grid: MapGrid) -> None:
    """The ``x`` and ``y`` coordinate variables are the grid's pixel centres, or
    :class:`ProductError` (two georeferencings of one image that disagree)."""
    for name, want, step in (
        ("x", grid.x_m(), grid.geotransform[1]),
        ("y", grid.y_m(), grid.geotransform[5]),
    ):
        if name not in f:
            raise ProductError(f"coordinate variable {name!r} missing; damaged or incomplete")
        got = np.asarray(f[name][()], dtype=np.float64)
        if got.shape != want.shape:
            raise ProductError(
                f"coordinate {name!r} of {got.shape[0]} values for {want.size} pixels"
            )
        off = float(np.max(np.abs(got - want))) if got.size else 0.0
        if not off <= COORDINATE_TOLERANCE_PX * abs(step):
            raise ProductError(
                f"coordinate {name!r} lies {off:.6g} m from the GeoTransform's pixel centres "
                "(the two georeferencings disagree); damaged or edited"
            )


def read_product(path: str | Path, images: bool = True) -> Product:
    """Read and check a product; ``images=False`` reads only its metadata (masks too)."""
    where = Path(path)
    with damage_as(ProductError, where):
        return _read_product(where, images)


def _read_product(where: Path, images: bool) -> Product:
    if not where.is_file():
        raise ProductError(f"{where}: no such product file")
    try:
        f = h5py.File(where, "r")
    except OSError as exc:
        raise ProductError(f"{where}: not a readable HDF5 file ({exc}); is it truncated?") from None
    with f:
        if f.attrs.get("format") != PRODUCT_FORMAT:
            raise ProductError(
                f"{where}: format attribute is {f.attrs.get('format')!r}, "
                f"expected {PRODUCT_FORMAT!r}; not a level product"
            )
        version = int(f.attrs.get("format_version", -1))
        if version not in _READABLE_VERSIONS:
            raise ProductError(
                f"{where}: product format version "
                f"{f.attrs.get('format_version')!r}; this reader knows "
                f"versions {', '.join(map(str, _READABLE_VERSIONS))}"
            )
        groups = (
            ("bands", "geometry", "quality", "provenance")
            if version == 1
            else ("geometry", "quality", "provenance")
        )
        missing = [k for k in groups if k not in f]
        if missing:
            raise ProductError(f"{where}: group '{missing[0]}' is missing; not a complete product")
        try:
            every = all_attrs(f)  # read once: the trees, then their digest
            attrs = {
                k: (v.item() if isinstance(v, np.generic) else v) for k, v in every[""].items()
            }
            trees = {k: _read_tree(f[k], every) for k in ("geometry", "quality", "provenance")}
            level = str(attrs.get("level"))
            lacking = [k for k in _required_trees(level) if k not in trees["geometry"]]
            if lacking:
                raise ProductError(
                    f"level {level} product without its geometry/{lacking[0]} "
                    "group; damaged or incomplete"
                )
            scene = trees["geometry"].get("scene", {})
            missing_keys = [k for k in SCENE_KEYS if k not in scene] if scene else []
            if missing_keys:
                raise ProductError(
                    f"geometry/scene lacks {missing_keys[0]!r}; damaged or incomplete"
                )
            if scene:
                _check_scene(scene)
            if version == 1:
                _upgrade_v1_geometry(trees["geometry"], attrs)
            attrs.pop(ATTRS_DIGEST, None)  # checked above; not part of what it holds
            names = json.loads(attrs.pop("band_names"))
            _check_geometry_trees(trees["geometry"], names)
            bands = _read_bands(f, names, version, images)
            shape = next(iter(bands.values())).valid.shape if bands else (0, 0)
            grid = _read_map_grid(f, version, trees["geometry"], shape)
            if grid is not None and version >= 2:
                _check_coordinates(f, grid)
            try:  # last: a missing part is named above, an edited value here
                check_attrs_digest(f, required=version >= 2, attrs=every)
            except ValueError as exc:
                raise ProductError(str(exc)) from None  # the path is added below
            return Product(attrs=attrs, bands=bands, map_grid=grid, **trees)
        except ProductError as exc:
            raise ProductError(f"{where}: {exc}") from None
        except (KeyError, ValueError, TypeError) as exc:  # h5py's own: damage_as, above
            raise ProductError(f"{where}: damaged or incomplete product ({exc})") from None
