"""Ground control points as users have them: a CSV file per pass (``docs/gcp.md``).

One row per point: its ``id``, its map position (``lon_deg``, ``lat_deg``, ellipsoidal
``h_m``, WGS84), where it was measured in the raw image (``line``, ``column``: 0-based,
integers at pixel centres, ``line`` the row of the pass's L0 archive, ``column`` the
detector), the 1σ of each (``sigma_ground_m`` per horizontal axis, ``sigma_h_m``,
``sigma_px`` per image axis) and the ``hrv`` that imaged it. Lines starting with ``#`` are
comments. :func:`read_gcps` checks everything before handing it over: a missing column, a
value that is not a number or not finite, a duplicate id, a point outside the image or a
σ that is not positive is a :class:`~levels.errors.GcpError` naming the row and the value.

An optional ``kind`` column says ``gcp`` (the default), ``tie`` or ``reference``: a tie
point (:mod:`levels.tiepoints`) was measured in several passes' images, under the same id
in each pass's file; its map position is only an approximation (its σ says how rough),
which a block adjustment solves. A ``reference`` point is a control point found on a
reference ortho-image (:mod:`levels.reference`): used as any control point, said apart.

A file inside a zip is named as GDAL names it, the zip a folder: ``scene.zip/control_points
.csv`` (the points of a DIMAP pack's zip, ``station export --dimap X.zip``), read in place.
"""

from __future__ import annotations

import csv
import dataclasses
import math
import zipfile
from dataclasses import dataclass, fields
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from levels.errors import GcpError
from levels.files import atomic_path
from levels.readers.bounded import MAX_TABLE_BYTES, read_capped, read_member
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
    #: Control points found on a reference ortho-image (kind ``reference``).
    reference: NDArray[np.bool_] | None = None

    def __post_init__(self) -> None:
        for name in ("tie", "reference"):
            if getattr(self, name) is None:
                object.__setattr__(self, name, np.zeros(len(self.id), dtype=bool))

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

    def as_recorded(self) -> ControlPointSet:
        """The points as their file records them (:func:`write_gcps`: 1e-9° on the ground,
        1 mm in height, 0.001 px in the image, six digits of σ), so that points handed on
        in memory are the numbers a reprocessing reads from the file."""

        def kept(values: NDArray[np.float64], spec: str) -> NDArray[np.float64]:
            return np.array([float(format(v, spec)) for v in values], dtype=np.float64)

        return dataclasses.replace(
            self,
            lon_rad=np.radians(kept(np.degrees(self.lon_rad), ".9f")),
            lat_rad=np.radians(kept(np.degrees(self.lat_rad), ".9f")),
            h_m=kept(self.h_m, ".3f"),
            line=kept(self.line, ".3f"),
            column=kept(self.column, ".3f"),
            sigma_ground_m=kept(self.sigma_ground_m, "g"),
            sigma_h_m=kept(self.sigma_h_m, "g"),
            sigma_px=kept(self.sigma_px, "g"),
        )

    def _subset(self, k: NDArray[np.bool_]) -> ControlPointSet:
        return ControlPointSet(
            tuple(i for i, keep in zip(self.id, k, strict=True) if keep),
            *(getattr(self, f.name)[k] for f in fields(self)[1:]),
        )


def _bad(where: Path, line: int, msg: str) -> GcpError:
    return GcpError(f"{where}: line {line}: {msg}")


def _rows(where: Path) -> tuple[list[str], list[tuple[int, dict[str, str]]]]:
    """The file's header and its rows, each with its line number in the file (comments
    and blank lines skipped; a UTF-8 byte-order mark, as spreadsheets write it, ignored)."""
    try:
        if zipfile.is_zipfile(where.parent) and not where.parent.is_dir():  # a zip's member
            data = read_member(
                where.parent, where.name, MAX_TABLE_BYTES, "control-point file", GcpError
            )
        else:
            data = read_capped(where, MAX_TABLE_BYTES, "control-point file", GcpError)
        text = data.decode("utf-8-sig")
    except KeyError:
        raise GcpError(f"{where}: no such member in the zip") from None
    except FileNotFoundError:
        raise GcpError(f"{where}: no such control-point file") from None
    except (UnicodeDecodeError, IsADirectoryError):
        raise GcpError(f"{where}: not a text (UTF-8) control-point file") from None
    numbered = [
        (k, ln)
        for k, ln in enumerate(text.splitlines(), start=1)
        if ln.strip() and not ln.lstrip().startswith("#")
    ]
    if not numbered:
        raise GcpError(f"{where}: no header and no control point")
    # each line parsed alone: a point is one line (a quote opened on one would swallow
    # the next lines as one field, and the rows lose their line numbers)
    parsed = csv.reader([ln for _, ln in numbered])
    header = [h.strip() for h in next(parsed)]
    missing = [c for c in GCP_COLUMNS if c not in header]
    if missing:
        raise GcpError(
            f"{where}: column {missing[0]!r} is missing; the header must name "
            f"{', '.join(GCP_COLUMNS)} (docs/gcp.md)"
        )
    rows = []
    for line, text_line in numbered[1:]:
        fields_ = next(csv.reader([text_line]), [])
        if len(fields_) > len(header):
            raise _bad(where, line, f"{len(fields_)} fields for {len(header)} columns")
        values = [v.strip() for v in fields_] + [""] * (len(header) - len(fields_))
        rows.append((line, dict(zip(header, values, strict=True))))
    return header, rows


def _point(where: Path, k: int, rec: dict[str, str]) -> dict[str, float]:
    """One row's numbers, each checked: finite, on the Earth, its σ positive and within
    what a measurement is, its HRV 1 or 2."""
    v: dict[str, float] = {}
    for c in GCP_COLUMNS[1:]:
        try:
            v[c] = float(rec[c])
        except ValueError:
            raise _bad(where, k, f"{c} = {rec[c]!r} is not a number") from None
        if not math.isfinite(v[c]):
            raise _bad(where, k, f"{c} = {rec[c]!r} is not finite")
    if not (-180.0 <= v["lon_deg"] <= 360.0 and -90.0 <= v["lat_deg"] <= 90.0):
        raise _bad(where, k, f"lon_deg, lat_deg = {v['lon_deg']}, {v['lat_deg']}: not on the Earth")
    sigmas = [v[c] for c in ("sigma_ground_m", "sigma_h_m", "sigma_px")]
    if min(sigmas) <= 0:
        raise _bad(
            where, k, "every sigma must be positive (a point known exactly cannot be weighted)"
        )
    if any(s > cap for s, cap in zip(sigmas, SIGMA_CAPS, strict=True)):
        caps = zip(GCP_COLUMNS[6:9], SIGMA_CAPS, strict=True)
        limits = ", ".join(f"{c} {cap:g}" for c, cap in caps)
        raise _bad(where, k, f"a sigma beyond {limits}: that is no measurement")
    h_lo, h_hi = EARTH_HEIGHTS_M
    if not h_lo <= v["h_m"] <= h_hi:
        raise _bad(
            where, k, f"h_m = {rec['h_m']!r}: not a height on Earth ({h_lo:g} to {h_hi:g} m)"
        )
    if v["hrv"] not in (1.0, 2.0):
        raise _bad(where, k, f"hrv = {rec['hrv']!r}: expected 1 or 2")
    return v


def read_gcps(
    path: str | Path, n_lines: int | None = None, n_columns: int | None = None
) -> ControlPointSet:
    """Read and check a control-point file (module docstring); with the image's size,
    points outside it (beyond half a pixel of its edges) are refused too. A refusal names
    the file's line."""
    where = Path(path)
    _, rows = _rows(where)
    ids: list[str] = []
    seen: set[str] = set()  # membership in a set: a list made 10⁶ rows quadratic
    values: list[dict[str, float]] = []
    kinds: list[str] = []
    for k, rec in rows:
        pid = rec["id"]
        if not pid:
            raise _bad(where, k, "empty id")
        if pid in seen:
            raise _bad(where, k, f"id {pid!r} given twice")
        seen.add(pid)
        v = _point(where, k, rec)
        kind = rec.get("kind", "") or "gcp"
        if kind not in ("gcp", "tie", "reference"):
            raise _bad(where, k, f"kind = {kind!r}: expected gcp, tie or reference")
        line, col = v["line"], v["column"]
        if (n_lines is not None and not -0.5 <= line <= n_lines - 0.5) or (
            n_columns is not None and not -0.5 <= col <= n_columns - 0.5
        ):
            raise _bad(
                where,
                k,
                f"line, column = {line}, {col}: outside the image of "
                f"{n_lines} lines × {n_columns} columns",
            )
        ids.append(pid)
        values.append(v)
        kinds.append(kind)
    a = {c: np.asarray([v[c] for v in values], dtype=np.float64) for c in GCP_COLUMNS[1:]}
    return ControlPointSet(
        tuple(ids),
        np.radians(a["lon_deg"]),
        np.radians(a["lat_deg"]),
        a["h_m"],
        a["line"],
        a["column"],
        a["sigma_ground_m"],
        a["sigma_h_m"],
        a["sigma_px"],
        a["hrv"].astype(np.int64),
        np.array([k == "tie" for k in kinds], dtype=bool),
        np.array([k == "reference" for k in kinds], dtype=bool),
    )


def _kind(gcps: ControlPointSet, k: int) -> str:
    assert gcps.tie is not None and gcps.reference is not None
    return "tie" if gcps.tie[k] else "reference" if gcps.reference[k] else "gcp"


def write_gcps(path: str | Path, gcps: ControlPointSet, comment: str = "") -> Path:
    """Write a control-point file (module docstring) atomically; returns its path."""
    target = Path(path)
    rows = [f"# {ln}" for ln in comment.splitlines()] if comment else []
    assert gcps.tie is not None and gcps.reference is not None
    kinds = bool(gcps.tie.any() or gcps.reference.any())  # the column only where needed
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
                    *([_kind(gcps, k)] if kinds else []),
                ]
            )
        )
    with atomic_path(target) as tmp:
        tmp.write_text("\n".join(rows) + "\n", encoding="utf-8")
    return target
