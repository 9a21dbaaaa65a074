"""``station catalogue DIR add|search|export``: the archive's catalogue
(:mod:`station.archive_catalogue`)."""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import TYPE_CHECKING

from station.cli._options import add_json, emit
from station.errors import StationError

if TYPE_CHECKING:
    from station.archive_catalogue import Catalogue
    from station.cli._options import Subparsers

__all__ = ["register"]


def register(sub: Subparsers) -> None:
    p = sub.add_parser(
        "catalogue",
        help="the archive's catalogue: add passes and products, search, export",
        description="The station's archive catalogue (DIR/catalogue.sqlite, SQLite): every "
        "archived pass, scene and product a STAC Item, searched by footprint (an R*Tree), "
        "time, level, mission, instrument, mode and SPOT's K-J grid reference.",
    )
    p.add_argument("dir", help="the archive's directory (its catalogue.sqlite)")
    verbs = p.add_subparsers(dest="verb", metavar="VERB", required=True)
    a = verbs.add_parser("add", help="catalogue L0 archives, products, or run directories")
    a.add_argument("paths", nargs="+", help="*.l0.h5 archives, products, or directories of them")
    add_json(a)
    a.set_defaults(func=_add)
    s = verbs.add_parser("search", help="the entries a query selects, by time")
    s.add_argument("--bbox", metavar="W,S,E,N", help="degrees; W > E across the antimeridian")
    s.add_argument("--datetime", metavar="I", help="an RFC 3339 instant or interval a/b (.. open)")
    s.add_argument(
        "--level", action="append", default=[], metavar="L",
        help="0 (scenes), pass, 1A, 1B, 2A, 2, 3 … (repeatable)",
    )  # fmt: skip
    s.add_argument("--kj", metavar="K/J", help="the grid reference, each a number or a range a-b")
    s.add_argument("--mission", help="spot-2, spot-emulated …")
    s.add_argument("--instrument", help="hrv1, hrv2 …")
    s.add_argument("--mode", help="P or XS")
    s.add_argument("--limit", type=int, help="at most N entries")
    add_json(s, "the STAC Items (a FeatureCollection)")
    s.set_defaults(func=_search)
    e = verbs.add_parser("export", help="every Item, for pgstac or stac-geoparquet")
    e.add_argument("--ndjson", required=True, metavar="F", help="one Item a line")
    add_json(e)
    e.set_defaults(func=_export)


def _catalogue(args: argparse.Namespace, create: bool) -> Catalogue:
    from station.archive_catalogue import CATALOGUE_FILE, Catalogue

    where = Path(args.dir)
    if create:
        where.mkdir(parents=True, exist_ok=True)
    elif not where.is_dir():
        raise StationError(f"{where}: no such directory")
    return Catalogue(where / CATALOGUE_FILE, create=create)


def _add(args: argparse.Namespace) -> int:
    from station.archive_catalogue import add_paths

    with _catalogue(args, create=True) as cat:
        said = add_paths(cat, [Path(p) for p in args.paths])
    emit(args, said, _add_text)
    return 0


def _add_text(said: dict) -> str:
    lines = [f"{said['items']} items catalogued (passes: {said['passes']}, with their scenes; "
             f"and products); {said['entries']} entries in the catalogue"]  # fmt: skip
    return "\n".join(lines + [f"not catalogued: {r}" for r in said["refused"]])


def _search(args: argparse.Namespace) -> int:
    from station.archive_catalogue import Query

    bbox = None
    if args.bbox:
        try:
            w, s, e, n = (float(v) for v in args.bbox.split(","))
        except ValueError:
            raise StationError(f"--bbox {args.bbox!r}: expected W,S,E,N in degrees") from None
        if not (-180 <= w <= 180 and -180 <= e <= 180 and -90 <= s <= n <= 90):
            raise StationError(f"--bbox {args.bbox!r}: outside the globe, or S > N")
        bbox = (w, s, e, n)
    query = Query(bbox, args.datetime, tuple(args.level), args.kj, args.mission,
                  args.instrument, args.mode, args.limit)  # fmt: skip
    with _catalogue(args, create=False) as cat:
        t0 = time.perf_counter()
        try:
            items = cat.search(query)
        except ValueError as exc:
            raise StationError(f"--datetime {args.datetime!r}: {exc}") from None
        took_ms = (time.perf_counter() - t0) * 1e3
    if args.json:
        emit(args, {"type": "FeatureCollection", "features": items,
                    "numberReturned": len(items)}, str)  # fmt: skip
    else:
        print(_search_text(items, took_ms))
    return 0


def _search_text(items: list[dict], took_ms: float) -> str:
    lines = [f"{len(items)} entries ({took_ms:.1f} ms)"]
    for it in items:
        p = it["properties"]
        kj = f"{p['spot:k']}/{p['spot:j']}" if "spot:k" in p else "-"
        lines.append(
            f"  {p.get('datetime') or p.get('start_datetime')}  {it['collection']:<12} "
            f"{kj:>8}  {p.get('platform', '')} {','.join(p.get('instruments', []))} "
            f"{p.get('spot:mode', '')}  {it['id']}"
        )
    return "\n".join(lines)


def _export(args: argparse.Namespace) -> int:
    with _catalogue(args, create=False) as cat:
        n = cat.export_ndjson(args.ndjson)
    emit(
        args, {"items": n, "ndjson": args.ndjson}, lambda d: f"{d['items']} items in {d['ndjson']}"
    )
    return 0
