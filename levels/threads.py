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

BLAS is the other pool on the same cores. numpy and scipy each load an OpenBLAS that starts
a thread per core, and after every call its threads spin, waiting for the next, on the
cores the kernels' threads want. The project's dense algebra is small (21 × 21 normal
equations of the 2A polynomials, 3 × 3 rotations of thousands of points, RPC fits), too
small to gain from a second thread: :func:`one_blas_thread` runs GEO and the scene tasks
with BLAS on the calling thread. Measured on this 2-core host with the other core busy
(2026-11-25): the Cholesky of one 5000 × 21 design 3.5 ms on OpenBLAS's 2 threads, 0.20 ms
on one; GEO of 20 P scenes 23 → 8.5 ms a scene (``benchmarks/bench_levels.py`` section 3).
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor, wait
from contextlib import contextmanager
from functools import cache, wraps
from itertools import pairwise
from typing import Any, ParamSpec, TypeVar

import numba
import scipy.linalg  # noqa: F401  (its OpenBLAS loaded before _blas() looks for them)
from threadpoolctl import ThreadpoolController

__all__ = [
    "blas_threads",
    "in_threads",
    "max_threads",
    "one_blas_thread",
    "over_blocks",
    "single_blas",
    "thread_count",
]

_P = ParamSpec("_P")
_R = TypeVar("_R")

#: Chunks per thread: enough for one slow chunk (a shared host's hiccup, a block of
#: rows with more to do) not to hold the others back, few enough to cost nothing.
CHUNKS_PER_THREAD = 4

_pool: ThreadPoolExecutor | None = None
_pool_lock = threading.Lock()


def max_threads() -> int:
    """The most threads numba's kernels may use in this process (``NUMBA_NUM_THREADS``, by
    default the cores)."""
    config: Any = numba.config  # its settings are made at import, unseen by type checkers
    return int(config.NUMBA_NUM_THREADS)


def _forget_pool() -> None:  # a forked child has the pool object but not its threads
    global _pool
    _pool = None


os.register_at_fork(after_in_child=_forget_pool)


def _executor() -> ThreadPoolExecutor:
    global _pool
    with _pool_lock:
        if _pool is None:
            _pool = ThreadPoolExecutor(max(1, max_threads()), thread_name_prefix="kernels")
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


def in_threads(fn: Callable[[Any], _R], items: list[Any]) -> list[_R]:
    """``[fn(x) for x in items]`` on :func:`max_threads` threads of their own, in order: for
    work that releases the GIL in part (matplotlib's Agg drawing and Pillow's PNG encoding:
    a run's six quicklooks 1.11 → 0.58 s on two threads, 2026-11-27), not for kernels
    (:func:`over_blocks`). The first exception is raised once every item has finished."""
    if max_threads() == 1 or len(items) <= 1:
        return [fn(x) for x in items]
    with ThreadPoolExecutor(min(max_threads(), len(items)), thread_name_prefix="items") as pool:
        return list(pool.map(fn, items))


@cache
def _blas() -> ThreadpoolController:
    """The BLAS libraries loaded in this process (found once: 0.7 ms; a limit then costs
    2 µs)."""
    return ThreadpoolController()


def blas_threads() -> int:
    """Threads of the BLAS libraries loaded in this process (the largest count)."""
    return max(
        (lib.num_threads for lib in _blas().select(user_api="blas").lib_controllers), default=1
    )


@contextmanager
def single_blas() -> Iterator[None]:
    """BLAS on one thread inside the block (module docstring), its count restored after.

    The count is the process's, not the calling thread's, and OpenBLAS takes a raise of it
    only from some threads: blocks are meant for the thread that drives the processing (a
    run's, or a Dask worker's task, whose BLAS is on one thread already); nested blocks in
    it are free (2 µs)."""
    with _blas().limit(limits=1, user_api="blas"):
        yield


def one_blas_thread(fn: Callable[_P, _R]) -> Callable[_P, _R]:
    """``fn`` run inside :func:`single_blas` (a decorator for GEO's public functions)."""

    @wraps(fn)
    def wrapped(*args: _P.args, **kwargs: _P.kwargs) -> _R:
        with single_blas():
            return fn(*args, **kwargs)

    return wrapped
