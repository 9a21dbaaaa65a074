"""What a plan's steps leave in a directory and a later plan takes back, as ASP's entry
points do (:mod:`levels.work`): the tie points matched between a block's scenes, each pass's
merged into ``<name>.tie.csv``; level 2's adjustment read back from its products."""

from __future__ import annotations

import functools
import itertools
import operator
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, TypedDict

from levels.choices import Level
from levels.errors import GcpError, GeometryError
from levels.products import product_name
from levels.readers.gcp import ControlPointSet, write_gcps
from levels.registry import kind

if TYPE_CHECKING:
    from levels.adjust.model import Adjustment

__all__ = ["TiePair", "TiesFound", "taken_adjustment", "tie_points"]


class TiePair(TypedDict):
    """Two passes' scenes that tie points were found between, and how many."""

    a: str
    b: str
    scene_a: int
    scene_b: int
    points: int
    counts: dict[str, int]


class TiesFound(TypedDict):
    """The tie points a block found (:func:`tie_points`), per pair of scenes; none when its
    ties were taken from a directory."""

    pairs: list[TiePair]


def tie_points(scene_dirs: dict[str, Path], out: Path) -> TiesFound:
    """Tie points between every two passes' overlapping 2A scenes (the ``*_2A.nc`` of each
    pass's directory in ``scene_dirs``), each pass's merged into ``out/<pass>.tie.csv``;
    what was found, per pair of scenes."""
    from levels.products import read_product
    from levels.tiepoints import MapView, match_views

    views = {
        name: [MapView.of_product(read_product(p)) for p in sorted(d.glob(f"{name}_s*_2A.nc"))]
        for name, d in scene_dirs.items()
    }
    per: dict[str, list[ControlPointSet]] = {n: [] for n in scene_dirs}
    pairs = []
    for a, b in itertools.combinations(list(scene_dirs), 2):
        for va, vb in itertools.product(views[a], views[b]):
            try:
                tp = match_views(va, vb)
            except GeometryError:  # these two scenes do not overlap
                continue
            if not len(tp):
                continue
            per[a].append(tp.control_points("a"))
            per[b].append(tp.control_points("b"))
            pairs.append(
                TiePair(
                    a=a, b=b, scene_a=va.scene, scene_b=vb.scene, points=len(tp), counts=tp.counts
                )
            )
    out.mkdir(parents=True, exist_ok=True)
    for n, sets in per.items():
        if sets:
            comment = f"tie points of {n} (docs/gcp.md)"
            write_gcps(out / f"{n}.tie.csv", functools.reduce(operator.add, sets), comment)
    return TiesFound(pairs=pairs)


def taken_adjustment(where: Path, name: str) -> Adjustment:
    """The adjustment of archive ``name`` taken from its level 2 products in ``where``
    (``<name>_sNNN_2.nc``, every scene's: :meth:`levels.adjust.Adjustment.from_trees`);
    refused in one line when there are none or they are damaged."""
    from levels.adjust.model import Adjustment
    from levels.products import read_product

    on_map = kind(Level.L2).on_map
    paths = sorted(Path(where).glob(product_name(name, 0, Level.L2, on_map).replace("000", "*")))
    if not paths:
        raise GcpError(
            f"no level 2 of {name} in {where} to take its adjustment from "
            f"({product_name(name, 0, Level.L2, on_map).replace('000', 'NNN')})"
        )
    trees = []
    for path in paths:
        product = read_product(path, images=False)
        tree = product.geometry.get("adjustment")
        if not isinstance(tree, Mapping):
            raise GcpError(f"{path}: a level 2 product without its adjustment")
        trees.append((int(product.attrs["scene_index"]), tree))
    try:
        return Adjustment.from_trees(trees)
    except (KeyError, TypeError, ValueError) as exc:
        raise GcpError(f"{where}: the adjustment of {name} cannot be read back ({exc})") from None
