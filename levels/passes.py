"""GEO's set-up of a pass before its scene tasks: the pass geometry (its ephemeris,
attitude and look angles, :func:`levels.geo.scenes.pass_geometry`), the scenes GEO can
place and those it skips (lost in the downlink, too few lines, not placeable), a twin
pass's platform records, the archives of a block grouped by pass, the nominal pixel.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from levels.errors import GeometryError
from levels.geo.scenes import PassGeometry, SceneCut, SceneGeometry, cut_scenes, pass_geometry
from levels.geometry.sensor import LookAngleTable
from levels.options import ProcessingOptions
from levels.readers.l0 import L0Archive
from levels.spot import ORBIT_ALTITUDE_M
from levels.threads import one_blas_thread

__all__ = [
    "PassSetup",
    "SkippedScene",
    "geo_pass",
    "nominal_pixel_size_m",
    "passes_of",
    "platform_records",
]


@dataclass(frozen=True)
class SkippedScene:
    """A scene of the pass that could not be made, and why (lost in the downlink, or GEO
    could not place it: no attitude or ephemeris over it)."""

    index: int
    first_line: int
    n_lines: int
    reason: str


def nominal_pixel_size_m(look: LookAngleTable) -> float:
    """The nominal output pixel: the look table's angular pitch at 822 km, to 10 m (10 m
    for P, 20 m for XS, and proportionally more for a reduced detector count)."""
    # per detector: a table of each, or of the first and last (a DIMAP's)
    pitch = float(np.median(np.abs(np.diff(look.psi_y_rad) / np.diff(look.column))))
    return max(10.0, 10.0 * round(pitch * ORBIT_ALTITUDE_M / 10.0))


@dataclass(frozen=True, eq=False)
class PassSetup:
    """GEO of one HRV's pass: the pass set-up, the scenes it can place and those it skips."""

    archive: L0Archive
    pg: PassGeometry
    scenes: list[SceneGeometry]
    skipped: list[SkippedScene]
    scene_lines: int
    time_s: float


def platform_records(
    archives: Sequence[L0Archive],
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The platform's gyro records of a pass imaged by several HRVs: every record any HRV's
    channel brought (each carries the same platform data; a record lost on one channel may
    have come through the other). Times and rates, unsorted (GEO sorts and deduplicates)."""
    first = archives[0]
    for a in archives[1:]:
        if a.epoch != first.epoch:
            raise GeometryError(
                f"{a.path} and {first.path} count time from different epochs: not the same pass"
            )
    return (
        np.concatenate([a.aux_t_s for a in archives]),
        np.concatenate([a.gyro_rates_rad_per_s for a in archives]),
    )


@one_blas_thread
def geo_pass(
    archive: L0Archive,
    options: ProcessingOptions,
    records: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None,
) -> PassSetup:
    """GEO's set-up of a pass and its scenes (``records``: the platform's gyro records,
    by default the archive's own; :func:`platform_records` for a twin pass)."""
    t0 = time.perf_counter()
    band_names = list(archive.bands)
    gyro_t, gyro = records or (archive.aux_t_s, archive.gyro_rates_rad_per_s)
    pg = pass_geometry(
        archive.epoch,
        archive.line_t_s,
        archive.line_period_s,
        archive.ephemeris,
        gyro_t,
        gyro,
        {b: archive.bands[b].look for b in band_names},
    )
    n_det = archive.bands[band_names[0]].counts.shape[1]
    scene_lines = options.scene_lines or n_det
    cuts = cut_scenes(archive.n_lines, scene_lines, options.overlap_lines, partial=True)
    # a row is seen when one of its segments arrived (every segment has detectors)
    rows_seen = np.logical_or.reduce([archive.bands[b].valid.any(axis=1) for b in band_names])
    scenes, skipped = [], []
    for c in cuts:
        reason = _too_few_lines(c, rows_seen, min(scene_lines, archive.n_lines), options)
        if reason:
            skipped.append(SkippedScene(c.index, c.first_line, c.n_lines, reason))
            continue
        try:
            scenes.append(pg.scene(c, options.reference_height_m))
        except GeometryError as exc:
            skipped.append(
                SkippedScene(c.index, c.first_line, c.n_lines, f"GEO could not place it: {exc}")
            )
    return PassSetup(archive, pg, scenes, skipped, scene_lines, time.perf_counter() - t0)


def _too_few_lines(
    cut: SceneCut, rows_seen: NDArray[np.bool_], whole: int, options: ProcessingOptions
) -> str:
    """Why scene ``cut`` is not made, or "": no line of it arrived, or fewer than
    ``options.min_valid_share`` of a ``whole`` scene's lines (a partial last scene's
    missing lines count as not arrived)."""
    seen = int(np.count_nonzero(rows_seen[cut.first_line : cut.first_line + cut.n_lines]))
    if not seen:
        return "no valid line: lost in the downlink"
    share = seen / whole
    if share >= options.min_valid_share:
        return ""
    what = (
        f"a partial last scene of {cut.n_lines} lines, {seen} valid"
        if cut.n_lines < whole
        else f"{seen} valid lines of {cut.n_lines}"
    )
    return (
        f"{what}: {share:.1%} of a scene's {whole} lines, below [processing] "
        f"min_valid_share = {options.min_valid_share:g}"
    )


def passes_of(archives: Sequence[L0Archive]) -> list[list[int]]:
    """The archives of a block grouped by pass: those counting time from one epoch are the
    HRVs of one pass (a twin pass, :func:`platform_records`), in the order given; an HRV
    twice in one pass is refused."""
    groups: dict[Any, list[int]] = {}
    for k, a in enumerate(archives):
        groups.setdefault(a.epoch, []).append(k)
    for group in groups.values():
        hrvs = [archives[k].hrv for k in group]
        if len(set(hrvs)) != len(hrvs):
            raise GeometryError(
                f"{', '.join(str(archives[k].path) for k in group)}: one pass (one epoch) "
                f"with HRVs {hrvs}: one archive per HRV of a pass"
            )
    return list(groups.values())
