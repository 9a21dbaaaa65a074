"""SPOT's Grid Reference System (GRS): the (K, J) node a scene is catalogued and ordered by.

The GRS (SPOT Image, *SPOT User's Handbook*; the grid's public description) is derived from
the orbit's 26-day cycle of 369 daylight ground tracks, numbered eastward and evenly spaced
at the equator (360°/369). Each track N gives two columns, K = 2N − 1 to its west and
K = 2N to its east (the HRVs' twin scenes). The rows J are numbered southward along the
descending track at equal arcs of the orbit: J = 350 is said to be the equator, and rows
200 and 500 are at latitudes ±71.42907°. That fixes the row's arc,
Δu = asin(sin 71.42907° / sin i) / 150 = 0.4902°. A point at latitude φ is at
u = asin(sin φ / sin i) of arc from the descending node (north positive). It lies on the
descending track whose node is Δλ(u) west of it (the track's own curve and the Earth's
rotation during the arc, the orbit sun-synchronous: 360° a solar day relative to the
node).

Two constants the public description does not give are taken from real SPOT scenes
(``refdata/dimap``). One is the node longitude of track 1. The other is the row of the
descending node: the scenes sit 2.3 rows south of what "J = 350 at the equator" makes of
them, the same 2.3 at every one of the four, so it is an origin, not an error of the
model's shape. The column's offset from its track is kept at a constant ground distance.
Both are fitted on the Izmit scene (SPOT 2, 1998, K/J 104/267, shift 7). The three others
(SPOT 4 near Montpellier, SPOT 4 and SPOT 5 over the Altai) are checked against their
``GRID_REFERENCE`` in ``tests/test_grs.py``: their K exact and their row within 0.15 of a
row (J plus the shift's tenths).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["kj_of"]

INCLINATION_DEG = 98.7
TRACKS, CYCLE_DAYS = 369, 26
TRACK_SPACING_DEG = 360.0 / TRACKS
J_EDGE, LAT_EDGE_DEG = 200, 71.42907  # the grid's northern row and its latitude
_SIN_I = np.sin(np.radians(INCLINATION_DEG))
#: The orbit's arc from one row to the next (degrees of argument of latitude).
ROW_ARC_DEG = float(np.degrees(np.arcsin(np.sin(np.radians(LAT_EDGE_DEG)) / _SIN_I))) / 150.0
#: Fitted on the Izmit scene (module docstring): the descending node's row, track 1's node
#: longitude (degrees east), and a column's offset from its track in longitude at the
#: equator (a constant ground distance: it grows as 1/cos φ).
NODE_ROW = 352.30
TRACK1_NODE_LON_DEG = 330.386
COLUMN_OFFSET_DEG = 0.145


def _node_offset_deg(u_rad: NDArray[np.float64]) -> NDArray[np.float64]:
    """Longitude of the descending track at arc ``u`` from its node (north positive),
    less the node's longitude."""
    v = np.pi - u_rad  # the argument of latitude from the ascending node
    cos_i = np.cos(np.radians(INCLINATION_DEG))
    along = np.degrees(np.arctan2(cos_i * np.sin(v), np.cos(v))) - 180.0
    return along - np.degrees(v - np.pi) * CYCLE_DAYS / TRACKS


def kj_of(
    lat_deg: ArrayLike, lon_deg: ArrayLike
) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.float64]]:
    """The GRS column K and row J of points (a scene's centre), and the row as a real
    number (J and the shift's tenths: SPOT's ``GRID_REFERENCE`` and ``SHIFT_VALUE``)."""
    lat = np.radians(np.asarray(lat_deg, np.float64))
    lon = np.asarray(lon_deg, np.float64)
    u = np.arcsin(np.clip(np.sin(lat) / _SIN_I, -1.0, 1.0))
    node_lon = lon - _node_offset_deg(u)
    x = np.mod(node_lon - TRACK1_NODE_LON_DEG, 360.0) / TRACK_SPACING_DEG
    track = np.rint(x)  # the nearest track, 0-based
    east = x - track >= 0.0
    n = np.mod(track, TRACKS).astype(np.int64) + 1
    k = np.where(east, 2 * n, 2 * n - 1)
    row = NODE_ROW - np.degrees(u) / ROW_ARC_DEG
    return k, np.floor(row + 1e-9).astype(np.int64), row
