"""Speed of the archive's catalogue (``station.archive_catalogue``) against a brute-force
filter of every entry.

10⁵ synthetic Items (footprints 0.6° wide anywhere between ±80°, some across the
antimeridian, dates over 26 years, levels and K–J) are added in transactions of a
thousand, then searched by bbox and date (a box of 1° to 20° and an interval of 1 to 5
years, drawn at random), and by bbox, date and level. Figures printed:

* the time to add them (Items a second);
* each kind of search's median and worst time over its draws, against issue 60's 50 ms,
  and the brute-force filter's time over the same entries in memory (numpy over their
  columns, the peer), and whether every answer is the filter's.

Run: ``python benchmarks/bench_catalogue.py [n_items]`` (default 100 000).
"""

from __future__ import annotations

import calendar
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from _smoke import size

from station.archive_catalogue import CATALOGUE_FILE, Catalogue, Query

#: Issue 60's bar for a search of 10⁵ entries by bbox and date.
SEARCH_MS = 50.0
DRAWS = size(40, 5)
BATCH = 1000


def _items(n: int, rng: np.random.Generator) -> tuple[list[dict], dict[str, np.ndarray]]:
    lon, lat = rng.uniform(-180, 180, n), rng.uniform(-80, 80, n)
    t = rng.uniform(5.0e8, 1.32e9, n)  # 1985–2011
    level = rng.choice(["L1A", "L1B", "L2A", "L0"], n)
    w = (lon - 0.3 + 540) % 360 - 180
    e = (lon + 0.3 + 540) % 360 - 180
    items = [
        {
            "type": "Feature", "stac_version": "1.1.0", "stac_extensions": [],
            "id": f"i{i:07d}", "collection": "spot-synthetic", "geometry": None,
            "bbox": [float(w[i]), float(lat[i] - 0.3), float(e[i]), float(lat[i] + 0.3)],
            "properties": {
                "datetime": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime(t[i])),
                "processing:level": str(level[i]), "platform": "spot-2",
                "spot:k": int(i % 738) + 1, "spot:j": int(200 + i % 301),
            },
            "links": [], "assets": {},
        }
        for i in range(n)
    ]  # fmt: skip
    cols = {"w": w, "e": e, "s": lat - 0.3, "n": lat + 0.3, "t": np.floor(t), "level": level}
    return items, cols


def _brute(cols: dict[str, np.ndarray], q: Query) -> np.ndarray:
    """The entries a query selects, over every entry's columns (the peer)."""
    hit = np.ones(cols["t"].size, bool)
    if q.bbox is not None:
        w, s, e, n = q.bbox
        crosses = cols["w"] > cols["e"]
        first_e = np.where(crosses, 180.0, cols["e"])  # an entry across 180°: two boxes
        lon = np.zeros_like(hit)
        for qw, qe in [(w, e)] if w <= e else [(w, 180.0), (-180.0, e)]:
            lon |= (first_e >= qw) & (cols["w"] <= qe)
            lon |= crosses & (cols["e"] >= qw) & (-180.0 <= qe)
        hit &= lon & (cols["n"] >= s) & (cols["s"] <= n)
    if q.datetime:
        a, _, b = q.datetime.partition("/")
        hit &= (cols["t"] >= _epoch(a)) & (cols["t"] <= _epoch(b))
    if q.levels:
        hit &= np.isin(cols["level"], [f"L{v}" for v in q.levels])
    return np.flatnonzero(hit)


def _epoch(text: str) -> float:
    return float(calendar.timegm(time.strptime(text, "%Y-%m-%dT%H:%M:%SZ")))


def main() -> None:
    n = int(sys.argv[1]) if len(sys.argv) > 1 else size(100_000, 3_000)
    rng = np.random.default_rng(60)
    items, cols = _items(n, rng)
    with tempfile.TemporaryDirectory(prefix="bench-catalogue-") as tmp:
        with Catalogue(Path(tmp) / CATALOGUE_FILE) as cat:
            t0 = time.perf_counter()
            for a in range(0, n, BATCH):
                cat.add(items[a : a + BATCH])
            added_s = time.perf_counter() - t0
            print(f"{n} items added in {added_s:.1f} s ({n / added_s:.0f} a second, "
                  f"transactions of {BATCH})")  # fmt: skip
            for kind in ("bbox and date", "bbox, date and level"):
                times, peer, same, found = [], [], True, 0
                for _ in range(DRAWS):
                    half = min(60.0, rng.uniform(0.5, 10) * (100_000 / n) ** 0.5)  # as dense
                    x, y = rng.uniform(-170, 170), rng.uniform(-70, 70)
                    y0 = rng.integers(1986, 2006)
                    q = Query(
                        bbox=(x - half, y - half, x + half, y + half),
                        datetime=f"{y0}-01-01T00:00:00Z/{y0 + rng.integers(1, 6)}-01-01T00:00:00Z",
                        levels=("2A",) if "level" in kind else (),
                    )
                    t = time.perf_counter()
                    got = cat.search(q)
                    times.append(time.perf_counter() - t)
                    t = time.perf_counter()
                    want = _brute(cols, q)
                    peer.append(time.perf_counter() - t)
                    same &= sorted(int(i["id"][1:]) for i in got) == want.tolist()
                    found += len(got)
                ms, peer_ms = 1e3 * np.array(times), 1e3 * np.array(peer)
                print(
                    f"search by {kind}: median {np.median(ms):.1f} ms, worst {ms.max():.1f} ms "
                    f"({found / DRAWS:.0f} entries a search; target <= {SEARCH_MS:g} ms: "
                    f"{'PASS' if ms.max() <= SEARCH_MS else 'FAIL'}); the brute-force filter "
                    f"{np.median(peer_ms):.1f} ms ({np.median(peer_ms) / np.median(ms):.1f}x); "
                    f"answers equal to it: {same}"
                )


if __name__ == "__main__":
    main()
