"""The warm-up's shipped archive (``levels/data/warmup.l0.h5``) is this version's L0, and a
process whose kernels are cached starts no warm-up."""

from __future__ import annotations

import numpy as np

from levels.readers.l0 import read_l0
from levels.warmup import WARM_UP_ARCHIVE, cache_is_cold, start_warm_up, wait_for_warm_up


def test_warm_up_archive_is_this_versions_l0() -> None:
    """The shipped archive reads and checks as an L0 archive of this version: the pass of
    ``scenarios/warmup.toml``, which regenerates it (levels/warmup.py says how)."""
    archive = read_l0(WARM_UP_ARCHIVE)
    assert archive.mode == "P"
    band = archive.bands["P"]
    assert band.counts.shape == (240, 200)
    assert np.count_nonzero(band.pixel_valid()) > 0.99 * band.counts.size


def test_no_background_warm_up_when_the_cache_is_warm() -> None:
    """This test process has compiled (and cached) the kernels by now: nothing is started,
    and waiting for nothing returns."""
    from levels.warmup import warm_up

    warm_up()
    assert not cache_is_cold()
    process = start_warm_up()
    assert process is None
    wait_for_warm_up(process)
