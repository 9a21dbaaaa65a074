"""The registry of levels: which levels the processing centre can make, by name.

A level is declared once, in a module of :mod:`levels.makers` that defines its
:class:`~levels.makers.base.LevelMaker` as ``MAKER``; the built-in levels are the entries
of :data:`BUILT_IN` below, in processing order. A level made elsewhere (a user's module, a
test) is added with :func:`register_level` and is then a choice of ``[processing] levels``
like the others: the driver (:mod:`levels.process`) plans and runs it without a change.

This module sits low in the tree (the options check level names against it): it names the
built-in makers' modules and imports one only when its maker is asked for, as a plugin
entry point would.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

from levels.choices import Level

if TYPE_CHECKING:
    from levels.makers.base import LevelMaker

__all__ = ["BUILT_IN", "level_maker", "level_names", "register_level", "unregister_level"]

#: The built-in levels and the module that declares each (its ``MAKER``), in processing order.
BUILT_IN: dict[str, str] = {
    Level.L1A: "levels.makers.level1a",
    Level.L1B: "levels.makers.level1b",
    Level.L2A: "levels.makers.level2a",
    Level.L2: "levels.makers.level2",
    Level.L3: "levels.makers.level3",
}

_registered: dict[str, LevelMaker] = {}


def level_names() -> tuple[str, ...]:
    """Every level that can be asked for: the built-in ones, then those registered."""
    return (*(str(k) for k in BUILT_IN), *_registered)


def level_maker(name: str) -> LevelMaker:
    """The maker of level ``name``; :class:`KeyError` naming the known levels if none."""
    if name in _registered:
        return _registered[name]
    if name not in BUILT_IN:
        raise KeyError(f"no level {name!r}; known: {', '.join(level_names())}")
    maker: LevelMaker = importlib.import_module(BUILT_IN[name]).MAKER
    return maker


def register_level(maker: LevelMaker) -> None:
    """Add a level (its maker's ``name`` must be new); it comes after the built-in ones and
    those registered before it, unless its ``requires`` put it later."""
    if maker.name in BUILT_IN or maker.name in _registered:
        raise ValueError(f"level {maker.name!r} is already registered")
    if not maker.name or "/" in maker.name or "_" in maker.name:
        raise ValueError(
            f"level name {maker.name!r}: a product is named <name>_s<scene>_<level>.h5, "
            "so a level's name is not empty and has no '/' or '_'"
        )
    _registered[maker.name] = maker


def unregister_level(name: str) -> None:
    """Remove a level added by :func:`register_level` (the built-in ones stay)."""
    if name not in _registered:
        raise KeyError(f"level {name!r} was not registered")
    del _registered[name]
