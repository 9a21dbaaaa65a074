"""Where the scenes of a pass are made: one after another in this process, or as tasks on
a Dask distributed cluster.

The processing is cut into tasks that share nothing but what they are handed: one task per
scene, given the pass's set-up (GEO's pass geometry, the options, the L0 archive read
lazily, :class:`levels.readers.l0.L0Rows`) and the scene, writing its products and
returning their paths and figures. A *runner* says where the tasks run:

- :class:`InProcess` (the default): each task is called in this process, in the order
  submitted, with every core for its kernels (numba). Nothing to start, nothing to install.
- :class:`DaskRunner`: each task is a Dask future on a ``distributed.Client`` (a cluster
  the user runs, ``station … --scheduler ADDRESS``, or a local one it starts,
  ``--workers N``). The pass's set-up is scattered once and each worker holds one scene at
  a time (run workers with one thread each; ``NUMBA_NUM_THREADS`` sets how many cores a
  worker's kernels use).

A task's result does not depend on where it ran: the products are bit for bit the same
with either runner and any number of workers (``tests/test_distributed.py``). A task that
fails is reported by its name (``<archive>-s<scene>``) with its error, and the others are
finished (:class:`TaskFailure`).

Dask is an optional dependency (the ``distributed`` extra); only :class:`DaskRunner`
imports it.
"""

from __future__ import annotations

import contextlib
import itertools
import os
import uuid
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from typing import Any, NoReturn, Protocol

from levels.errors import LevelsError

__all__ = [
    "SCHEDULER_ENV",
    "DaskRunner",
    "InProcess",
    "Runner",
    "TaskFailure",
    "dask_runner",
    "raise_first",
    "scheduler_address",
]

#: The usual Dask environment variable naming a scheduler (Dask's configuration key
#: ``scheduler-address``): a run with it set goes to that cluster.
SCHEDULER_ENV = "DASK_SCHEDULER_ADDRESS"
#: How long a client waits for a scheduler to answer before saying there is none.
CONNECT_TIMEOUT_S = 20.0


@dataclass(frozen=True)
class TaskFailure:
    """A task that raised: its name and its error (with its traceback, remote or not)."""

    name: str
    error: BaseException

    @property
    def bad_input(self) -> bool:
        """The error is the library's own (bad input, damaged file), not a bug."""
        return isinstance(self.error, LevelsError | OSError)

    def line(self) -> str:
        first = (str(self.error).splitlines() or [""])[0]
        kind = "" if self.bad_input else f"{type(self.error).__name__}: "
        return f"{self.name}: {kind}{first}"


def raise_first(
    failures: list[TaskFailure], what: str = "task", first: TaskFailure | None = None
) -> NoReturn:
    """Raise one failure's error as itself (``first``, by default the first), with a note
    naming its task and every task that failed: once all tasks have ended, the others'
    results kept."""
    one = first or failures[0]
    one.error.add_note(f"in {what} {one.name}; failed: {', '.join(f.name for f in failures)}")
    raise one.error


class Runner(Protocol):
    """Where tasks run (module docstring)."""

    #: How many tasks run at once.
    workers: int

    def share(self, obj: Any) -> Any:
        """``obj`` as tasks receive it: itself in process, a scattered future on Dask."""
        ...

    def submit(self, name: str, fn: Callable[..., Any], *args: Any) -> Any:
        """A handle on ``fn(*args)``, named ``name``, started now or when asked."""
        ...

    def completed(self, handles: Iterable[Any]) -> Iterator[tuple[Any, Any]]:
        """Each handle with its result or its :class:`TaskFailure`, as they end."""
        ...


@dataclass(frozen=True, eq=False)
class _Call:
    name: str
    fn: Callable[..., Any]
    args: tuple[Any, ...]


class InProcess:
    """Tasks called in this process, in the order submitted, when their results are asked
    for (:meth:`completed`)."""

    workers = 1

    def share(self, obj: Any) -> Any:
        return obj

    def submit(self, name: str, fn: Callable[..., Any], *args: Any) -> _Call:
        return _Call(name, fn, args)

    def completed(self, handles: Iterable[_Call]) -> Iterator[tuple[_Call, Any]]:
        for h in handles:
            try:
                result = h.fn(*h.args)
            except Exception as exc:  # reported by name; the other tasks go on
                result = TaskFailure(h.name, exc)
            yield h, result


class DaskRunner:
    """Tasks as futures of a ``distributed.Client`` (module docstring). Task keys are the
    task's name, a token of this runner and a serial number, so that neither two runs on
    one cluster nor one runner's two submissions of a name ever share a result."""

    def __init__(self, client: Any, kernel_threads: int = 0) -> None:
        self.client = client
        self.kernel_threads = kernel_threads  # 0: the workers' own NUMBA_NUM_THREADS
        self._token = uuid.uuid4().hex[:8]
        self._serial = itertools.count()
        self._names: dict[str, str] = {}

    @property
    def workers(self) -> int:
        try:  # newer Dask lists only some workers unless asked for all
            info = self.client.scheduler_info(n_workers=-1)["workers"]
        except TypeError:
            info = self.client.scheduler_info()["workers"]
        return max(1, sum(int(w.get("nthreads", 1)) for w in info.values()))

    def share(self, obj: Any) -> Any:
        return self.client.scatter(obj, broadcast=True, hash=False)

    def submit(self, name: str, fn: Callable[..., Any], *args: Any) -> Any:
        # a key of its own for every submission: a task submitted again under a key the
        # scheduler still holds (its release on the way) would not run, its old result
        # standing for the new one (a pass made twice on one runner lost products so)
        key = f"{name}-{self._token}-{next(self._serial)}"
        self._names[key] = name
        if self.kernel_threads:
            return self.client.submit(
                _with_kernel_threads, self.kernel_threads, fn, *args, key=key, pure=False
            )
        return self.client.submit(fn, *args, key=key, pure=False)

    def completed(self, handles: Iterable[Any]) -> Iterator[tuple[Any, Any]]:
        from distributed import as_completed

        for future in as_completed(list(handles)):
            name = self._names.pop(future.key, str(future.key))
            if future.status == "error":
                exc = future.exception()
                tb = future.traceback()
                result = TaskFailure(name, exc.with_traceback(tb) if tb is not None else exc)
            elif future.status == "cancelled":
                result = TaskFailure(name, RuntimeError("the task was cancelled"))
            else:
                result = future.result()
            future.release()
            yield future, result


def _with_kernel_threads(n: int, fn: Callable[..., Any], *args: Any) -> Any:
    """``fn(*args)`` with numba's kernels on ``n`` threads (at most its pool), set in the
    thread that runs the task: numba's count is per thread, and a worker's pool is sized
    when numba is first imported there, which a spawned worker may do before its
    environment is set (the parent's main module imports it again)."""
    import numba

    from levels.threads import max_threads

    numba.set_num_threads(max(1, min(n, max_threads())))
    return fn(*args)


@contextlib.contextmanager
def _environment(values: dict[str, str]) -> Iterator[None]:
    """``os.environ`` with ``values`` while the block runs: what processes started in it
    inherit (a spawned worker reads its thread counts when it imports numpy and numba)."""
    saved = {k: os.environ.get(k) for k in values}
    os.environ.update(values)
    try:
        yield
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def scheduler_address(given: str | None = None) -> str | None:
    """The scheduler to use: ``given``, else ``$DASK_SCHEDULER_ADDRESS`` (Dask's own
    configuration when Dask is installed), else None (run in process)."""
    if given:
        return given
    try:
        import dask.config
    except ImportError:
        return os.environ.get(SCHEDULER_ENV) or None
    return dask.config.get("scheduler-address", None) or os.environ.get(SCHEDULER_ENV) or None


@contextlib.contextmanager
def dask_runner(
    address: str | None = None,
    workers: int = 0,
    memory_limit: str = "auto",
    cores_per_worker: int = 0,
) -> Iterator[InProcess | DaskRunner]:
    """The runner of a command: a client of the scheduler at ``address``
    (:func:`scheduler_address`), else a local cluster of ``workers`` processes started and
    stopped here (one task at a time each, bound to 127.0.0.1; their kernels share this
    machine's cores, or use ``cores_per_worker`` each, BLAS one), else
    :class:`InProcess`. :class:`LevelsError` when Dask is needed and not installed, or the
    scheduler does not answer."""
    address = scheduler_address(address)
    cores = os.cpu_count() or 1
    if workers > cores:  # more would only queue behind each other, and hold memory each
        raise LevelsError(
            f"{workers} workers on a machine of {cores} cores: give at most {cores} "
            "(each worker runs one task at a time, its kernels on the cores it is given)"
        )
    if not address and workers <= 0:
        yield InProcess()
        return
    try:
        from distributed import Client, LocalCluster
    except ImportError:
        raise LevelsError(
            "running on Dask needs the distributed extra: pip install 'spot-station[distributed]'"
        ) from None
    if address:
        try:
            client = Client(address, timeout=CONNECT_TIMEOUT_S)
        except (OSError, TimeoutError, ValueError) as exc:  # ValueError: not an address
            raise LevelsError(f"no Dask scheduler answers at {address}: {exc}") from None
        with client:
            yield DaskRunner(client)
        return
    cores = cores_per_worker or max(1, cores // workers)
    threads = {"NUMBA_NUM_THREADS": str(cores), "OMP_NUM_THREADS": "1"}
    threads["OPENBLAS_NUM_THREADS"] = "1"
    # The nanny sets ``env`` once the worker runs, after the spawned process has imported
    # the parent's main module (and, through it, numpy and numba): the thread counts are
    # also in the environment the workers are spawned with, and each task sets numba's.
    with _environment(threads):
        cluster = LocalCluster(
            n_workers=workers,
            threads_per_worker=1,
            processes=True,
            host="127.0.0.1",
            dashboard_address="127.0.0.1:0",  # no fixed port: never 8787 taken
            memory_limit=memory_limit,
            env=threads,
        )
    with cluster, Client(cluster) as client:
        yield DaskRunner(client, kernel_threads=cores)
