"""Synthetic STAC Items for the archive catalogue's tests and benchmark."""

from __future__ import annotations

import time

import numpy as np

__all__ = ["synthetic"]


def synthetic(n: int, seed: int, prefix: str = "syn") -> list[dict]:
    """``n`` Items on random footprints (some across the antimeridian) and dates."""
    rng = np.random.default_rng(seed)
    lon = rng.uniform(-180, 180, n)
    lat = rng.uniform(-80, 80, n)
    t = rng.uniform(5e8, 1.3e9, n)  # 1985–2011
    out = []
    for i in range(n):
        w, e = lon[i] - 0.3, lon[i] + 0.3
        w, e = (w + 540) % 360 - 180, (e + 540) % 360 - 180
        when = time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime(t[i]))
        out.append({
            "type": "Feature", "stac_version": "1.1.0", "stac_extensions": [],
            "id": f"{prefix}{i:06d}", "collection": "spot-l1a",
            "geometry": None, "bbox": [w, lat[i] - 0.3, e, lat[i] + 0.3],
            "properties": {"datetime": when, "processing:level": "L1A",
                           "platform": "spot-2", "spot:k": int(i % 738) + 1,
                           "spot:j": int(200 + i % 300)},
            "links": [], "assets": {},
        })  # fmt: skip
    return out
