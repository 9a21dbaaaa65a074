"""Numba kernels over blocks, on threads: compiled serial and ``nogil``, run by a thread pool.

Every multi-core kernel of the project (levels' and the emulator's) is written as
``kernel(lo, hi, *args)``: it does items ``lo … hi − 1`` of its outer loop (lines, blocks
of lines, columns) and nothing else, each item writing only its own part of the outputs.
:func:`over_blocks` cuts ``[0, n)`` into contiguous chunks and has ``k`` threads take them
in turn, ``k`` being numba's thread count in the calling thread (``numba.set_num_threads``
and ``NUMBA_NUM_THREADS`` keep their meaning: a Dask worker's one-core task runs its kernels
in its own thread, ``levels.tasks``).

Why not ``parallel=True``: numba compiles a ``prange`` loop into a gufunc of its own, which
made compiling the default scenario's kernels 55 % longer (23.8 s instead of 15.4 s of one
core, measured the same minutes on 2026-11-24, ``benchmarks/bench_first_run.py``'s
subject). The chunks here are as coarse as numba's. The bytes are the same whatever
``k``: no item reads what another writes, and no kernel reduces across items.

One thing ``parallel=True`` did on the way, and serial kernels must do themselves: its
pipeline copy-propagates the arrays handed to ``inline="always"`` helpers. Without it each
such call increfs and decrefs every array it takes (atomic operations): 2A's per-pixel
helper cost 40 % that way, until its pixels went by spans (``levels.cor.resample``). In a
hot loop, inline helpers take scalars; arrays are read in the loop itself.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor, wait
from itertools import pairwise
from typing import Any

import numba

__all__ = ["over_blocks", "thread_count"]

#: Chunks per thread: enough for one slow chunk (a shared host's hiccup, a block of
#: rows with more to do) not to hold the others back, few enough to cost nothing.
CHUNKS_PER_THREAD = 4

_pool: ThreadPoolExecutor | None = None
_pool_lock = threading.Lock()


def _forget_pool() -> None:  # a forked child has the pool object but not its threads
    global _pool
    _pool = None


os.register_at_fork(after_in_child=_forget_pool)


def _executor() -> ThreadPoolExecutor:
    global _pool
    with _pool_lock:
        if _pool is None:
            _pool = ThreadPoolExecutor(
                max(1, numba.config.NUMBA_NUM_THREADS), thread_name_prefix="kernels"
            )
        return _pool


def thread_count() -> int:
    """Threads a kernel called from this thread runs on (numba's count for this thread)."""
    return max(1, numba.get_num_threads())


def over_blocks(kernel: Callable[..., Any], n: int, *args: Any, grain: int = 1) -> None:
    """``kernel(lo, hi, *args)`` over ``[0, n)``, on :func:`thread_count` threads.

    On one thread, or ``n ≤ grain`` items, the kernel runs once in the calling thread.
    Otherwise the range is cut into up to ``CHUNKS_PER_THREAD`` chunks per thread, of
    ``grain`` items at least, taken in turn by that many workers of a shared pool (so at
    most ``k`` run at once, however many callers); an exception in a chunk is raised here
    once every chunk taken has finished.
    """
    k = thread_count()
    if n <= 0:
        return
    if k == 1 or n <= grain:
        kernel(0, n, *args)
        return
    n_chunks = min(max(n // grain, 1), k * CHUNKS_PER_THREAD)
    bounds = [n * c // n_chunks for c in range(n_chunks + 1)]
    chunks = pairwise(bounds)
    lock = threading.Lock()

    def drain() -> None:
        while True:
            with lock:
                chunk = next(chunks, None)
            if chunk is None:
                return
            kernel(chunk[0], chunk[1], *args)

    pool = _executor()
    futures: list[Future[None]] = [pool.submit(drain) for _ in range(min(k, n_chunks))]
    wait(futures)
    for f in futures:
        f.result()
