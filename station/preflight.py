"""Everything a run or a reprocessing needs, checked before any work starts.

A run that would fail on its input after minutes of emulation fails here, in a second,
with one line: the files the scenario names (its TLE, its world's SRTM tile, the DEM level 3
is given: readable, with a CRS, heights of this planet), what the levels asked need (level
3 a DEM), and the memory and disk the run will take against what the machine has.

The figures are measured, not guessed (``docs/reliability.md``): a full P pass of 6000
detectors × 6000 lines peaks at 1.63 GB resident (300 MB of interpreter, libraries and
compiled kernels, then about 37 bytes per pixel of the pass: the rendered radiances, the
counts, the frames, the L0 archive read back); a pass of 3000 × 12 000 at 1.59 GB. On disk,
an L0 archive takes under 1 byte per pixel and a product under 2 (its uint8 image and mask,
compressed): the bounds below.
"""

from __future__ import annotations

import logging
import os
import shutil
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, TypedDict

from station.errors import StationError
from station.scenario import Scenario

if TYPE_CHECKING:
    from levels.geometry.dem import Dem

_log = logging.getLogger(__name__)

__all__ = [
    "DISK_L0_BYTES_PER_PIXEL",
    "DISK_PRODUCT_BYTES_PER_PIXEL",
    "MEMORY_BASE_BYTES",
    "MEMORY_BYTES_PER_OUTPUT_PIXEL",
    "MEMORY_BYTES_PER_PIXEL",
    "OUTPUT_GRID_SHARE",
    "Checked",
    "Needs",
    "available_memory_bytes",
    "check_needs",
    "check_scenario",
    "frame_needs",
    "output_pixels",
    "run_needs",
    "scene_needs",
]

#: Resident memory before any pixel: interpreter, numpy, scipy, numba's kernels (bytes).
MEMORY_BASE_BYTES = 300e6
#: Peak resident memory per pixel of a pass (all bands): 37 measured, with margin.
MEMORY_BYTES_PER_PIXEL = 40.0
#: Peak resident memory per pixel of a scene's largest output grid (bytes): 5.4 measured
#: (small_test at 8 m pixels: a 2A of 8503 × 9006, 412 MB above the run at its 200 m), with
#: margin; what a fine ``pixel_size_m`` costs beyond the pass itself.
MEMORY_BYTES_PER_OUTPUT_PIXEL = 8.0
#: A map grid's pixels over its scene's at the same pixel size: the north-up box around the
#: rotated, skewed scene (small_test's 2A: 341 × 361 over 300 × 300, 1.37), with margin.
OUTPUT_GRID_SHARE = 1.6
#: Disk per pixel: an L0 archive's counts and masks; a product's uint8 image and mask.
DISK_L0_BYTES_PER_PIXEL = 1.0
DISK_PRODUCT_BYTES_PER_PIXEL = 2.0


@dataclass(frozen=True)
class Needs:
    """What a job will take: ``pixels`` of the pass (every band), peak ``memory_bytes``
    and ``disk_bytes`` written; ``what`` says it in words for a message."""

    pixels: float
    memory_bytes: float
    disk_bytes: float
    what: str
    advice: str = "make the pass smaller (n_lines, detector_count) or use fewer --workers"


def output_pixels(scene_pixels: float, native_pixel_m: float, pixel_size_m: float) -> float:
    """The pixels of a scene's map grid: its own at the native pixel, times
    :data:`OUTPUT_GRID_SHARE`, times the square of native over asked (``pixel_size_m`` 0:
    the native pixel)."""
    ratio = native_pixel_m / pixel_size_m if pixel_size_m > 0 else 1.0
    return scene_pixels * OUTPUT_GRID_SHARE * ratio * ratio


def run_needs(scn: Scenario) -> Needs:
    """A scenario's run: every HRV's pass rendered at once, its L0 archive and products."""
    from levels.spot import MODES

    pixels = out_pixels = largest_out = 0.0
    parts = []
    opts = scn.processing
    for ins in scn.instruments:
        mode = MODES[ins.mode]
        n = ins.n_detectors or mode.detectors
        n_det = ins.detector_count or (n - ins.first_detector)
        n_lines = ins.n_lines or n  # build_hrv: one square scene
        bands = len(mode.bands)
        pixels += float(n_lines) * n_det * bands
        native_m = mode.pixel_size_m * mode.detectors / n  # a reduced scene's wider IFOV
        scene_lines = min(n_lines, opts.scene_lines or n)
        out_pixels += output_pixels(float(n_lines) * n_det * bands, native_m, opts.pixel_size_m)
        largest_out = max(
            largest_out, output_pixels(float(scene_lines) * n_det, native_m, opts.pixel_size_m)
        )
        parts.append(f"{n_lines} lines × {n_det} detectors × {bands} band(s)")
    if opts.pixel_size_m:
        parts.append(f"map grids of {opts.pixel_size_m:g} m pixels, {largest_out:.3g} a scene")
    n_levels = len(opts.levels)
    return Needs(
        pixels,
        MEMORY_BASE_BYTES
        + MEMORY_BYTES_PER_PIXEL * pixels
        + MEMORY_BYTES_PER_OUTPUT_PIXEL * largest_out,
        pixels * DISK_L0_BYTES_PER_PIXEL
        + max(out_pixels, pixels) * DISK_PRODUCT_BYTES_PER_PIXEL * n_levels,
        " + ".join(parts),
        "make the pass smaller (n_lines, detector_count), its pixels larger (pixel_size_m) "
        "or use fewer --workers",
    )


def scene_needs(
    n_lines: int,
    n_columns: int,
    n_bands: int,
    n_levels: int,
    n_scenes: int,
    workers: int,
    native_pixel_m: float = 10.0,
    pixel_size_m: float = 0.0,
) -> Needs:
    """A reprocessing: ``workers`` scenes of ``n_lines × n_columns × n_bands`` at once in
    memory, each with its largest map grid (:func:`output_pixels` at ``pixel_size_m``),
    ``n_scenes`` scenes of ``n_levels`` products on disk."""
    per_scene = float(n_lines) * n_columns * n_bands
    out = output_pixels(float(n_lines) * n_columns, native_pixel_m, pixel_size_m)
    grids = f", map grids of {pixel_size_m:g} m pixels" if pixel_size_m else ""
    return Needs(
        per_scene * n_scenes,
        MEMORY_BASE_BYTES
        + (MEMORY_BYTES_PER_PIXEL * per_scene + MEMORY_BYTES_PER_OUTPUT_PIXEL * out)
        * max(1, workers),
        max(per_scene, out * n_bands) * n_scenes * n_levels * DISK_PRODUCT_BYTES_PER_PIXEL,
        f"{max(1, workers)} scene(s) of {n_lines} lines × {n_columns} columns × "
        f"{n_bands} band(s) at once{grids}",
        "process fewer scenes at once (--workers), fewer levels, larger pixels "
        "(pixel_size_m), or on a machine with more memory",
    )


#: Peak resident memory per pixel of a SAR frame's map grid (bytes): 20 measured (a 2000 ×
#: 2000 frame's GEC on 2388 × 3606 pixels: 391 MB, against 225 MB for 400 × 400), with margin.
MEMORY_BYTES_PER_FRAME_PIXEL = 32.0


def frame_needs(grid_pixels: float, frame_pixels: float, n_levels: int) -> Needs:
    """A SAR frame's processing: its detected image in memory and its map grid's pixels
    (every kind on the one grid), each kind's product on disk."""
    return Needs(
        grid_pixels,
        MEMORY_BASE_BYTES
        + MEMORY_BYTES_PER_FRAME_PIXEL * grid_pixels
        + MEMORY_BYTES_PER_PIXEL * frame_pixels,
        grid_pixels * n_levels * 4 * DISK_PRODUCT_BYTES_PER_PIXEL,  # float32 bands
        f"a frame of {frame_pixels / 1e6:.2g} Mpx on a grid of {grid_pixels / 1e6:.3g} Mpx",
        "ask for a larger pixel (--scenario's [sar] pixel_size_m) or a smaller frame",
    )


def available_memory_bytes() -> float | None:
    """Memory this machine can give a new job now (Linux's ``MemAvailable``), or None
    where it is not known."""
    try:
        with open("/proc/meminfo", encoding="ascii") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return float(line.split()[1]) * 1024.0
    except OSError:
        pass
    return None


class Checked(TypedDict, total=False):
    """What a check before work found (``--check`` prints it): the files or archives it
    read, the pixels a run makes, the memory and disk the job takes and the machine has
    (bytes; None where the machine does not say)."""

    files: list[str]
    archives: list[str]
    frame: str
    pixels: float
    memory_bytes: float
    memory_available_bytes: float | None
    disk_bytes: float
    disk_free_bytes: float | None


def check_needs(needs: Needs, out: Path) -> Checked:
    """:class:`StationError` when the job will not fit the machine's available memory, or
    ``out``'s nearest existing directory cannot be written or lacks the disk (a staged
    output and the previous one coexist until the swap); returns the figures checked."""
    memory = available_memory_bytes()
    if memory is not None and needs.memory_bytes > memory:
        raise StationError(
            f"this needs about {needs.memory_bytes / 2**30:.1f} GiB of memory ({needs.what}, "
            f"{MEMORY_BYTES_PER_PIXEL:g} bytes per pixel as measured) and the machine has "
            f"{memory / 2**30:.1f} GiB available: {needs.advice}"
        )
    parent = next((p for p in (out, *out.absolute().parents) if p.exists()), Path("."))
    if not os.access(parent, os.W_OK | os.X_OK):
        raise StationError(
            f"cannot write in {parent}: no write permission for this user "
            f"(mode {parent.stat().st_mode & 0o777:o}); give another --out"
        )
    free = float(shutil.disk_usage(parent).free)
    if needs.disk_bytes > free:
        raise StationError(
            f"this writes up to {needs.disk_bytes / 2**30:.1f} GiB ({needs.what}) and "
            f"{parent} has {free / 2**30:.1f} GiB free: free some space or give another --out"
        )
    return Checked(
        memory_bytes=needs.memory_bytes,
        memory_available_bytes=memory,
        disk_bytes=needs.disk_bytes,
        disk_free_bytes=free,
    )


def check_scenario(scn: Scenario) -> list[str]:
    """The files a scenario names, read now (:class:`StationError`, :class:`LevelsError`
    on the first that cannot be used); returns what was checked, in words."""
    from levels.makers.base import Need
    from levels.process import pass_dem, plan_levels
    from levels.readers.dem import read_dem

    done = []
    _warn_outside_service(scn)
    if scn.orbit.kind == "tle":
        from station.spacecraft.tle import read_tle

        path = scn.path(scn.orbit.tle_path)
        records = read_tle(path)
        if scn.orbit.tle_index >= len(records):
            raise StationError(
                f"[orbit] tle_index = {scn.orbit.tle_index}: {path} holds {len(records)} "
                "element set(s)"
            )
        done.append(f"TLE {path.name} ({len(records)} element sets)")
    if scn.world.kind == "dem":
        from station.spacecraft.hgt import read_hgt

        path = scn.path(scn.world.dem_path)
        read_hgt(path)
        done.append(f"world DEM {path.name}")
    if scn.processing.dem_path:
        dem = read_dem(scn.processing.dem_path, scn.processing.dem_vertical)
        if any(Need.DEM in m.needs for m in plan_levels(scn.processing.levels)):
            _check_covers(scn, dem)
        done.append(f"level 3 DEM {Path(scn.processing.dem_path).name} ({dem.height_m.shape})")
    elif scn.dem is None:
        pass_dem(scn.processing)  # a level needing a DEM without one: said now
    return done


def _warn_outside_service(scn: Scenario) -> None:
    """One warning when the pass's day (``[pass] date_utc``; a TLE dates its own) lies
    outside the days SPOT 1–4 imaged (:data:`levels.spot.SERVICE_UTC`): emulated all the
    same."""
    import numpy as np

    from levels.spot import SERVICE_UTC

    if scn.orbit.kind == "tle":
        return
    day = np.datetime64(scn.pass_.date_utc, "D")
    first, last = (np.datetime64(d, "D") for d in SERVICE_UTC)
    if not first <= day <= last:
        _log.warning(
            "[pass] date_utc = %s: no SPOT 1–4 flew then (SPOT 1 from %s, SPOT 4 to %s); "
            "the pass is emulated all the same",
            scn.pass_.date_utc,
            *SERVICE_UTC,
        )


def _check_covers(scn: Scenario, dem: Dem) -> None:
    """:class:`StationError` when the level 3 DEM lies off the pass: the pass's footprint
    traced on the geometry alone (no image rendered: a fraction of a second), its corners
    and centre against the DEM's grid (``levels.geo.coverage.on_dem``)."""
    import numpy as np

    from levels.geo.coverage import on_dem
    from station.spacecraft.dem import footprint_rad
    from station.spacecraft.emulator import emulate_pass

    south, north, west, east = footprint_rad(emulate_pass(scn, render=False))
    lat = np.array([south, south, north, north, 0.5 * (south + north)])
    lon = np.array([west, east, west, east, 0.5 * (west + east)])
    if not on_dem(dem, lat, lon).any():
        d = np.degrees
        raise StationError(
            f"the level 3 DEM {Path(scn.processing.dem_path).name} does not cover the pass "
            f"(latitudes {d(south):.3f}° to {d(north):.3f}°, longitudes {d(west):.3f}° to "
            f"{d(east):.3f}°): give one over it"
        )
