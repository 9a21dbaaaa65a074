"""A day's needs estimated before any work: cores, memory and disk, each refused with its
estimate when the machine does not hold it.

The estimates, each from this code's measured sizes:

- **memory**: the front end (its resident memory on a ten-minute pass, ``bench_live``:
  300 MB), each worker's interpreter with the processing modules and kernels loaded
  (:data:`WORKER_BASE_MB`), its largest scene's arrays (:data:`BYTES_PER_PIXEL` a pixel of
  a band: the image, its radiometry in float32 and the resampling's grids), and the
  streams of the passes emulated before the clock (their bytes);
- **disk**: each pass's archive (its stream's bytes: the frames' payload is the archive's
  content, deflated little) and each order's product (a band's pixels, two bytes each);
- **cores**: more than twice as many workers as cores is refused (they would only share
  the cores: the day would measure the machine's time-slicing, not the station).
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

from station.capacity.plan import DayPlan
from station.day.config import DayScenario
from station.errors import StationError

__all__ = ["check_room", "cores", "estimate"]

FRONT_END_MB = 300.0
WORKER_BASE_MB = 400.0
BYTES_PER_PIXEL = 40.0
#: A reduced scene's flight time (s): the same 60 km as a full scene's, whatever its size.
SCENE_S = 9.0
MAX_WORKERS_PER_CORE = 2


def _available_mb() -> float:
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemAvailable:"):
                return float(line.split()[1]) / 1024.0
    except OSError:
        pass
    return float("inf")  # not Linux: not checked


def estimate(scn: DayScenario, plan: DayPlan, local_workers: bool = True) -> dict[str, float]:
    """The day's needs (module docstring): memory and disk in MB, cores (the workers'
    memory and cores left out when they are a cluster's)."""
    day = scn.day
    bands = {"P": 1, "XS": 3}
    stream_mb = 0.0
    largest_px = 0.0
    for p in plan.passes:
        for s in p.segments:
            stream_mb += (s.scenes * SCENE_S + 0.2) * day.bit_rate_mbps / 8.0
            n = day.p_detectors if s.mode == "P" else day.p_detectors // 2
            largest_px = max(largest_px, n * n * bands[s.mode])
    product_mb = 0.0
    for o in plan.orders:
        _, seg = plan.segment(o.pass_name, o.hrv)
        n = day.p_detectors if seg.mode == "P" else day.p_detectors // 2
        product_mb += n * n * bands[seg.mode] * 2.0 / 1e6
    worker_mb = WORKER_BASE_MB + largest_px * BYTES_PER_PIXEL / 1e6
    return {
        "memory_mb": FRONT_END_MB + day.workers * worker_mb * local_workers + stream_mb,
        "disk_mb": 1.1 * stream_mb + product_mb,
        "cores": float(day.workers * local_workers),
    }


def cores() -> int:
    """Cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        return os.cpu_count() or 1


def check_room(
    scn: DayScenario, plan: DayPlan, out: Path, local_workers: bool = True
) -> dict[str, float]:
    """The estimate, or :class:`StationError` naming what the machine lacks (without
    ``local_workers``, a cluster's workers: their cores and memory are not this machine's)."""
    need = estimate(scn, plan, local_workers)
    have_cores = cores()
    if local_workers and scn.day.workers > MAX_WORKERS_PER_CORE * have_cores:
        raise StationError(
            f"{scn.day.workers} workers on {have_cores} core(s): more than "
            f"{MAX_WORKERS_PER_CORE} a core only shares them; give --workers "
            f"{MAX_WORKERS_PER_CORE * have_cores} or fewer"
        )
    avail = _available_mb()
    if need["memory_mb"] > avail:
        raise StationError(
            f"the day needs about {need['memory_mb']:.0f} MB of memory (front end "
            f"{FRONT_END_MB:.0f}, {scn.day.workers} workers, the passes' streams) and "
            f"{avail:.0f} MB are available: fewer workers, or smaller [day] p_detectors"
        )
    where = out.resolve()
    while not where.exists():
        where = where.parent
    free = shutil.disk_usage(where).free / 1e6
    if need["disk_mb"] > free:
        raise StationError(
            f"the day writes about {need['disk_mb']:.0f} MB (archives and products) and "
            f"{free:.0f} MB are free under {out}"
        )
    return need | {
        "cores_available": float(have_cores),
        "memory_available_mb": avail,
        "cpu_count": float(os.cpu_count() or 1),
    }
