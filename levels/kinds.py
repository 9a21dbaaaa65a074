"""What a product kind declares: every product the station makes, declared once.

A *kind* is what a product is: a scene's level (1A, 1B, 2A, 2, 3), a stereo pair's DEM, a
SAR frame geocoded on the ellipsoid (GEC) or over terrain (GTC). Each is declared once, as a
:class:`ProductKind` in the module that makes it, and named in :mod:`levels.registry`; every
consumer reads the declaration and none tests a kind's name:

- the driver (:mod:`levels.process`): its unit of work (:class:`Unit`), what it requires
  and needs, its maker;
- the product format (:mod:`levels.products`): its bands (:class:`BandSpec`: dtype, units,
  CF names, fill value), the geometry trees it must carry, a map grid or raw geometry;
- export (:mod:`levels.export`): a GeoTIFF with RPCs, with a map grid, or none
  (:class:`Export`), which bands, which attributes as tags;
- the console (``station run``, ``station process``): its headline figures
  (:class:`Figure`) and notes;
- quicklooks (:mod:`levels.quicklook`): how it is browsed (:class:`Browse`);
- ``inspect`` (:mod:`levels.inspect`): its own section and title (:class:`Inspection`);
- the STAC catalogue: its own properties;
- ``compare`` (:mod:`levels.compare`): its tolerances where they are not the defaults.

A new kind is one module defining its ``ProductKind`` and one entry of
:data:`levels.registry.BUILT_IN` (or :func:`levels.registry.register_kind` from anywhere).
This module sits low: it imports neither the products nor the makers.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from enum import StrEnum
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from levels.product import Product

__all__ = [
    "BandSpec",
    "Browse",
    "Export",
    "Figure",
    "Inspection",
    "ProductKind",
    "Unit",
    "counts_band",
    "figure_at",
    "flag_band",
    "headline",
]


class Unit(StrEnum):
    """What one product of a kind is made of: its unit of work."""

    SCENE = "scene"  # one scene of a pass (the driver's scene tasks)
    PAIR = "pair"  # two scenes of two passes over one ground (a stereo pair)
    FRAME = "frame"  # one SAR frame


class Export(StrEnum):
    """How a kind is exported as a GeoTIFF (:func:`levels.export.write_geotiff`)."""

    RPC = "rpc"  # image geometry, with the RPCs fitted to the rigorous model
    MAP = "map"  # a map grid: its CRS and north-up geotransform
    NONE = "none"  # not exported


@dataclass(frozen=True)
class BandSpec:
    """One band a kind's products hold, as written (CF, ``docs/products.md``).

    Attributes
    ----------
    name
        The band's variable name; a quantity's unit is read off its suffix
        (:func:`levels.products.units_of`) unless ``units`` says it.
    long_name
        CF ``long_name``.
    standard_name
        CF ``standard_name``, or None where none fits.
    dtype
        NumPy dtype of the stored values.
    quantity
        A quantity in its units (compared as numbers, drawn with a colour bar); else counts.
    fill
        The fill value written as ``_FillValue`` (NaN for a float quantity: where not
        valid), or None.
    units
        CF units; None: from the name's suffix.
    optional
        A product of the kind may lack it.
    flags
        A band of flags (a mask): the meaning of each value 0, 1, … (CF ``flag_values`` and
        ``flag_meanings``), what a viewer shows as classes; stored as bytes, ``fill`` where
        not valid. Empty: not flags.
    """

    name: str
    long_name: str
    standard_name: str | None = None
    dtype: str = "float32"
    quantity: bool = True
    fill: float | None = math.nan
    units: str | None = None
    optional: bool = False
    flags: tuple[str, ...] = ()


def flag_band(name: str, long_name: str, meanings: tuple[str, ...]) -> BandSpec:
    """A band of flags (:attr:`BandSpec.flags`): bytes, 255 where not valid."""
    return BandSpec(name, long_name, dtype="uint8", quantity=False, fill=255, flags=meanings)


def counts_band(level: str, name: str, fill: int | None = None) -> BandSpec:
    """A band of counts of the instrument (P, XS1…), as the scene levels hold them; its
    ``fill`` the count written where it is not valid (None: every count is data)."""
    return BandSpec(
        name, f"level {level} counts of band {name}", dtype="uint8", quantity=False, fill=fill
    )


@dataclass(frozen=True)
class Figure:
    """A headline figure of a kind: a column of the console's table.

    ``value(figures)`` reads it from a product's flattened quality
    (:func:`levels.quality.scalar_figures`); None where the product has none (a dash)."""

    label: str
    spec: str
    value: Callable[[Mapping[str, Any]], float | None]
    #: What the column means, said once under the table (empty: its label says it).
    legend: str = ""


def headline(
    of: Callable[[Mapping[str, Any]], object], attr: str
) -> Callable[[Mapping[str, Any]], float | None]:
    """A figure's reader: attribute ``attr`` of a kind's typed headline, ``of(figures)``
    (:class:`levels.quality.Headline` and its kin), as a float."""

    def value(figures: Mapping[str, Any]) -> float | None:
        v = getattr(of(figures), attr)
        return None if v is None else float(v)

    return value


def figure_at(*keys: str) -> Callable[[Mapping[str, Any]], float | None]:
    """A figure's reader: the first of ``keys`` the flattened quality has, as a float (a
    kind declared outside the library, without a typed headline of its own)."""

    def value(figures: Mapping[str, Any]) -> float | None:
        for key in keys:
            v = figures.get(key)
            if isinstance(v, int | float) and not isinstance(v, bool):
                return float(v)
        return None

    return value


@dataclass(frozen=True)
class Browse:
    """How a kind's quicklook draws it (:mod:`levels.quicklook`).

    ``band`` None: the counts, in grey (one band) or false colour (three), with the
    checkpoint errors as arrows where the quality places them; a band's name: that
    quantity, in colour map ``cmap``, with a colour bar labelled ``label`` (its units)."""

    band: str | None = None
    cmap: str = "gray"
    label: str = ""


@dataclass(frozen=True)
class Inspection:
    """What ``station inspect`` says of a product beyond what every product has: a title
    line, sections of the JSON summary (by key), and lines of text."""

    title: str
    sections: dict[str, object] = field(default_factory=dict)
    lines: tuple[str, ...] = ()


def _no_notes(figures: Mapping[str, Any]) -> tuple[str, ...]:
    return ()


def _no_stac(product: Product) -> dict[str, object]:
    return {}


@dataclass(frozen=True)
class ProductKind:
    """A kind of product, declared once (module docstring).

    Attributes
    ----------
    name
        Its name: ``attrs/level`` of its products, ``[processing] levels``, file names.
    doc
        One line: what it is.
    unit
        Its unit of work (:class:`Unit`).
    on_map
        Its images lie on a map grid (``.nc``, CF coordinates) or in raw geometry (``.h5``).
    geometry_trees
        The groups under ``geometry`` its products must carry (checked on reading).
    export
        Its GeoTIFF export (:class:`Export`).
    inspect
        ``inspect(product) -> Inspection``: its title and own section for ``inspect``.
    bands
        Its bands when fixed (quantities: a DEM's, a SAR frame's); empty: the instrument's
        bands, as counts (:func:`counts_band`).
    export_bands
        The bands its GeoTIFF holds (empty: every band).
    export_tags
        Product attributes its GeoTIFF also carries as tags.
    requires
        Kinds its products are made from (made before it).
    needs
        What it needs from outside: ``"dem"`` (a DEM: a GTC's terrain).
    figures
        Its headline figures (:class:`Figure`): the console's columns.
    notes
        ``notes(figures) -> lines``: what the console says of a product below the table
        (control points used and rejected, …), from its flattened quality.
    browse
        Its quicklook (:class:`Browse`).
    stac
        ``stac(product) -> properties``: its own STAC Item properties.
    tolerances
        ``compare``'s tolerances for it, by section, over the defaults.
    maker
        What makes it (:class:`levels.makers.base.LevelMaker` for a scene's level; a
        pair's or a frame's maker), or None where the station makes it.
    counts_fill
        The count its counts bands hold where not valid, declared to viewers (netCDF
        ``_FillValue``, GeoTIFF nodata); a valid pixel of that count is written one above
        (1 DN). None: every count is data (the raw counts of a 1A).
    """

    name: str
    doc: str
    unit: Unit
    on_map: bool
    geometry_trees: tuple[str, ...]
    export: Export
    inspect: Callable[[Product], Inspection]
    bands: tuple[BandSpec, ...] = ()
    export_bands: tuple[str, ...] = ()
    export_tags: tuple[str, ...] = ()
    requires: tuple[str, ...] = ()
    needs: frozenset[str] = frozenset()
    figures: tuple[Figure, ...] = ()
    notes: Callable[[Mapping[str, Any]], tuple[str, ...]] = _no_notes
    browse: Browse = Browse()
    stac: Callable[[Product], dict[str, object]] = _no_stac
    tolerances: Mapping[str, Mapping[str, float]] = field(default_factory=dict)
    maker: Any = None
    counts_fill: int | None = None

    def band(self, name: str) -> BandSpec:
        """The declaration of band ``name`` of a product of this kind."""
        for b in self.bands:
            if b.name == name:
                return b
        return counts_band(self.name, name, self.counts_fill)
