"""Compiling the processing kernels before a first run needs them: ``python -m levels.warmup``.

Numba compiles each kernel on its first call and caches the machine code on disk
(``cache=True``); on a fresh install the first ``station run`` spends most of its time
compiling (15 s of one core on 2026-11-24, 24 s while the kernels were numba's
``parallel=True``), about half of that in this package's kernels (calibration,
deconvolution, the 1B and 2A resampling, the inverse grid). :func:`warm_up` processes a
tiny L0 archive shipped with the package (``levels/data/warmup.l0.h5``: 240 lines × 200
detectors of the default scenario's P pass near Cuiabá, 170 kB) through levels 1A, 1B and
2A into a temporary directory: every kernel of a default run is compiled with the types it
is called with, and cached.

:func:`start_warm_up` does that in a background process when the cache is cold, so that on
a machine with two cores or more the processing kernels compile while the emulator's do;
:func:`wait_for_warm_up` lets the run wait for it before its own processing rather than
compile the same kernels a second time. The warm cache is then the same as if the run had
compiled them itself: products do not depend on it.

Regenerate the archive after a change of the L0 format::

    station run scenarios/warmup.toml --out /tmp/warmup --quiet --no-quicklooks
    cp /tmp/warmup/warmup.l0.h5 levels/data/
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
from pathlib import Path

__all__ = [
    "WARM_UP_ARCHIVE",
    "cache_is_cold",
    "start_warm_up",
    "stop_warm_up",
    "wait_for_warm_up",
    "warm_up",
]

#: The tiny L0 archive :func:`warm_up` processes.
WARM_UP_ARCHIVE = Path(__file__).resolve().parent / "data" / "warmup.l0.h5"
#: How long a run waits for the background warm-up before compiling itself (s): it takes
#: 8–20 s on one core of this project's shared host, whose speed varies twofold.
WAIT_S = 120.0


def _kernels() -> list:
    """The dispatchers of the kernels a default run calls (levels 1A, 1B, 2A)."""
    from levels import products
    from levels.cor import radiometry, resample
    from levels.geo import inverse_grid
    from levels.hdf5 import fletcher32

    return [
        radiometry._calibrate,
        radiometry._fir_along_lines,
        radiometry._fir_along_columns,
        resample._kernel_1b,
        resample._kernel_2a,
        resample._kernel_nan,
        inverse_grid.invert_nodes,
        fletcher32,
        products._kernel_fill,
    ]


def cache_is_cold() -> bool:
    """Whether a kernel of a default run has no machine code cached for its current
    source. Numba's cache index is read through its internals; if they are not what this
    version knows, the cache is taken as warm (no background process is started)."""
    try:
        return any(not k._cache._cache_file._load_index() for k in _kernels())
    except Exception:  # numba's internals changed, or a damaged index: do nothing
        return False


def warm_up() -> None:
    """Process :data:`WARM_UP_ARCHIVE` through levels 1A, 1B and 2A into a temporary
    directory and export its 2A as a run does (the GeoTIFF's fill), compiling (and
    caching) the kernels a default run calls."""
    from levels.export import write_geotiff
    from levels.options import ProcessingOptions
    from levels.process import ProcessingRequest, process
    from levels.products import read_product
    from levels.readers.l0 import read_l0

    options = ProcessingOptions(levels=("1A", "1B", "2A"))
    with tempfile.TemporaryDirectory(prefix="levels-warmup-") as tmp:
        made = process(
            ProcessingRequest.of(read_l0(WARM_UP_ARCHIVE, lazy=True), options, tmp, "warmup")
        )
        two_a = made[0].scenes[0].paths["2A"]
        write_geotiff(read_product(two_a), Path(tmp) / "warmup_2A.tif")


def start_warm_up() -> subprocess.Popen | None:
    """:func:`warm_up` in a background process, if the cache is cold and this machine has
    a second core to run it on; ``None`` otherwise. Its output is discarded: a failure
    only means the run compiles the kernels itself."""
    if (os.cpu_count() or 1) < 2 or not WARM_UP_ARCHIVE.is_file() or not cache_is_cold():
        return None
    return subprocess.Popen(
        [sys.executable, "-m", "levels.warmup"],
        stdin=subprocess.DEVNULL,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )


def wait_for_warm_up(process: subprocess.Popen | None, timeout_s: float = WAIT_S) -> None:
    """Wait for a background warm-up to end (at most ``timeout_s``; then it is stopped)."""
    if process is None:
        return
    try:
        process.wait(timeout=timeout_s)
    except subprocess.TimeoutExpired:
        stop_warm_up(process)


def stop_warm_up(process: subprocess.Popen | None) -> None:
    """End a background warm-up that is still running (a run that fails or is
    interrupted does not leave it behind)."""
    if process is not None and process.poll() is None:
        process.kill()
        process.wait()


if __name__ == "__main__":
    warm_up()
