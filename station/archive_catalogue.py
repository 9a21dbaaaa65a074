"""The archive's catalogue: every archived pass, scene and product an entry of a database.

It is embedded in SQLite, the standard library's (``<archive>/catalogue.sqlite``). Each
entry is a STAC Item, kept whole as JSON. Beside it are the columns it is searched by:
time, mission, instrument, mode, level, and SPOT's K–J grid reference
(:mod:`station.grs`), each indexed. The footprints' bounding boxes are in an R*Tree
(SQLite's ``rtree`` module). A box across the antimeridian is two boxes of one entry.

Entries are written **one transaction a pass or a product** (:meth:`Catalogue.add`), so a
crash never leaves half an entry. Adding an entry again replaces it, which is how a
resumed day re-catalogues what it finds. The database is in write-ahead-log mode, with a
busy timeout, so several processes (a front end, processing workers) can write at once and
readers never wait for them.

What a pass's archive gives (:func:`archive_items`):

- one Item for the pass (``spot-passes``), its footprint the strip's;
- one for each scene of its cut (``spot-scenes``), footprint and centre instant as GEO
  places them on the reference surface, with its K–J.

Each product gets the Item ``station.catalog.item_of`` makes of it (``spot-l1a``,
``spot-l2a``, …), with its scene's K–J.

``station catalogue DIR search`` answers from the indexes; ``export --ndjson F`` writes one
Item a line, each naming its collection, which pgstac's loader (``pypgstac load items``)
and stac-geoparquet take for a catalogue that outgrows one machine.
"""

from __future__ import annotations

import datetime as dt
import json
import sqlite3
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from station.errors import StationError
from station.grs import kj_of

__all__ = [
    "CATALOGUE_FILE",
    "Catalogue",
    "Query",
    "add_archive",
    "add_paths",
    "add_products",
    "archive_items",
    "product_items",
]

CATALOGUE_FILE = "catalogue.sqlite"
#: Seconds a writer waits for another's transaction before it gives up.
BUSY_TIMEOUT_S = 60.0
_SCHEMA = """
CREATE TABLE IF NOT EXISTS items (
    rowid INTEGER PRIMARY KEY,
    id TEXT NOT NULL,
    collection TEXT NOT NULL,
    t REAL NOT NULL,
    t_end REAL NOT NULL,
    mission TEXT, instrument TEXT, mode TEXT, level TEXT,
    k INTEGER, j INTEGER,
    pass TEXT,
    href TEXT,
    item TEXT NOT NULL,
    UNIQUE (collection, id)
);
CREATE VIRTUAL TABLE IF NOT EXISTS boxes USING rtree(
    box, min_lon, max_lon, min_lat, max_lat, +item INTEGER
);
CREATE INDEX IF NOT EXISTS items_t ON items (t);
CREATE INDEX IF NOT EXISTS items_t_end ON items (t_end);
CREATE INDEX IF NOT EXISTS items_mission ON items (mission);
CREATE INDEX IF NOT EXISTS items_instrument ON items (instrument);
CREATE INDEX IF NOT EXISTS items_mode ON items (mode);
CREATE INDEX IF NOT EXISTS items_level ON items (level);
CREATE INDEX IF NOT EXISTS items_kj ON items (k, j);
CREATE INDEX IF NOT EXISTS items_pass ON items (pass);
"""


def _seconds(when: str | None) -> float | None:
    """An RFC 3339 instant as UNIX seconds (UTC when no zone is said)."""
    if when in (None, "", ".."):
        return None
    t = dt.datetime.fromisoformat(str(when).replace("Z", "+00:00"))
    return (t if t.tzinfo else t.replace(tzinfo=dt.UTC)).timestamp()


def _boxes(bbox: Sequence[float]) -> list[tuple[float, float, float, float]]:
    """(west, east, south, north) boxes of a STAC bbox, split at 180° when it crosses."""
    west, south, east, north = (float(v) for v in (*bbox[:2], *bbox[-2:]))
    if west <= east:
        return [(west, east, south, north)]
    return [(west, 180.0, south, north), (-180.0, east, south, north)]


@dataclass(frozen=True)
class Query:
    """What ``search`` is asked: a bbox (west, south, east, north, degrees; west > east
    across the antimeridian), an interval (RFC 3339 ``a/b``, ``..`` open, or one
    instant), levels (``0``, ``1A``, ``2A`` …; ``pass`` and ``scene`` for the archive's
    own), K–J (``K/J``, each a number or a range ``a-b``), mission, instrument, mode."""

    bbox: tuple[float, float, float, float] | None = None
    datetime: str | None = None
    levels: tuple[str, ...] = ()
    kj: str | None = None
    mission: str | None = None
    instrument: str | None = None
    mode: str | None = None
    limit: int | None = None

    def where(self) -> tuple[str, list[object], str]:
        """The SQL conditions and their parameters, and the join the bbox needs."""
        cond: list[str] = []
        args: list[object] = []
        join = ""
        if self.bbox is not None:
            boxes = _boxes(self.bbox)
            join = (
                "JOIN (SELECT DISTINCT item FROM boxes WHERE "
                + " OR ".join(
                    "(max_lon >= ? AND min_lon <= ? AND max_lat >= ? AND min_lat <= ?)"
                    for _ in boxes
                )
                + ") AS b ON b.item = items.rowid"
            )
            for w, e, s, n in boxes:
                args += [w, e, s, n]
        if self.datetime:
            a, _, b = self.datetime.partition("/") if "/" in self.datetime else (
                self.datetime, "", self.datetime)  # fmt: skip
            lo, hi = _seconds(a), _seconds(b)
            if lo is not None:
                cond.append("t_end >= ?")
                args.append(lo)
            if hi is not None:
                cond.append("t <= ?")
                args.append(hi)
        if self.levels:
            cond.append(f"level IN ({','.join('?' * len(self.levels))})")
            args += [_level(v) for v in self.levels]
        if self.kj:
            for column, part in zip(("k", "j"), _kj(self.kj), strict=True):
                if part is not None:
                    cond.append(f"{column} BETWEEN ? AND ?")
                    args += list(part)
        for column in ("mission", "instrument", "mode"):
            value = getattr(self, column)
            if value:
                cond.append(f"{column} = ?")
                args.append(value.lower() if column != "mode" else value)
        return " AND ".join(cond) or "1", args, join


def _level(value: str) -> str:
    v = str(value).strip().upper().removeprefix("L")
    return {"PASS": "pass", "SCENE": "scene", "0": "L0"}.get(v, f"L{v}")


def _kj(text: str) -> tuple[tuple[int, int] | None, tuple[int, int] | None]:
    """``K/J``: each a number, a range ``a-b``, or empty (any)."""
    parts = str(text).split("/")
    if len(parts) != 2:
        raise StationError(f"--kj {text!r}: expected K/J, each a number or a range a-b")
    out: list[tuple[int, int] | None] = []
    for p in parts:
        p = p.strip()
        if not p:
            out.append(None)
            continue
        try:
            a, _, b = p.partition("-")
            lo, hi = int(a), int(b or a)
        except ValueError:
            raise StationError(f"--kj {text!r}: {p!r} is not a number or a range a-b") from None
        out.append((min(lo, hi), max(lo, hi)))
    return out[0], out[1]


class Catalogue:
    """The archive's catalogue at ``path`` (created if absent)."""

    def __init__(self, path: str | Path, *, create: bool = True) -> None:
        self.path = Path(path)
        if not create and not self.path.is_file():
            raise StationError(f"{self.path}: no catalogue there")
        self._db = sqlite3.connect(self.path, timeout=BUSY_TIMEOUT_S, isolation_level=None)
        self._db.execute("PRAGMA journal_mode=WAL")
        self._db.execute("PRAGMA synchronous=NORMAL")
        self._db.executescript(_SCHEMA)

    def close(self) -> None:
        self._db.close()

    def __enter__(self) -> Catalogue:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __len__(self) -> int:
        return int(self._db.execute("SELECT count(*) FROM items").fetchone()[0])

    def add(self, items: Iterable[dict]) -> int:
        """Items added (or replaced) in one transaction: all of them, or, on any failure,
        none. Returns how many."""
        rows = [_row(item) for item in items]
        db = self._db
        db.execute("BEGIN IMMEDIATE")
        try:
            for row, boxes in rows:
                old = db.execute(
                    "SELECT rowid FROM items WHERE collection = ? AND id = ?", (row[1], row[0])
                ).fetchone()
                if old is not None:
                    db.execute("DELETE FROM boxes WHERE item = ?", (old[0],))
                    db.execute("DELETE FROM items WHERE rowid = ?", (old[0],))
                cur = db.execute(
                    "INSERT INTO items (id, collection, t, t_end, mission, instrument, mode, "
                    "level, k, j, pass, href, item) VALUES (?,?,?,?,?,?,?,?,?,?,?,?,?)",
                    row,
                )
                db.executemany(
                    "INSERT INTO boxes (min_lon, max_lon, min_lat, max_lat, item) "
                    "VALUES (?,?,?,?,?)",
                    [(*b, cur.lastrowid) for b in boxes],
                )
            db.execute("COMMIT")
        except BaseException:
            db.execute("ROLLBACK")
            raise
        return len(rows)

    def search(self, query: Query) -> list[dict]:
        """The Items the query selects, by time."""
        cond, args, join = query.where()
        sql = f"SELECT items.item FROM items {join} WHERE {cond} ORDER BY t, collection, id"
        if query.limit:
            sql += f" LIMIT {int(query.limit)}"
        return [json.loads(r[0]) for r in self._db.execute(sql, args)]

    def count(self, query: Query) -> int:
        cond, args, join = query.where()
        return int(self._db.execute(f"SELECT count(*) FROM items {join} WHERE {cond}", args)
                   .fetchone()[0])  # fmt: skip

    def has(self, collection: str, item_id: str) -> bool:
        return (
            self._db.execute(
                "SELECT 1 FROM items WHERE collection = ? AND id = ?", (collection, item_id)
            ).fetchone()
            is not None
        )

    def ids(self) -> set[str]:
        """Every entry's id (a pass's, a scene's, a product's: ids are unique across the
        collections this module writes)."""
        return {row[0] for row in self._db.execute("SELECT id FROM items")}

    def items(self) -> Iterator[dict]:
        for (raw,) in self._db.execute("SELECT item FROM items ORDER BY t, collection, id"):
            yield json.loads(raw)

    def collections(self) -> list[dict]:
        """A STAC Collection for each collection the entries are in: its extent in space
        and time from theirs."""
        rows = self._db.execute(
            "SELECT collection, min(t), max(t_end), count(*), min(b.min_lon), min(b.min_lat), "
            "max(b.max_lon), max(b.max_lat) FROM items JOIN boxes AS b ON b.item = items.rowid "
            "GROUP BY collection ORDER BY collection"
        ).fetchall()
        out = []
        for name, t0, t1, n, w, s, e, north in rows:
            iso = [dt.datetime.fromtimestamp(t, dt.UTC).isoformat().replace("+00:00", "Z")
                   for t in (t0, t1)]  # fmt: skip
            out.append({
                "type": "Collection", "stac_version": "1.1.0", "stac_extensions": [],
                "id": name, "license": "other",
                "description": f"{_DESCRIPTIONS.get(name, 'products')} of the station's "
                f"archive ({n} entries)",
                "extent": {"spatial": {"bbox": [[w, s, e, north]]},
                           "temporal": {"interval": [iso]}},
                "links": [],
            })  # fmt: skip
        return out

    def export_ndjson(self, path: str | Path) -> int:
        """Every Item, one a line (the newline-delimited form pgstac's loader and
        stac-geoparquet read), each linked to its Collection; the Collections one a line
        beside (``<F>.collections.ndjson``: ``pypgstac load collections`` first). Written
        whole or not at all. Returns how many Items."""
        from levels.files import atomic_path

        path = Path(path)
        beside = path.with_name(f"{path.name}.collections.ndjson")
        with atomic_path(beside) as tmp, Path(tmp).open("w") as f:
            for c in self.collections():
                f.write(json.dumps(c, separators=(",", ":")) + "\n")
        n = 0
        with atomic_path(path) as tmp, Path(tmp).open("w") as f:
            for item in self.items():
                item["links"] = [
                    link for link in item.get("links", []) if link.get("rel") != "collection"
                ] + [{"rel": "collection", "href": beside.name, "type": "application/json"}]
                f.write(json.dumps(item, separators=(",", ":")) + "\n")
                n += 1
        return n


_DESCRIPTIONS = {
    "spot-passes": "the passes",
    "spot-scenes": "the scenes (level 0, as the passes were cut)",
}


def _row(item: dict) -> tuple[tuple, list[tuple[float, float, float, float]]]:
    """The searched columns of an Item, and its boxes."""
    p = item.get("properties", {})
    when = p.get("datetime") or p.get("start_datetime")
    t = _seconds(when)
    if t is None or "bbox" not in item:
        raise StationError(f"item {item.get('id')!r}: no time or no bbox, not catalogued")
    t_end = _seconds(p.get("end_datetime")) or t
    instruments = p.get("instruments") or [None]
    row = (
        str(item["id"]),
        str(item.get("collection") or "spot-items"),
        t,
        t_end,
        (p.get("platform") or "").lower() or None,
        (instruments[0] or "").lower() or None,
        p.get("spot:mode"),
        "pass" if item.get("collection") == "spot-passes" else p.get("processing:level"),
        p.get("spot:k"),
        p.get("spot:j"),
        p.get("spot:pass"),
        next((a.get("href") for a in item.get("assets", {}).values()), None),
        json.dumps(item, separators=(",", ":")),
    )
    return row, _boxes(item["bbox"])


def _iso(epoch: np.ndarray, t_s: float) -> str:
    when = epoch + np.timedelta64(round(t_s * 1e6), "us")
    return str(np.datetime_as_string(when.astype("datetime64[us]"), unit="us")) + "Z"


def _kj_props(lat: float, lon: float) -> dict[str, object]:
    k, j, row = kj_of(lat, lon)
    return {
        "spot:k": int(k),
        "spot:j": int(j),
        "spot:shift": round((float(row) - int(j)) * 10),
    }


def _relative(item: dict, root: Path) -> dict:
    """Asset hrefs relative to the catalogue's directory (moved with it)."""
    import os

    for asset in item.get("assets", {}).values():
        href = asset.get("href", "")
        if href and Path(href).is_absolute():
            asset["href"] = os.path.relpath(href, root)
    return item


def archive_items(path: str | Path, root: str | Path) -> list[dict]:
    """The Items of a pass's L0 archive: the pass, and each scene of its cut as GEO places
    it (module docstring); hrefs relative to ``root``."""
    from levels.options import ProcessingOptions
    from levels.passes import geo_pass
    from levels.readers.l0 import read_l0
    from station.catalog import EXTENSIONS, footprint_geojson

    path = Path(path)
    archive = read_l0(path, lazy=True)
    cut = archive.scene_cut
    options = ProcessingOptions(
        scene_lines=int(cut.get("scene_lines", 0)), overlap_lines=int(cut.get("overlap_lines", 0))
    )
    setup = geo_pass(archive, options)
    if not setup.scenes:
        raise StationError(f"{path}: GEO placed no scene of the pass; not catalogued")
    epoch = np.asarray(archive.epoch.t0_utc).astype("datetime64[us]")
    stem = path.name.removesuffix(".l0.h5").removesuffix(".h5")
    prov = archive.provenance
    common: dict[str, object] = {
        "constellation": "spot",
        "platform": str(prov.get("mission", "spot-emulated")).lower().replace(" ", "-"),
        "instruments": [f"hrv{archive.hrv}"],
        "spot:mode": archive.mode,
        "spot:mirror_step": int(archive.mirror_step),
        "spot:pass": stem,
        "processing:level": "L0",
    }
    ext = [EXTENSIONS["processing:"]]
    asset = {"data": {"href": str(path.resolve()), "type": "application/x-hdf5",
                      "roles": ["data"], "title": "the pass's L0 archive"}}  # fmt: skip
    items = []
    for s in setup.scenes:
        lat, lon = np.degrees(s.corners_lat_rad), np.degrees(s.corners_lon_rad)
        geometry, bbox = footprint_geojson(lat, lon)
        clock = setup.pg.clock(s.cut.first_line)
        t0, t1 = (float(clock.time_s(x)) for x in (0, s.cut.n_lines - 1))
        props = {
            "datetime": _iso(epoch, s.t_centre_s),
            "start_datetime": _iso(epoch, t0),
            "end_datetime": _iso(epoch, t1),
            **common,
            "spot:scene_index": int(s.cut.index),
            "spot:first_line": int(s.cut.first_line),
            "spot:lines": int(s.cut.n_lines),
            **_kj_props(float(np.degrees(s.centre_lat_rad)), float(np.degrees(s.centre_lon_rad))),
        }
        items.append(_feature(f"{stem}_s{s.cut.index:03d}", "spot-scenes", geometry, bbox,
                              props, ext, asset))  # fmt: skip
    first, last = setup.scenes[0], setup.scenes[-1]
    lat = np.degrees(np.r_[first.corners_lat_rad[:2], last.corners_lat_rad[2:]])
    lon = np.degrees(np.r_[first.corners_lon_rad[:2], last.corners_lon_rad[2:]])
    geometry, bbox = footprint_geojson(lat, lon)
    t0 = float(setup.pg.clock(0).time_s(0))
    t1 = float(setup.pg.clock(0).time_s(archive.n_lines - 1))
    props = {
        "datetime": _iso(epoch, 0.5 * (t0 + t1)),
        "start_datetime": _iso(epoch, t0),
        "end_datetime": _iso(epoch, t1),
        **common,
        "spot:lines": int(archive.n_lines),
        "spot:scenes": len(setup.scenes),
    }
    items.insert(0, _feature(stem, "spot-passes", geometry, bbox, props, ext, asset))
    return [_relative(i, Path(root)) for i in items]


def _feature(
    item_id: str, collection: str, geometry: dict, bbox: list[float], props: dict,
    extensions: list[str], assets: dict,
) -> dict:  # fmt: skip
    return {
        "type": "Feature",
        "stac_version": "1.1.0",
        "stac_extensions": list(extensions),
        "id": item_id,
        "collection": collection,
        "geometry": geometry,
        "bbox": bbox,
        "properties": props,
        "links": [],
        "assets": json.loads(json.dumps(assets)),
    }


def product_items(paths: Iterable[str | Path], root: str | Path) -> list[dict]:
    """The Items of level products (``station.catalog.item_of``'s), each in its level's
    collection (``spot-l1a`` …) with its scene's K–J; hrefs relative to ``root``."""
    from levels.products import read_product
    from station.catalog import item_of

    items = []
    for path in paths:
        path = Path(path)
        item = item_of(path, Path(root))
        if item is None:
            continue
        d = item.to_dict(include_self_link=False)
        level = str(d["properties"].get("processing:level", "")).lower() or "product"
        d["collection"] = f"spot-{level}"
        scene = read_product(path, images=False).geometry.get("scene")
        if scene is not None and "centre_lat_deg" in scene:
            d["properties"].update(
                _kj_props(float(scene["centre_lat_deg"]), float(scene["centre_lon_deg"]))
            )
        items.append(_relative(d, Path(root)))
    return items


def add_archive(catalogue: Catalogue, path: str | Path) -> int:
    """A pass's archive catalogued (the pass and its scenes, one transaction)."""
    return catalogue.add(archive_items(path, catalogue.path.parent))


def add_products(catalogue: Catalogue, paths: Iterable[str | Path]) -> int:
    """Products catalogued, one transaction each."""
    return sum(catalogue.add(product_items([p], catalogue.path.parent)) for p in paths)


def add_paths(catalogue: Catalogue, paths: Iterable[str | Path]) -> dict[str, object]:
    """L0 archives (``*.l0.h5``), products, or directories of them, catalogued: each
    archive one transaction (an archive GEO cannot place is listed, not fatal), each
    product one. What was done."""
    from levels.products import is_product_file

    archives, products = [], []
    for given in map(Path, paths):
        if not given.exists():
            raise StationError(f"{given}: no such file or directory")
        files = sorted(given.rglob("*")) if given.is_dir() else [given]
        archives += [f for f in files if f.name.endswith(".l0.h5")]
        products += [f for f in files if f.is_file() and is_product_file(f)]
    n_passes = n_items = 0
    refused: list[str] = []
    for f in archives:
        try:
            n_items += add_archive(catalogue, f)
            n_passes += 1
        except StationError as exc:
            refused.append(f"{f}: {exc}")
    n_items += add_products(catalogue, products)
    return {"passes": n_passes, "items": n_items, "refused": refused, "entries": len(catalogue)}
