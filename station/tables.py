"""The console's tables of products: every kind's headline figures, as its kind declares them.

``station run`` (a pass, a block, a stereo pair, a SAR frame), ``station process`` and a
block's level 2 and 3 print their products through :func:`product_table`: one table per
set of columns (the scene levels share theirs; a pair's DEM and a SAR frame's GEC and GTC
have their own, :attr:`levels.kinds.ProductKind.figures`), a dash where a product has no
such figure, and below each table what the kind notes of each product (the stripes of a
1A, the control points of a level 2).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from levels.kinds import Figure
from levels.quality import scalar_figures
from levels.registry import kind

__all__ = ["dash", "product_table"]


def dash(x: float | None, spec: str) -> str:
    """``x`` formatted by ``spec`` ("10.1f"), or a dash as wide when there is no figure
    (None, or not a finite number)."""
    width = int(spec.split(".")[0]) if spec[0].isdigit() else 1
    if x is None or x != x or x in (float("inf"), float("-inf")):
        return "—".rjust(width)
    return format(x, spec)


def _columns(row: Mapping[str, Any]) -> tuple[Figure, ...]:
    try:
        return kind(str(row["level"])).figures
    except KeyError:  # a kind not known here: its size and file alone
        return ()


def _notes(level: str, figures: Mapping[str, Any]) -> tuple[str, ...]:
    try:
        return kind(level).notes(figures)
    except KeyError:
        return ()


def product_table(rows: Sequence[Mapping[str, Any]], lead: Sequence[tuple[str, str]]) -> list[str]:
    """Lines of text: the products ``rows`` (``level``, ``file``, ``quality``; ``n_rows``,
    ``n_cols`` and ``valid`` where known), their ``lead`` columns first (``(key, header)``,
    e.g. ``("scene", "scene")``), then level, size, valid share and their kind's figures,
    grouped by those columns in the order they come."""
    groups: dict[tuple[str, ...], list[Mapping[str, Any]]] = {}
    for r in rows:
        groups.setdefault(tuple(f.label for f in _columns(r)), []).append(r)
    widths = [max([len(h), 5] + [len(str(r.get(key, ""))) for r in rows]) for key, h in lead]
    lines: list[str] = []
    for members in groups.values():
        figures = _columns(members[0])
        head = [h.rjust(w) for (_, h), w in zip(lead, widths, strict=True)]
        lines.append(
            " ".join(
                [*head, f"{'level':>5}", f"{'size px':>11}", f"{'valid':>6}"]
                + [f.label.rjust(int(f.spec.split(".")[0])) for f in figures]
            )
            + "  product"
        )
        notes, figured = [], []
        for r in members:
            q = scalar_figures(dict(r.get("quality", {})))
            figured.append(q)
            size = f"{r['n_rows']:>5}×{r['n_cols']:<5}" if "n_rows" in r else f"{'':11}"
            cells = [str(r.get(key, "")).rjust(w) for (key, _), w in zip(lead, widths, strict=True)]
            lines.append(
                " ".join(
                    [*cells, f"{r['level']:>5}", size, dash(r.get("valid"), "6.3f")]
                    + [dash(f.value(q), f.spec) for f in figures]
                )
                + f"  {r['file']}"
            )
            notes += [f"  {r['file']}: {n}" for n in _notes(str(r["level"]), q)]
        lines += notes
        if any(f.value(q) is not None for q in figured for f in figures if f.legend):
            lines += [f"  {f.legend}" for f in figures if f.legend]  # once, under the table
    return lines
