"""levels.threads: kernels over blocks on threads cover every item once, whatever the
thread count, and give the same bytes; a failing chunk is raised to the caller. BLAS runs
on one thread inside GEO and the scene tasks, and its count comes back after."""

from __future__ import annotations

import threading

import numba as nb
import numpy as np
import pytest

from levels.threads import blas_threads, one_blas_thread, over_blocks, single_blas, thread_count


@nb.njit(nogil=True)
def _count(lo, hi, hits):
    for i in range(lo, hi):
        hits[i] += 1


@pytest.mark.parametrize("n", [0, 1, 2, 3, 7, 64, 1001])
def test_every_item_once(n: int) -> None:
    hits = np.zeros(n, dtype=np.int64)
    over_blocks(_count, n, hits)
    assert np.all(hits == 1)


def test_grain_runs_small_calls_in_the_calling_thread() -> None:
    seen: list[tuple[int, int, str]] = []

    def kernel(lo: int, hi: int) -> None:
        seen.append((lo, hi, threading.current_thread().name))

    over_blocks(kernel, 100, grain=100)
    assert seen == [(0, 100, threading.current_thread().name)]


def test_thread_count_follows_numba() -> None:
    before = nb.get_num_threads()
    try:
        nb.set_num_threads(1)
        assert thread_count() == 1
        names: set[str] = set()
        over_blocks(lambda lo, hi: names.add(threading.current_thread().name), 50)
        assert names == {threading.current_thread().name}  # one thread: no pool
    finally:
        nb.set_num_threads(before)


@pytest.mark.skipif(
    nb.config.NUMBA_NUM_THREADS < 2, reason="one thread: nothing to compare it with"
)
def test_same_result_on_one_and_all_threads() -> None:
    """The 2A kernel's products do not depend on how its blocks are shared out."""
    from levels.cor.resample import _BLOCK_ROWS, _kernel_2a

    rng = np.random.default_rng(3)
    img = rng.uniform(0, 255, (300, 280)).astype(np.float32)
    img[50:60, 100:110] = np.nan
    inv_line = np.broadcast_to(np.linspace(-20, 320, 12)[:, None], (2, 12, 11)).copy()
    inv_col = np.broadcast_to(np.linspace(-15, 300, 11)[None, :], (12, 11)).copy()
    seg_of = (np.arange(280) >= 140).astype(np.int64)
    outs = []
    before = nb.get_num_threads()
    try:
        for k in (1, before):
            nb.set_num_threads(k)
            out = np.empty((330, 300), np.uint8)
            ok = np.empty(out.shape, bool)
            n = -(-out.shape[0] // _BLOCK_ROWS)
            over_blocks(_kernel_2a, n, img, 30, 30, inv_line, inv_col, seg_of, 0, 0, 2, out, ok)
            outs.append((out, ok))
    finally:
        nb.set_num_threads(before)
    assert outs[0][1].any() and not outs[0][1].all()  # inside, outside and around the NaNs
    assert np.array_equal(outs[0][0], outs[1][0]) and np.array_equal(outs[0][1], outs[1][1])


def test_a_failing_chunk_is_raised_after_the_others() -> None:
    done = np.zeros(40, dtype=bool)

    def kernel(lo: int, hi: int) -> None:
        if lo <= 13 < hi:
            raise ValueError("chunk with item 13")
        done[lo:hi] = True

    with pytest.raises(ValueError, match="item 13"):
        over_blocks(kernel, 40)
    missing = np.flatnonzero(~done)  # the failing chunk only, every other one finished
    assert 13 in missing and np.all(np.diff(missing) == 1)
    if thread_count() > 1:
        assert missing.size < 40


@pytest.mark.skipif(
    blas_threads() < 2, reason="BLAS on one thread already: a limit to one would show nothing"
)
def test_single_blas_nests_and_restores() -> None:
    before = blas_threads()
    with single_blas():
        assert blas_threads() == 1
        with single_blas():
            assert blas_threads() == 1
        assert blas_threads() == 1  # the inner block's end leaves the outer's limit
    assert blas_threads() == before


def test_geo_and_scene_tasks_run_blas_on_one_thread() -> None:
    from levels.geo.level1b import level1b_geometry
    from levels.geo.level2a import level2a_geometry
    from levels.geo.level3 import level3_geometry
    from levels.geo.rpc import fit_rpc
    from levels.geo.scenes import PassGeometry, pass_geometry
    from levels.process import geo_pass, make_scene

    for fn in (
        level1b_geometry,
        level2a_geometry,
        level3_geometry,
        fit_rpc,
        pass_geometry,
        PassGeometry.scene,
        geo_pass,
        make_scene,
    ):
        assert getattr(fn, "__wrapped__", None) is not None, fn.__name__

    @one_blas_thread
    def probe() -> int:
        return blas_threads()

    assert probe() == 1
