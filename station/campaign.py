"""Reprocessing campaigns: many recorded L0 archives processed again as one job.

A processing centre mostly reprocesses what it has archived (a new calibration, new levels,
a regression over months of passes). ``station campaign SOURCE… --out DIR`` takes L0
archives given one by one, as directories (every ``*.l0.h5`` under them) or as list files
(``.txt``: one path per line, relative to the list, ``#`` comments), processes each into
``DIR/<archive>/`` exactly as ``station process`` would (the same products, byte for
byte), and writes one report, ``DIR/campaign.json``: per archive its status, its products
and their headline figures, or the reason it failed. An archive that fails (damaged,
unreadable, a bug) is reported by name and the others are still processed.

The archives are planned here in batches (read lazily, GEO: one archive at a time in
process, twice as many as workers on Dask); their scenes are tasks (:mod:`levels.tasks`):
in this process by default, each using every core, or on a Dask cluster (``--workers N``,
``--scheduler ADDRESS``), where the products are the same bit for bit. A scene that fails
makes its archive fail, named with the scene; its other scenes and the other archives are
finished.
"""

from __future__ import annotations

import dataclasses
import time
import traceback
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from levels.errors import LevelsError
from levels.options import ProcessingOptions
from levels.tasks import Runner
from station.errors import StationError
from station.reports import CAMPAIGN

if TYPE_CHECKING:
    from levels.work import Result
    from station.flow import FlowRun

__all__ = ["CAMPAIGN_FORMAT", "campaign_archives", "run_campaign"]

CAMPAIGN_FORMAT = CAMPAIGN.name
_L0_SUFFIX = ".l0.h5"


def campaign_archives(sources: list[str | Path]) -> list[Path]:
    """The L0 archives of a campaign, in the order given (directories sorted by path),
    each once."""
    found: list[Path] = []
    for source in (Path(s) for s in sources):
        if source.is_dir():
            found += sorted(p for p in source.rglob(f"*{_L0_SUFFIX}") if p.is_file())
        elif source.suffix == ".txt":
            if not source.is_file():
                raise StationError(f"{source}: list of L0 archives not found")
            for line in source.read_text().splitlines():
                entry = line.split("#", 1)[0].strip()
                if entry:
                    path = Path(entry)
                    found.append(path if path.is_absolute() else source.parent / path)
        else:
            found.append(source)
    unique = list(dict.fromkeys(p.resolve() for p in found))
    if not unique:
        raise StationError(
            f"no L0 archives (*{_L0_SUFFIX}) in {', '.join(str(s) for s in sources)}"
        )
    return unique


def run_campaign(
    archives: list[Path],
    out: str | Path,
    options: ProcessingOptions,
    progress: Callable[[int, int, str], None] | None = None,
    runner: Runner | None = None,
) -> dict[str, Any]:
    """Process each archive into ``out/<archive>/`` (module docstring); returns the
    campaign report, also written to ``out/campaign.json``. The campaign is built beside
    ``out`` and replaces it whole once complete; one with failed archives is not published
    over an earlier campaign (:class:`StationError` naming them; the earlier one stays).

    The archives go in batches (one in process; twice as many as workers on Dask, so
    that the workers always have scenes while the next archives are planned): each is
    planned here (read lazily, GEO, its output directory), then every scene of the batch
    goes to ``runner`` as a task (:mod:`levels.tasks`). ``progress(done, total, what)``
    counts scenes (``total``: those of the archives planned so far): called while
    planning, after each scene, and at the end.
    """
    from station.reprocess import l0_stem

    names = [l0_stem(a) for a in archives]
    clashes = sorted({n for n in names if names.count(n) > 1})
    if clashes:
        raise StationError(
            f"archives with the same name would share a directory: {', '.join(clashes)}"
        )
    from station.flow import run_flow

    flow = Campaign(archives, names, options, progress, runner)
    return run_flow(flow, out, quicklooks=False, runner=runner)


class Campaign:
    """The campaign as a flow of the run skeleton (:mod:`station.flow`): its archives
    planned and made in batches by its own loop (:func:`_run`), its report."""

    report = CAMPAIGN

    def __init__(
        self,
        archives: list[Path],
        names: list[str],
        options: ProcessingOptions,
        progress: Callable[[int, int, str], None] | None,
        runner: Runner | None,
    ) -> None:
        self.archives, self.names, self.options = archives, names, options
        self.progress, self.runner = progress, runner
        self.target, self.previous = Path(), False
        self._body: dict[str, Any] = {}

    @property
    def owner(self) -> object:
        return CAMPAIGN_FORMAT

    def what(self, owner: object) -> str:
        return "a campaign"

    def inputs(self) -> list[Path]:
        dem = [Path(self.options.dem_path)] if self.options.dem_path else []
        return [*self.archives, *dem]

    def check(self, out: Path) -> None:
        self.target = out
        self.previous = out.is_dir() and any(out.iterdir())

    def catalog(self) -> tuple[str, str]:
        n = len(self.archives)
        return self.target.name, f"the products of a campaign of {n} archive(s)"

    def measure(self) -> Any:
        return None

    def acquire(self, stage: Path, state: FlowRun) -> None:
        """Every archive planned and made into ``stage/<name>/`` (:func:`_run`): nothing
        left for the skeleton's request."""
        self._body = _run(
            self.archives,
            self.names,
            self.target,
            stage,
            self.options,
            self.progress,
            self.runner,
        )

    def sections(self, stage: Path, result: Result, state: FlowRun) -> dict[str, object]:
        """The report; a campaign with failures is not published over a previous one."""
        failed = [a for a in self._body["archives"] if a["status"] != "ok"]
        if failed and self.previous:  # never a campaign with failures over a good one
            what = "; ".join(f"{a['name']}: {a['reason']}" for a in failed)
            message = (
                f"{len(failed)} of {len(self.archives)} archive(s) failed ({what}): not "
                "published over the previous campaign"
            )
            if any(a["kind"] == "internal error" for a in failed):
                raise RuntimeError(message)  # a bug made it fail: said as one
            raise StationError(message)
        return self._body


def _run(
    archives: list[Path],
    names: list[str],
    target: Path,
    stage: Path,
    options: ProcessingOptions,
    progress: Callable[[int, int, str], None] | None,
    runner: Runner | None,
) -> dict[str, object]:
    """:func:`run_campaign`'s archives made into ``stage``: the report's body, naming the
    paths in ``target``."""
    from levels.process import run_plans
    from station.reprocess import plan_reprocess

    clock = time.perf_counter
    t0 = clock()
    # archives go in batches: a year of passes is never planned, nor held, all at once
    workers = runner.workers if runner is not None else 1
    batch = 1 if workers <= 1 else 2 * workers
    entries: list[dict[str, Any]] = []
    done = total = 0
    what = ""

    def on_scene(_made: Any, _n: int) -> None:
        nonlocal done
        done += 1
        if progress is not None:
            progress(done, total, what)

    for first in range(0, len(archives), batch):
        plans = []
        for archive, name in zip(
            archives[first : first + batch], names[first : first + batch], strict=True
        ):
            if progress is not None:
                progress(done, total, f"GEO {name}")
            entry: dict[str, Any] = {"l0": str(archive), "name": name, "out": str(target / name)}
            t = clock()
            try:
                [plan] = plan_reprocess([archive], stage / name, options=options, names=[name])
            except Exception as exc:  # reported by name; the other archives go on
                entry.update(_failure(exc, traceback.format_exc()))
            else:
                plans.append((entry, plan))
            entry["time_s"] = clock() - t
            entries.append(entry)
        total += sum(len(plan.scenes) for _, plan in plans)
        last = min(first + batch, len(archives))
        what = (
            f"archive {last} of {len(archives)}"
            if batch == 1
            else (f"archives {first + 1}–{last} of {len(archives)}")
        )
        if progress is not None:
            progress(done, total, what)
        results = run_plans([plan for _, plan in plans], runner, on_scene)
        for (entry, _), result in zip(plans, results, strict=True):
            _record(entry, result, target / entry["name"])
    if progress is not None:
        progress(total, total, "")
    failed = [e for e in entries if e["status"] != "ok"]
    return {
        "options": dataclasses.asdict(options),
        "workers": workers,
        "archives": entries,
        "summary": {
            "archives": len(entries),
            "ok": len(entries) - len(failed),
            "failed": len(failed),
            "scenes": sum(e.get("scenes", 0) for e in entries),
            "products": sum(len(e.get("products", [])) for e in entries),
            "time_s": clock() - t0,
        },
    }


def _record(entry: dict[str, Any], result: Any, out: Path) -> None:
    """An archive's entry from what :func:`levels.process.run_plans` made of it."""
    from levels.process import PassProducts

    made = result if isinstance(result, PassProducts) else result.made[0]
    entry.update(
        status="ok",
        scenes=len(made.scenes),
        skipped=[dataclasses.asdict(s) for s in made.skipped],
        products=[
            {"scene": s.index, "level": lv, "path": str(out / p.name)}
            for s in made.scenes
            for lv, p in s.paths.items()
        ],
    )
    # the archive's processing time: GEO here, and its scene tasks wherever they ran
    entry["time_s"] += sum(sum(s.timings_s.values()) for s in made.scenes)
    if not isinstance(result, PassProducts):
        bugs = [f for f in result.failures if not f.bad_input]
        entry.update(
            status="failed",
            kind="internal error" if bugs else "bad input",
            reason=str(result),
            failed_scenes=[f.name for f in result.failures],
        )
        if bugs:
            entry["traceback"] = "".join(traceback.format_exception(bugs[0].error))


def _failure(exc: BaseException, trace: str) -> dict[str, Any]:
    """A campaign entry's failure: bad input (the library's own errors) or a bug."""
    if isinstance(exc, LevelsError | StationError | OSError):
        return {"status": "failed", "kind": "bad input", "reason": str(exc).splitlines()[0]}
    return {
        "status": "failed",
        "kind": "internal error",
        "reason": f"{type(exc).__name__}: {exc}",
        "traceback": trace,
    }
