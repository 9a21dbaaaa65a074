"""The archive's catalogue (``station.archive_catalogue``, ``station catalogue``): a run's
pass, scenes and products as entries; searches equal to a brute-force filter of every
entry; exported Items valid; two writers at once; a writer killed mid-transaction."""

from __future__ import annotations

import json
import sqlite3
import subprocess
import sys
from pathlib import Path

import pytest
from _catalogue_items import synthetic

from station.archive_catalogue import CATALOGUE_FILE, Catalogue, Query
from station.cli import main

HERE = Path(__file__).resolve().parent
#: Seconds a writer subprocess may take (a few hundred small transactions).
WRITER_S = 120


def _brute(items: list[dict], q: Query) -> list[str]:
    """The Items a query selects, by filtering every one in Python."""
    from station.archive_catalogue import _boxes, _seconds

    def hit(it: dict) -> bool:
        p = it["properties"]
        if q.bbox is not None:
            boxes = _boxes(it["bbox"])
            if not any(
                a[1] >= b[0] and a[0] <= b[1] and a[3] >= b[2] and a[2] <= b[3]
                for a in boxes
                for b in _boxes(q.bbox)
            ):
                return False
        if q.datetime:
            lo, _, hi = q.datetime.partition("/")
            t = _seconds(p.get("datetime") or p.get("start_datetime"))
            t_end = _seconds(p.get("end_datetime")) or t
            if (_seconds(lo) is not None and t_end < _seconds(lo)) or (
                _seconds(hi) is not None and t > _seconds(hi)
            ):
                return False
        return not q.levels or p.get("processing:level") in {f"L{v}" for v in q.levels}

    return sorted(it["id"] for it in items if hit(it))


def test_searches_are_a_brute_force_filter(tmp_path: Path) -> None:
    """Thousands of Items: every query's answer is the filter of every Item."""
    items = synthetic(3000, 60)
    with Catalogue(tmp_path / CATALOGUE_FILE) as cat:
        assert cat.add(items) == 3000
        queries = [
            Query(bbox=(-10, -10, 10, 10)),
            Query(bbox=(170, -20, -170, 20)),  # across the antimeridian
            Query(datetime="1990-01-01T00:00:00Z/1995-01-01T00:00:00Z"),
            Query(bbox=(0, 0, 60, 60), datetime="../1992-06-01T00:00:00Z", levels=("1A",)),
            Query(levels=("2A",)),
        ]
        for q in queries:
            got = sorted(it["id"] for it in cat.search(q))
            assert got == _brute(items, q), q
            assert cat.count(q) == len(got)
        assert [it["id"] for it in cat.search(Query(kj="5/204"))] == ["syn000004"]
        cat.add(items[:10])  # again: replaced, not doubled
        assert len(cat) == 3000


def test_a_runs_pass_scenes_and_products_are_catalogued(run_dir: Path, tmp_path: Path) -> None:
    """``station catalogue DIR add RUN``: the pass, each scene of its cut and each product,
    found by level, K–J, bbox and time; the export's Items are valid STAC."""
    from stac_validator import stac_validator
    from test_stac import SCHEMA_MAP

    arch = tmp_path / "archive"
    assert main(["catalogue", "-q", str(arch), "add", str(run_dir)]) == 0
    with Catalogue(arch / CATALOGUE_FILE) as cat:
        items = list(cat.items())
        kinds = {it["collection"] for it in items}
        assert {"spot-passes", "spot-scenes", "spot-l1a"} <= kinds
        (pass_item,) = [it for it in items if it["collection"] == "spot-passes"]
        scenes = [it for it in items if it["collection"] == "spot-scenes"]
        l1a = [it for it in items if it["collection"] == "spot-l1a"]
        assert len(scenes) == len(l1a) == pass_item["properties"]["spot:scenes"]
        for scene, product in zip(scenes, l1a, strict=True):  # the scene's K–J is its 1A's
            for key in ("spot:k", "spot:j"):
                assert scene["properties"][key] == product["properties"][key]
        k, j = scenes[0]["properties"]["spot:k"], scenes[0]["properties"]["spot:j"]
        found = cat.search(Query(kj=f"{k}/{j}", levels=("1A",)))
        assert [it["id"] for it in found] == [l1a[0]["id"]]
        for q in (Query(bbox=tuple(scenes[0]["bbox"])), Query(datetime="1990-01-01/..")):
            assert sorted(it["id"] for it in cat.search(q)) == _brute(items, q)
    out = tmp_path / "items.ndjson"
    assert main(["catalogue", "-q", str(arch), "export", "--ndjson", str(out)]) == 0
    lines = out.read_text().splitlines()
    assert len(lines) == len(items)
    for k, line in enumerate(lines):
        item = json.loads(line)
        assert item["collection"].startswith("spot-")  # what pypgstac's loader needs
        one = tmp_path / f"item{k}.json"
        one.write_text(line)
        v = stac_validator.StacValidate(str(one), core=True, schema_map=SCHEMA_MAP)
        assert v.run(), (item["id"], v.message)
        for asset in item["assets"].values():  # relative to the catalogue, resolving
            assert (arch / asset["href"]).resolve().is_file(), asset["href"]
    collections = [
        json.loads(x) for x in Path(f"{out}.collections.ndjson").read_text().splitlines()
    ]
    assert {c["id"] for c in collections} == {json.loads(x)["collection"] for x in lines}
    for k, c in enumerate(collections):
        one = tmp_path / f"collection{k}.json"
        one.write_text(json.dumps(c))
        v = stac_validator.StacValidate(str(one), core=True, schema_map=SCHEMA_MAP)
        assert v.run(), (c["id"], v.message)


def test_bad_searches_are_one_line(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    arch = tmp_path / "archive"
    assert main(["catalogue", str(arch), "search"]) == 2  # no catalogue there
    with Catalogue(tmp_path / CATALOGUE_FILE) as cat:
        cat.add(synthetic(3, 1))
    for bad in (["--kj", "x/1"], ["--bbox", "1,2,3"], ["--datetime", "yesterday"]):
        capsys.readouterr()
        assert main(["catalogue", str(tmp_path), "search", *bad]) == 2, bad
        err = capsys.readouterr().err.strip()
        assert err.startswith("station: error:") and "\n" not in err


_WRITER = """
import sys
from pathlib import Path
sys.path.insert(0, sys.argv[-1])
from _catalogue_items import synthetic
from station.archive_catalogue import Catalogue
with Catalogue(Path(sys.argv[1])) as cat:
    for item in synthetic(int(sys.argv[2]), int(sys.argv[3]), sys.argv[4]):
        cat.add([item])
"""


def test_two_processes_writing_at_once_lose_no_entry(tmp_path: Path) -> None:
    """Two writers, each a transaction an Item, at once: every Item of both is there."""
    db = tmp_path / CATALOGUE_FILE
    Catalogue(db).close()
    procs = [
        subprocess.Popen(
            [sys.executable, "-c", _WRITER, str(db), "300", str(seed), prefix, str(HERE)]
        )
        for seed, prefix in ((1, "a"), (2, "b"))
    ]
    assert [p.wait(WRITER_S) for p in procs] == [0, 0]
    with Catalogue(db) as cat:
        assert len(cat) == 600


_KILLED = """
import sys, time
from pathlib import Path
sys.path.insert(0, sys.argv[-1])
from _catalogue_items import synthetic
from station.archive_catalogue import Catalogue

class Slow:  # the connection, stopping in the middle of a transaction's inserts
    def __init__(self, db):
        self.db, self.n = db, 0
    def execute(self, sql, *args):
        if sql.startswith("INSERT INTO items"):
            self.n += 1
            if self.n == 50:
                print("inside", flush=True)
                time.sleep(60)
        return self.db.execute(sql, *args)
    def executemany(self, *args):
        return self.db.executemany(*args)

cat = Catalogue(Path(sys.argv[1]))
cat._db = Slow(cat._db)
cat.add(synthetic(200, 7, "k"))
"""


def test_a_writer_killed_mid_transaction_leaves_no_partial_entry(tmp_path: Path) -> None:
    """A pass's 200 entries, the writer killed after 50: none of them is there, the
    database is whole, and the next writer writes."""
    db = tmp_path / CATALOGUE_FILE
    with Catalogue(db) as cat:
        cat.add(synthetic(5, 3, "before"))
    proc = subprocess.Popen(
        [sys.executable, "-c", _KILLED, str(db), str(HERE)], stdout=subprocess.PIPE, text=True
    )
    try:
        assert proc.stdout is not None and proc.stdout.readline().strip() == "inside"
    finally:
        proc.kill()
        proc.wait(WRITER_S)
        if proc.stdout is not None:
            proc.stdout.close()
    with sqlite3.connect(db) as raw:
        assert raw.execute("PRAGMA integrity_check").fetchone()[0] == "ok"
    with Catalogue(db) as cat:
        assert len(cat) == 5
        assert cat.search(Query(bbox=(-180, -90, 180, 90)))  # the R*Tree whole too
        cat.add(synthetic(200, 7, "k"))
        assert len(cat) == 205


def test_the_text_search_says_each_entry(run_dir: Path, tmp_path: Path, capsys) -> None:
    arch = tmp_path / "archive"
    assert main(["catalogue", str(arch), "add", str(run_dir / "small_test.l0.h5")]) == 0
    capsys.readouterr()
    assert main(["catalogue", str(arch), "search", "--level", "0"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith(f"{len(out) - 1} entries")
    assert all("spot-scenes" in line for line in out[1:])
