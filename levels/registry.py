"""The registry of product kinds: every product the processing centre can make, by name.

A kind is declared once (:class:`levels.kinds.ProductKind`), in the module that makes it;
the built-in kinds are the entries of :data:`BUILT_IN` below: the scene levels in processing
order, then the stereo pair's DEM and the SAR frame's GEC and GTC. A kind made elsewhere (a
user's module, a test) is added with :func:`register_kind`, and a scene level with
:func:`levels.makers.scene.register_level` (its :class:`~levels.makers.base.LevelMaker`
alone: the kind's other declarations take their defaults); either is then a choice of
``[processing] levels`` like
the others, planned and made by the driver (:mod:`levels.process`) without a change.

This module sits low in the tree (the options check level names against it, the product
format reads its kinds' bands): it names the built-in kinds' modules and imports one only
when its kind is asked for, as a plugin entry point would.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

from levels.choices import Level
from levels.kinds import ProductKind, Unit

if TYPE_CHECKING:
    from levels.product import Product

__all__ = [
    "BUILT_IN",
    "kind",
    "kind_names",
    "kind_of",
    "level_names",
    "register_kind",
    "unregister_kind",
]

#: The built-in kinds and where each is declared (``module:attribute``), the scene levels
#: in processing order.
BUILT_IN: dict[str, str] = {
    Level.L1A: "levels.makers.level1a:KIND",
    Level.L1B: "levels.makers.level1b:KIND",
    Level.L2A: "levels.makers.level2a:KIND",
    Level.L2: "levels.makers.level2:KIND",
    Level.L3: "levels.makers.level3:KIND",
    "DEM": "levels.makers.dem:KIND",
    "GEC": "levels.makers.sar:GEC",
    "GTC": "levels.makers.sar:GTC",
}

_registered: dict[str, ProductKind] = {}


def kind_names(unit: Unit | None = None) -> tuple[str, ...]:
    """Every kind (of ``unit``, if given): the built-in ones, then those registered."""
    names = (*(str(k) for k in BUILT_IN), *_registered)
    return names if unit is None else tuple(n for n in names if kind(n).unit is unit)


def kind(name: str) -> ProductKind:
    """The kind ``name``; :class:`KeyError` naming the known kinds if none."""
    if name in _registered:
        return _registered[name]
    if name not in BUILT_IN:
        raise KeyError(f"no product kind {name!r}; known: {', '.join(kind_names())}")
    module, attr = BUILT_IN[name].split(":")
    found: ProductKind = getattr(importlib.import_module(module), attr)
    return found


def kind_of(product: Product) -> ProductKind | None:
    """The kind of ``product`` (its ``level`` attribute), or None if no kind of that name
    is known here (a product of a kind registered elsewhere)."""
    name = str(product.attrs.get("level"))
    return kind(name) if name in BUILT_IN or name in _registered else None


def register_kind(new: ProductKind) -> None:
    """Add a kind (its name must be new); it comes after the built-in ones and those
    registered before it, unless its ``requires`` put it later."""
    if new.name in BUILT_IN or new.name in _registered:
        raise ValueError(f"level {new.name!r} is already registered")
    if not new.name or "/" in new.name or "_" in new.name:
        raise ValueError(
            f"level name {new.name!r}: a product is named <name>_s<scene>_<level>.h5, "
            "so a level's name is not empty and has no '/' or '_'"
        )
    _registered[new.name] = new


def unregister_kind(name: str) -> None:
    """Remove a kind added by :func:`register_kind` (the built-in ones stay)."""
    if name not in _registered:
        raise KeyError(f"level {name!r} was not registered")
    del _registered[name]


def level_names() -> tuple[str, ...]:
    """Every level ``[processing] levels`` can ask for: the kinds of a scene and of a pair
    of passes (made from archives; a SAR frame's are not), the built-in ones, then those
    registered."""
    return tuple(n for n in kind_names() if kind(n).unit in (Unit.SCENE, Unit.PAIR))
