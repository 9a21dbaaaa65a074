"""Level products: one HDF5 file per scene and level, written atomically; the reader.

The layout is documented in ``docs/products.md``. A :class:`Product` is what COR made of a
scene at a level: one image and validity mask per band, and four trees of metadata,
``geometry`` (everything needed to redo the geometry), ``quality`` (figures measured
against the truth), ``provenance`` (what made it) and root ``attrs``. Trees are nested
dicts of arrays, numbers and strings: a dict becomes an HDF5 group, an array a dataset, a
scalar or string an attribute of its group.

Every dataset carries CF-style ``units`` and ``long_name`` attributes; the unit is read off
the name's suffix (``_m`` → ``m``, ``_rad`` → ``rad``, …), the project's naming rule.
The file is written under a hidden temporary name beside its target and renamed into place
when complete (``os.replace``), so no reader ever sees half a product.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import h5py
import numpy as np
from numpy.typing import NDArray

from levels.errors import ProductError

__all__ = ["PRODUCT_FORMAT", "PRODUCT_VERSION", "BandImage", "Product", "read_product",
           "write_product"]

PRODUCT_FORMAT = "SPOT-LEVEL"
PRODUCT_VERSION = 1
_CHUNK = 512
_UNITS = (("_m_per_s", "m s-1"), ("_rad_per_s", "rad s-1"), ("_rad", "rad"), ("_deg", "degree"),
          ("_px", "1"), ("_m", "m"), ("_s", "s"), ("_counts", "1"))


def units_of(name: str) -> str:
    """CF units of a quantity named by the project's rule (suffix); ``"1"`` if none."""
    for suffix, unit in _UNITS:
        if name.endswith(suffix):
            return unit
    return "1"


@dataclass(frozen=True, eq=False)
class BandImage:
    """One band of a product: 8-bit image and validity mask, same shape (rows, cols)."""

    image: NDArray[np.uint8]
    valid: NDArray[np.bool_]

    def __post_init__(self) -> None:
        if self.image.shape != self.valid.shape or self.image.ndim != 2:
            raise ProductError(f"band image {self.image.shape} and mask {self.valid.shape} "
                               "must be 2-D of the same shape")


@dataclass(frozen=True, eq=False)
class Product:
    """A scene at a level (module docstring). ``attrs`` must hold ``level``."""

    attrs: dict[str, Any]
    bands: dict[str, BandImage]
    geometry: dict[str, Any] = field(default_factory=dict)
    quality: dict[str, Any] = field(default_factory=dict)
    provenance: dict[str, Any] = field(default_factory=dict)

    @property
    def level(self) -> str:
        return str(self.attrs["level"])


def _attr(value: Any) -> Any:
    if isinstance(value, str | bool | int | float | np.integer | np.floating | np.bool_):
        return value
    if value is None:
        return "null"
    return json.dumps(value)


def _write_tree(group: h5py.Group, tree: dict[str, Any]) -> None:
    for name, value in tree.items():
        if isinstance(value, dict):
            _write_tree(group.create_group(name), value)
        elif isinstance(value, np.ndarray):
            ds = group.create_dataset(name, data=value)
            ds.attrs["units"] = units_of(name)
            ds.attrs["long_name"] = name.replace("_", " ")
        else:
            group.attrs[name] = _attr(value)


def _read_tree(group: h5py.Group) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for name, value in group.attrs.items():
        out[name] = value.item() if isinstance(value, np.generic) else value
    for name, item in group.items():
        out[name] = _read_tree(item) if isinstance(item, h5py.Group) else item[()]
    return out


def write_product(path: str | Path, product: Product) -> Path:
    """Write a product atomically (module docstring); returns its path."""
    target = Path(path)
    tmp = target.with_name(f".{target.name}.partial")
    try:
        with h5py.File(tmp, "w") as f:
            f.attrs["format"] = PRODUCT_FORMAT
            f.attrs["format_version"] = PRODUCT_VERSION
            f.attrs["Conventions"] = "CF-1.8"
            f.attrs["band_names"] = json.dumps(list(product.bands))
            for k, v in product.attrs.items():
                f.attrs[k] = _attr(v)
            for name, band in product.bands.items():
                g = f.create_group(f"bands/{name}")
                rows, cols = band.image.shape
                chunks = (min(_CHUNK, rows), min(_CHUNK, cols))
                img = g.create_dataset("image", data=band.image, chunks=chunks,
                                       compression="gzip", compression_opts=1)
                img.attrs["units"] = "1"
                img.attrs["long_name"] = f"level {product.level} counts of band {name}"
                img.attrs["_FillValue"] = np.uint8(0)
                val = g.create_dataset("valid", data=band.valid, chunks=chunks,
                                       compression="gzip", compression_opts=1)
                val.attrs["units"] = "1"
                val.attrs["long_name"] = "pixel is valid (every raw pixel it uses arrived)"
            for name in ("geometry", "quality", "provenance"):
                _write_tree(f.create_group(name), getattr(product, name))
        os.replace(tmp, target)
    finally:
        if tmp.exists():
            tmp.unlink()
    return target


def read_product(path: str | Path, images: bool = True) -> Product:
    """Read and check a product; ``images=False`` reads only its metadata (masks too)."""
    where = Path(path)
    if not where.is_file():
        raise ProductError(f"{where}: no such product file")
    try:
        f = h5py.File(where, "r")
    except OSError as exc:
        raise ProductError(f"{where}: not a readable HDF5 file ({exc}); is it truncated?") \
            from None
    with f:
        if f.attrs.get("format") != PRODUCT_FORMAT:
            raise ProductError(f"{where}: format attribute is {f.attrs.get('format')!r}, "
                               f"expected {PRODUCT_FORMAT!r}; not a level product")
        if int(f.attrs.get("format_version", -1)) != PRODUCT_VERSION:
            raise ProductError(f"{where}: product format version "
                               f"{f.attrs.get('format_version')!r}; this reader knows "
                               f"version {PRODUCT_VERSION}")
        missing = [k for k in ("bands", "geometry", "quality", "provenance") if k not in f]
        if missing:
            raise ProductError(f"{where}: group '{missing[0]}' is missing; not a complete "
                               "product")
        try:
            attrs = {k: (v.item() if isinstance(v, np.generic) else v)
                     for k, v in f.attrs.items()}
            trees = {k: _read_tree(f[k]) for k in ("geometry", "quality", "provenance")}
            names = json.loads(attrs.pop("band_names"))
            bands = {}
            for name in names:
                g = f[f"bands/{name}"]
                valid = g["valid"][()]
                image = g["image"][()] if images else np.zeros(valid.shape, np.uint8)
                bands[name] = BandImage(image, valid.astype(bool))
        except (KeyError, OSError, RuntimeError, ValueError) as exc:
            raise ProductError(f"{where}: damaged or incomplete product ({exc})") from None
    return Product(attrs=attrs, bands=bands, **trees)
