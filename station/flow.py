"""One run skeleton for every flow of the station: a pass, a block of passes, a SAR frame;
emulated (``station run``) or from files (``station process``).

A :class:`Flow` says what it is (its report's format, what its directory is made of, the
files it reads) and supplies the parts that are its own: ``check`` (before any work),
``acquire`` (the :class:`levels.work.Request` of its inputs: the pass emulated, sent and
recorded; the archives or the frame read), ``measure`` (what the products are held to: the
truth, or nothing) and ``sections`` (its report's body, from the one
:class:`levels.work.Result`). :func:`run_flow` does the rest, once for every flow:

1. the output directory checked before any work (:func:`station.outdir.replaceable_dir`:
   absent, empty, or an earlier output of the same flow), and the flow's own checks;
2. everything made in a staging directory published whole when complete
   (:func:`station.outdir.published_dir`): a failure leaves the previous output as it was;
3. the flow's request planned and made by ``levels`` (:func:`levels.work.plan`,
   :func:`levels.work.run`);
4. a quicklook of every product (when asked), the STAC catalogue and the report, written
   once, its header from the flow's format (:class:`station.reports.ReportFormat`).

A flow inside another (a block's passes, each run as a pass's flow in its own directory)
is :func:`make_flow` in the outer one's staging directory.
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

from levels.files import write_json
from levels.tasks import Runner
from levels.work import Measure, Request, Result, plan, run
from station.reports import ReportFormat

if TYPE_CHECKING:
    from levels.tasks import DaskRunner, InProcess

__all__ = [
    "Flow",
    "FlowRun",
    "ScenarioRun",
    "flow_dir",
    "make_flow",
    "quicklooks_of",
    "run_flow",
    "runner_for",
]


@dataclass
class FlowRun:
    """What a flow's parts share while it runs: how it was asked to run, its timings (s,
    by stage; nested dicts for a stage's parts) and the quicklooks drawn (by product
    path, the quicklook's path)."""

    quicklooks: bool = True
    progress: bool = False
    runner: Runner | None = None
    timings: dict[str, Any] = field(default_factory=dict)
    drawn: dict[Path, Path] = field(default_factory=dict)
    #: ``on_scene(done, n_scenes)`` after each scene of a lone pass (a progress bar).
    on_scene: Callable[[Any, int], None] | None = None


class Flow(Protocol):
    """A flow of the station (module docstring)."""

    #: Its report: file, format, version.
    report: ReportFormat

    @property
    def owner(self) -> object:
        """What its output is made of, as its report names it (a scenario's name)."""
        ...

    def what(self, owner: object) -> str:
        """An output made of ``owner``, in words."""
        ...

    def inputs(self) -> list[Path]:
        """The files it reads (an output directory may not hold them)."""
        ...

    def check(self, out: Path) -> None:
        """Everything it needs, checked before any work; raises what is wrong."""
        ...

    def acquire(self, stage: Path, state: FlowRun) -> Request | None:
        """Its inputs made or read into ``stage``, as one request of ``levels`` (None:
        nothing for ``levels`` to make)."""
        ...

    def measure(self) -> Measure:
        """What its products are held to (after :meth:`acquire`)."""
        ...

    def catalog(self) -> tuple[str, str]:
        """Its STAC catalogue's id and description."""
        ...

    def sections(self, stage: Path, result: Result, state: FlowRun) -> dict[str, Any]:
        """Its report's header fields and body, in order (``header``: the header's)."""
        ...


class ScenarioRun:
    """What the flows of ``station run`` share: their output is a run of one scenario (its
    name in the report's ``scenario``), replaced only by a run of the same scenario, and
    reads the scenario's files. ``scenario`` has a ``name`` and ``inputs()``."""

    def __init__(self, scenario: _Named) -> None:
        self._scenario = scenario

    @property
    def owner(self) -> object:
        return self._scenario.name

    def what(self, owner: object) -> str:
        return f"a run of scenario {owner!r}"

    def inputs(self) -> list[Path]:
        return self._scenario.inputs()


class _Named(Protocol):
    @property
    def name(self) -> str: ...

    def inputs(self) -> list[Path]: ...


@contextlib.contextmanager
def runner_for(
    workers: int | None = None, scheduler: str | None = None
) -> Iterator[InProcess | DaskRunner]:
    """Where a flow's tasks run (:func:`levels.tasks.dask_runner`): in this process, on a
    local Dask cluster of ``workers`` processes, or on the cluster at ``scheduler``."""
    from levels.tasks import dask_runner
    from station.errors import StationError

    if workers is not None and workers < 1:
        raise StationError(
            f"--workers {workers}: give a positive number of workers (without "
            "--workers the tasks run in this process)"
        )
    if workers and scheduler:
        raise StationError("give --workers (a local cluster) or --scheduler, not both")
    with dask_runner(scheduler, workers or 0) as runner:
        yield runner


def run_flow(
    flow: Flow,
    out_dir: str | Path,
    *,
    quicklooks: bool = True,
    progress: bool = False,
    runner: Runner | None = None,
    on_scene: Callable[[Any, int], None] | None = None,
) -> dict[str, Any]:
    """Run ``flow`` into ``out_dir`` (module docstring); returns its report."""
    from station.outdir import published_dir

    out = flow_dir(flow, out_dir)
    flow.check(out)
    state = FlowRun(quicklooks, progress, runner, on_scene=on_scene)
    with published_dir(out) as stage:
        return make_flow(flow, stage, state)


def flow_dir(flow: Flow, out_dir: str | Path) -> Path:
    """The flow's output directory, checked before any work: absent, empty, or an earlier
    output of the same flow (:func:`station.outdir.replaceable_dir`)."""
    from station.outdir import replaceable_dir

    return replaceable_dir(
        out_dir, flow.report.file, flow.report.owner_in, flow.owner, flow.what, flow.inputs()
    )


def make_flow(flow: Flow, stage: Path, state: FlowRun) -> dict[str, Any]:
    """Everything of :func:`run_flow` inside its (staging) directory ``stage``."""
    from station.catalog import write_catalog

    clock = time.perf_counter
    t0 = clock()
    request = flow.acquire(stage, state)
    result = (
        run(plan(request), state.runner, flow.measure(), state.on_scene)
        if request is not None
        else Result((), ())
    )
    if state.quicklooks and result.products:
        t = clock()
        state.drawn = quicklooks_of([m.path for m in result.products])
        state.timings["quicklooks"] = clock() - t
    t = clock()
    write_catalog(stage, *flow.catalog())
    state.timings["catalog"] = clock() - t
    state.timings["total"] = clock() - t0
    body = flow.sections(stage, result, state)
    report = {**flow.report.header(**body.pop("header", {})), **body}
    write_json(stage / flow.report.file, report)
    return report


def quicklooks_of(paths: list[Path]) -> dict[Path, Path]:
    """A quicklook of each product, ``<its directory>/quicklooks/<its stem>.png``, drawn on
    threads: by product path, the quicklook's."""
    from levels.products import read_product
    from levels.quicklook import write_quicklook
    from levels.threads import in_threads

    drawn = in_threads(
        lambda p: write_quicklook(read_product(p), p.parent / "quicklooks" / f"{p.stem}.png"),
        paths,
    )
    return dict(zip(paths, drawn, strict=True))
