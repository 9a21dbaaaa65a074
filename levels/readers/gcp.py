"""Ground control points as users have them: a CSV file per pass (``docs/gcp.md``).

One row per point: its ``id``, its map position (``lon_deg``, ``lat_deg``, ellipsoidal
``h_m``, WGS84), where it was measured in the raw image (``line``, ``column``: 0-based,
integers at pixel centres, ``line`` the row of the pass's L0 archive, ``column`` the
detector), the 1σ of each (``sigma_ground_m`` per horizontal axis, ``sigma_h_m``,
``sigma_px`` per image axis) and the ``hrv`` that imaged it. Lines starting with ``#`` are
comments. :func:`read_gcps` checks everything before handing it over: a missing column, a
value that is not a number or not finite, a duplicate id, a point outside the image or a
σ that is not positive is a :class:`~levels.errors.GcpError` naming the row and the value.

An optional ``kind`` column says ``gcp`` (the default) or ``tie``: a tie point
(:mod:`levels.tiepoints`) was measured in several passes' images, under the same id in each
pass's file; its map position is only an approximation (its σ says how rough), which a
block adjustment solves.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass, fields
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from levels.errors import GcpError
from levels.files import atomic_path
from levels.readers.dem import EARTH_HEIGHTS_M

__all__ = ["GCP_COLUMNS", "ControlPointSet", "read_gcps", "write_gcps"]

#: The columns of a control-point file, in order (``docs/gcp.md``).
GCP_COLUMNS = (
    "id",
    "lon_deg",
    "lat_deg",
    "h_m",
    "line",
    "column",
    "sigma_ground_m",
    "sigma_h_m",
    "sigma_px",
    "hrv",
)
#: The largest σ a control point may claim (sigma_ground_m, sigma_h_m, sigma_px): beyond,
#: it weighs nothing and says nothing (a map position known to 100 km is no measurement).
SIGMA_CAPS = (100_000.0, 10_000.0, 10_000.0)


@dataclass(frozen=True, eq=False)
class ControlPointSet:
    """Control points of a pass; arrays of shape (N,), angles in radians (SI inside)."""

    id: tuple[str, ...]
    lon_rad: NDArray[np.float64]
    lat_rad: NDArray[np.float64]
    h_m: NDArray[np.float64]
    line: NDArray[np.float64]
    column: NDArray[np.float64]
    sigma_ground_m: NDArray[np.float64]
    sigma_h_m: NDArray[np.float64]
    sigma_px: NDArray[np.float64]
    hrv: NDArray[np.int64]
    #: Tie points (kind ``tie``), whose ground position is unknown, not control.
    tie: NDArray[np.bool_] | None = None

    def __post_init__(self) -> None:
        if self.tie is None:
            object.__setattr__(self, "tie", np.zeros(len(self.id), dtype=bool))

    def __len__(self) -> int:
        return len(self.id)

    def of_hrv(self, hrv: int) -> ControlPointSet:
        """The points imaged by one HRV."""
        return self._subset(self.hrv == hrv)

    def controls(self) -> ControlPointSet:
        """The control points alone (kind ``gcp``): what a single-pass adjustment uses."""
        assert self.tie is not None
        return self._subset(~self.tie)

    def ties(self) -> ControlPointSet:
        """The tie points alone (kind ``tie``): what a block adds to its passes' controls."""
        assert self.tie is not None
        return self._subset(self.tie)

    def __add__(self, other: ControlPointSet) -> ControlPointSet:
        """Both sets' points (a pass's control points and its tie points, read apart)."""
        clash = set(self.id) & set(other.id)
        if clash:
            raise GcpError(f"point id {sorted(clash)[0]!r} in both sets")
        return ControlPointSet(
            self.id + other.id,
            *(
                np.concatenate([getattr(self, f.name), getattr(other, f.name)])
                for f in fields(self)[1:]
            ),
        )

    def _subset(self, k: NDArray[np.bool_]) -> ControlPointSet:
        return ControlPointSet(
            tuple(i for i, keep in zip(self.id, k, strict=True) if keep),
            *(getattr(self, f.name)[k] for f in fields(self)[1:]),
        )


def _bad(where: Path, row: int, msg: str) -> GcpError:
    return GcpError(f"{where}: row {row}: {msg}")


def read_gcps(
    path: str | Path, n_lines: int | None = None, n_columns: int | None = None
) -> ControlPointSet:
    """Read and check a control-point file (module docstring); with the image's size,
    points outside it (beyond half a pixel of its edges) are refused too."""
    where = Path(path)
    try:
        text = where.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise GcpError(f"{where}: no such control-point file") from None
    except (UnicodeDecodeError, IsADirectoryError):
        raise GcpError(f"{where}: not a text (UTF-8) control-point file") from None
    lines = [ln for ln in text.splitlines() if ln.strip() and not ln.lstrip().startswith("#")]
    if not lines:
        raise GcpError(f"{where}: no header and no control point")
    reader = csv.DictReader(lines)
    header = [h.strip() for h in (reader.fieldnames or [])]
    missing = [c for c in GCP_COLUMNS if c not in header]
    if missing:
        raise GcpError(
            f"{where}: column {missing[0]!r} is missing; the header must name "
            f"{', '.join(GCP_COLUMNS)} (docs/gcp.md)"
        )
    cols: dict[str, list] = {c: [] for c in GCP_COLUMNS}
    kinds: list[bool] = []
    for k, raw in enumerate(reader, start=1):
        if None in raw:  # csv's restkey: the row has more fields than the header
            raise _bad(where, k, f"{len(header) + len(raw[None])} fields for {len(header)} columns")
        rec = {(key or "").strip(): (v or "").strip() for key, v in raw.items()}
        pid = rec["id"]
        if not pid:
            raise _bad(where, k, "empty id")
        if pid in cols["id"]:
            raise _bad(where, k, f"id {pid!r} given twice")
        cols["id"].append(pid)
        for c in GCP_COLUMNS[1:]:
            try:
                v = float(rec[c])
            except ValueError:
                raise _bad(where, k, f"{c} = {rec[c]!r} is not a number") from None
            if not math.isfinite(v):
                raise _bad(where, k, f"{c} = {rec[c]!r} is not finite")
            cols[c].append(v)
        lon, lat = cols["lon_deg"][-1], cols["lat_deg"][-1]
        if not (-180.0 <= lon <= 360.0 and -90.0 <= lat <= 90.0):
            raise _bad(where, k, f"lon_deg, lat_deg = {lon}, {lat}: not on the Earth")
        if min(cols["sigma_ground_m"][-1], cols["sigma_h_m"][-1], cols["sigma_px"][-1]) <= 0:
            raise _bad(
                where, k, "every sigma must be positive (a point known exactly cannot be weighted)"
            )
        sigmas = (cols[c][-1] for c in ("sigma_ground_m", "sigma_h_m", "sigma_px"))
        if any(v > cap for v, cap in zip(sigmas, SIGMA_CAPS, strict=True)):
            raise _bad(
                where,
                k,
                "a sigma beyond "
                + ", ".join(
                    f"{c} {cap:g}" for c, cap in zip(GCP_COLUMNS[6:9], SIGMA_CAPS, strict=True)
                )
                + ": that is no measurement",
            )
        h_lo, h_hi = EARTH_HEIGHTS_M
        if not h_lo <= cols["h_m"][-1] <= h_hi:
            raise _bad(
                where, k, f"h_m = {rec['h_m']!r}: not a height on Earth ({h_lo:g} to {h_hi:g} m)"
            )
        if cols["hrv"][-1] not in (1.0, 2.0):
            raise _bad(where, k, f"hrv = {rec['hrv']!r}: expected 1 or 2")
        kind = rec.get("kind", "") or "gcp"
        if kind not in ("gcp", "tie"):
            raise _bad(where, k, f"kind = {kind!r}: expected gcp or tie")
        kinds.append(kind == "tie")
        line, col = cols["line"][-1], cols["column"][-1]
        if (n_lines is not None and not -0.5 <= line <= n_lines - 0.5) or (
            n_columns is not None and not -0.5 <= col <= n_columns - 0.5
        ):
            raise _bad(
                where,
                k,
                f"line, column = {line}, {col}: outside the image of "
                f"{n_lines} lines × {n_columns} columns",
            )
    a = {c: np.asarray(cols[c], dtype=np.float64) for c in GCP_COLUMNS[1:]}
    return ControlPointSet(
        tuple(cols["id"]),
        np.radians(a["lon_deg"]),
        np.radians(a["lat_deg"]),
        a["h_m"],
        a["line"],
        a["column"],
        a["sigma_ground_m"],
        a["sigma_h_m"],
        a["sigma_px"],
        a["hrv"].astype(np.int64),
        np.array(kinds, dtype=bool),
    )


def write_gcps(path: str | Path, gcps: ControlPointSet, comment: str = "") -> Path:
    """Write a control-point file (module docstring) atomically; returns its path."""
    target = Path(path)
    rows = [f"# {ln}" for ln in comment.splitlines()] if comment else []
    assert gcps.tie is not None
    kinds = bool(gcps.tie.any())  # the kind column only where a tie point needs it
    rows.append(",".join(GCP_COLUMNS) + (",kind" if kinds else ""))
    for k, pid in enumerate(gcps.id):
        rows.append(
            ",".join(
                [
                    pid,
                    f"{np.degrees(gcps.lon_rad[k]):.9f}",
                    f"{np.degrees(gcps.lat_rad[k]):.9f}",
                    f"{gcps.h_m[k]:.3f}",
                    f"{gcps.line[k]:.3f}",
                    f"{gcps.column[k]:.3f}",
                    f"{gcps.sigma_ground_m[k]:g}",
                    f"{gcps.sigma_h_m[k]:g}",
                    f"{gcps.sigma_px[k]:g}",
                    str(int(gcps.hrv[k])),
                    *(["tie" if gcps.tie[k] else "gcp"] if kinds else []),
                ]
            )
        )
    with atomic_path(target) as tmp:
        tmp.write_text("\n".join(rows) + "\n", encoding="utf-8")
    return target
