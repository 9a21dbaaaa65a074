"""Where a day's processing workers run: a pool of local processes (``--workers N``), or the
workers of a running Dask cluster (``--scheduler ADDRESS``).

Both are used the same way by the day and its calibration: ``submit(fn, *args)`` gives a
future with ``result()``, ``done()`` and ``add_done_callback``, and ``workers`` says how
many jobs run at once. Local workers are spawned processes, each warmed as it starts
(:func:`station.day.work.warm`); a cluster's workers are warmed once, all of them, when the
day connects. A cluster's workers must see the day's directory at the same path (this
machine, or a file system they share): they read the archives and write the products and
their catalogue entries there. SQLite's locking, which the catalogue relies on for several
writers, holds on a local file system, not on every network one.
"""

from __future__ import annotations

import contextlib
import time
import uuid
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context
from typing import Any, Protocol

from station.day import work
from station.errors import StationError

__all__ = ["DayPool", "day_pool", "finish_times"]

#: Wall seconds a scheduler has to answer.
CONNECT_TIMEOUT_S = 10.0


class DayPool(Protocol):
    """A day's processing workers (module docstring)."""

    workers: int
    where: str

    def submit(self, fn: Callable[..., Any], *args: Any) -> Any: ...


class _Local:
    def __init__(self, pool: ProcessPoolExecutor, workers: int) -> None:
        self.pool, self.workers, self.where = pool, workers, f"{workers} local process(es)"

    def submit(self, fn: Callable[..., Any], *args: Any) -> Any:
        return self.pool.submit(fn, *args)


class _Cluster:
    def __init__(self, client: Any, address: str) -> None:
        self.client = client
        try:  # newer Dask lists only some workers unless asked for all
            info = client.scheduler_info(n_workers=-1)["workers"]
        except TypeError:
            info = client.scheduler_info()["workers"]
        self.workers = sum(int(w.get("nthreads", 1)) for w in info.values())
        self.where = f"{self.workers} Dask worker thread(s) at {address}"

    def submit(self, fn: Callable[..., Any], *args: Any) -> Any:
        # a key of its own each time: the same job submitted again runs again
        key = f"{getattr(fn, '__name__', 'job')}-{uuid.uuid4().hex}"
        return self.client.submit(fn, *args, key=key, pure=False)


@contextlib.contextmanager
def day_pool(workers: int, scheduler: str | None = None) -> Iterator[DayPool]:
    """The day's workers: ``workers`` spawned local processes, or, with ``scheduler``,
    the workers of the Dask cluster there (every one warmed before it is given a job).
    :class:`StationError` when Dask is not installed, the scheduler does not answer, or
    its cluster has no worker."""
    if scheduler is None:
        ctx = get_context("spawn")
        with ProcessPoolExecutor(workers, mp_context=ctx, initializer=work.warm) as pool:
            yield _Local(pool, workers)
        return
    try:
        from distributed import Client
    except ImportError:
        raise StationError(
            "--scheduler needs the distributed extra: pip install 'spot-station[distributed]'"
        ) from None
    try:
        client = Client(scheduler, timeout=CONNECT_TIMEOUT_S)
    except (OSError, TimeoutError, ValueError) as exc:  # ValueError: not an address
        raise StationError(f"no Dask scheduler answers at {scheduler}: {exc}") from None
    with client:
        cluster = _Cluster(client, scheduler)
        if cluster.workers < 1:
            raise StationError(f"the Dask cluster at {scheduler} has no worker")
        client.run(work.warm)  # every worker's kernels loaded before the clock
        yield cluster


def finish_times(futures: Iterable[Any]) -> list[float]:
    """Each future's end on the wall clock (as its done callback sees it), once all are
    done, in the order given; a failed job raises here."""
    futures = list(futures)
    ends: dict[int, float] = {}

    def seen(k: int) -> Callable[[Any], None]:
        return lambda _f: ends.__setitem__(k, time.time())

    for k, f in enumerate(futures):
        f.add_done_callback(seen(k))
    for f in futures:
        f.result()
    deadline = time.time() + 5.0  # a callback runs in another thread, just after the end
    while len(ends) < len(futures) and time.time() < deadline:
        time.sleep(0.001)
    return [ends.get(k, time.time()) for k in range(len(futures))]
