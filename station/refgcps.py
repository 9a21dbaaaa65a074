"""Control points of a recorded pass (an L0 archive or a DIMAP 1A scene) found on a
reference ortho-image: ``station gcps`` (:mod:`levels.reference` does the finding).

:func:`gcps_from_reference` reads the archive, makes GEO's scenes on the system model, the
raw image of each (calibrated: the 1A's values, NaN where not valid), reads the reference
(its stated accuracy the CE95 the user gives, or its truth file's beside it when the
emulator wrote it) and the DEM, finds the points and writes them (``docs/gcp.md``, kind
``reference``); with the scenario that made the archive, each point is also scored
against the truth: where its raw pixel truly looks, against the ground it was given.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from levels.options import ProcessingOptions
from levels.readers.gcp import ControlPointSet
from levels.reference import KEEP_SIGMAS, ReferencePoints

if TYPE_CHECKING:
    from station.scenario import Scenario
    from station.truth.optical import Truth

__all__ = [
    "KEEP_SIGMAS",
    "gcps_from_reference",
    "point_errors_en",
    "points_source",
    "record_found",
    "reference_sigma_m",
]


def reference_sigma_m(path: str | Path, ce95_m: float | None) -> float:
    """The reference's stated accuracy (1σ per axis, m): from ``ce95_m``, else from the
    emulator's truth file beside it (``<stem>.json``), else 0 (exact)."""
    from station.spacecraft.reference import CE95_PER_SIGMA

    if ce95_m is not None:
        return float(ce95_m) / CE95_PER_SIGMA
    truth = Path(path).with_suffix(".json")
    try:
        return float(json.loads(truth.read_text(encoding="utf-8"))["error_ce95_m"]) / CE95_PER_SIGMA
    except (OSError, ValueError, KeyError):
        return 0.0


#: How the file of the points found for a pass begins (its first comment).
_FOUND = "control points of"


def points_source(path: Path) -> str | None:
    """The pass whose points found on a reference a control-point file holds (its first
    comment, as :func:`gcps_from_reference` writes it); None for any other file."""
    with open(path, encoding="utf-8") as f:
        first = f.readline(1000)
    words = first.removeprefix("# ").split()
    if not first.startswith(f"# {_FOUND} ") or "found" not in words:
        return None
    return words[len(_FOUND.split())]


def gcps_from_reference(
    source: str | Path,
    reference: str | Path,
    dem_path: str | Path,
    out: str | Path,
    *,
    options: ProcessingOptions | None = None,
    ce95_m: float | None = None,
    scenario: Scenario | None = None,
    truth: Truth | None = None,
) -> tuple[ReferencePoints, dict[str, object]]:
    """Find, write and (with ``scenario``, or the run's ``truth`` of the archive) score the
    pass's control points (module docstring); returns them and the summary the command
    prints (and the run reports)."""
    from levels.process import geo_pass
    from levels.readers.dem import read_dem
    from levels.readers.formats import open_archive
    from levels.reference import ReferenceInput, find_on_reference, read_reference

    archive = open_archive(source)
    opts = options or ProcessingOptions()
    setup = geo_pass(archive, opts)
    ref = read_reference(reference, reference_sigma_m(reference, ce95_m))
    given = ReferenceInput(ref, read_dem(dem_path, opts.dem_vertical))
    found = find_on_reference(archive, setup.pg, setup.scenes, given, opts)
    if truth is None and scenario is not None:
        from station.truth.optical import truth_for

        truth = truth_for(scenario, archive)
    return found, record_found(source, reference, out, found, ref.sigma_m, truth)


def record_found(
    source: str | Path,
    reference: str | Path,
    out: str | Path,
    found: ReferencePoints,
    sigma_m: float,
    truth: Truth | None = None,
) -> dict[str, object]:
    """The points found on a reference written to ``out`` (``docs/gcp.md``, kind
    ``reference``), and what finding them did: the reference, its stated σ, each loop, the
    adjustment's summary and, with the archive's ``truth``, the points scored against it."""
    from levels.readers.gcp import write_gcps

    write_gcps(
        out,
        found.points,
        f"{_FOUND} {Path(source).name} found on {Path(reference).name} "
        f"(levels.reference; docs/gcp.md)",
    )
    summary: dict[str, object] = {
        "source": str(source),
        "reference": str(reference),
        "out": str(out),
        "points": len(found.points),
        "reference_sigma_m": sigma_m,
        "loops": found.loops,
        "adjustment": found.adjustment.summary() if found.adjustment is not None else {},
    }
    if truth is not None:
        summary["truth"] = _scored(truth, found, _reference_bias_m(reference))
    return summary


def _reference_bias_m(path: str | Path) -> tuple[float, float] | None:
    """The reference's true bias (east, north; m) from the emulator's truth beside it."""
    try:
        t = json.loads(Path(path).with_suffix(".json").read_text(encoding="utf-8"))
        return float(t["bias_east_m"]), float(t["bias_north_m"])
    except (OSError, ValueError, KeyError):
        return None


def point_errors_en(truth: Truth, points: ControlPointSet) -> NDArray[np.float64]:
    """Each point's ground less where its raw pixel truly looks on the terrain (``truth``:
    :class:`station.truth.optical.Truth` of the archive), east and north (m), (N, 2); NaN
    where the pixel's ray missed."""
    from levels.geometry.ellipsoid import WGS84
    from levels.geometry.frames import apply, enu_from_ecef

    g = points
    true = truth.ground(0, g.line + truth.row_offset, g.column)
    lat, lon, _ = WGS84.to_geodetic(true)
    enu = apply(enu_from_ecef(lat, lon), WGS84.to_ecef(g.lat_rad, g.lon_rad, g.h_m) - true)
    return np.asarray(enu[:, :2])


def _scored(
    truth: Truth, found: ReferencePoints, bias: tuple[float, float] | None
) -> dict[str, float]:
    """Each point's ground against where its raw pixel truly looks (east, north, m); with
    the reference's true ``bias``, also against it: what the matching alone missed."""
    en = point_errors_en(truth, found.points)
    ok = np.isfinite(en).all(axis=1)
    e, n = en[ok, 0], en[ok, 1]
    out = {
        "points": int(ok.sum()),
        "mean_east_m": float(e.mean()),
        "mean_north_m": float(n.mean()),
        "rms_m": float(np.sqrt(np.mean(e**2 + n**2))),
        "median_m": float(np.median(np.hypot(e, n))),
    }
    if bias is not None:  # the reference shows the ground at (x, y) + bias at (x, y)
        de, dn = e + bias[0], n + bias[1]
        out |= {
            "reference_bias_east_m": bias[0],
            "reference_bias_north_m": bias[1],
            "rms_of_matching_m": float(np.sqrt(np.mean(de**2 + dn**2))),
        }
    return out
