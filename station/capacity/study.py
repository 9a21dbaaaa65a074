"""Capacity studies: replications with confidence intervals, what-if sweeps, and their
outputs (JSON, CSV, PNG): ``station capacity``.

Each replication is an independent run of :func:`~station.capacity.model.simulate` (its own
random streams); every figure is reported as the mean over the replications and the
half-width of its 95 % Student-t interval, given only from :data:`MIN_REPLICATIONS_CI`
replications on (fewer: the mean alone). A figure some replications cannot give (an
outage's backlog not cleared by the end of the horizon) is censored: said so, with how
many, and no mean (the mean of those that cleared would be biased low). A sweep repeats
that for each value of one key of the scenario (``resources.cor_workers=1,2,3,4``), or
for every combination of several (``--sweep`` given twice: a grid), with the same seeds
(common random numbers: the differences between values are not drowned in noise). Each
value ends with a verdict: stable, saturated (the COR backlog growing by so many jobs a
day, with its interval), or undecided.

Written to the output directory:

- ``summary.json``: the scenario, the service times used, and per sweep value the station's,
  stages' and levels' figures (mean and CI);
- ``stages.csv``, ``levels.csv``, ``station.csv``: the same, one row per value and figure;
- ``queues.csv``: the queue length of every stage over time (first replication);
- ``queues.png`` (the first value's; for a sweep also ``queues_<k>.png`` for the k-th
  value, each titled with it), ``latency.png`` and, for a sweep, ``sweep.png``: backlog
  growth of COR, its utilisation and the 2A latency against the swept value.
"""

from __future__ import annotations

import csv
import itertools
import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from levels.files import atomic_path, check_writable, plain, write_text
from levels.tasks import InProcess, Runner, TaskFailure, raise_first
from station.capacity.config import CapacityScenario, with_value
from station.capacity.model import LEVELS, Replication, Service, pass_patterns, simulate
from station.capacity.stats import mean_ci
from station.errors import ScenarioError

__all__ = [
    "MIN_REPLICATIONS_CI",
    "STABLE_GROWTH_PER_DAY",
    "load_service",
    "parse_sweep",
    "parse_sweeps",
    "run_study",
    "study_table",
    "verdict",
]

#: Replications from which a 95 % interval is given: with fewer, Student's t (12.7 for
#: two, 4.3 for three) makes an interval wider than what it bounds.
MIN_REPLICATIONS_CI = 5
#: A COR backlog whose growth lies within ± this many jobs a day (its whole interval) is
#: stable: the queue's slope over a year of a station that keeps up.
STABLE_GROWTH_PER_DAY = 0.5


def load_service(scn: CapacityScenario) -> Service:
    """The scenario's service-time file (``[service] file``)."""
    p = scn.path(scn.service.file)
    try:
        return Service.from_dict(json.loads(p.read_text(encoding="utf-8")))
    except FileNotFoundError:
        raise ScenarioError(
            f"[service] file = {scn.service.file!r}: {p} not found; "
            "make one with `station capacity calibrate --out FILE`"
        ) from None
    except (json.JSONDecodeError, UnicodeDecodeError, KeyError, TypeError, ValueError) as exc:
        raise ScenarioError(f"{p}: not a service-time file ({exc})") from None


def parse_sweep(text: str) -> tuple[str, list[str]]:
    """``SECTION.KEY=V1,V2,...`` → (``SECTION.KEY``, values as written)."""
    param, sep, values = text.partition("=")
    vals = [v.strip() for v in values.split(",") if v.strip()]
    if not sep or not vals or "." not in param:
        raise ScenarioError(
            f"--sweep {text!r}: expected SECTION.KEY=V1,V2,... (e.g. resources.cor_workers=1,2,3,4)"
        )
    return param.strip(), vals


def parse_sweeps(texts: list[str]) -> list[tuple[str, list[str]]]:
    """Several ``--sweep`` (a grid of their values); a key swept twice is refused."""
    sweeps = [parse_sweep(t) for t in texts]
    keys = [k for k, _ in sweeps]
    twice = sorted({k for k in keys if keys.count(k) > 1})
    if twice:
        raise ScenarioError(
            f"--sweep {twice[0]} given twice: give its values once (KEY=V1,V2,...); "
            "several --sweep of different keys make a grid"
        )
    return sweeps


def _ci(values: list[float]) -> dict[str, float]:
    """Mean and 95 % half-width over the replications (``n``: how many have the figure).
    A figure not every replication has is censored (an outage's backlog not cleared by
    the end of one): no mean, ``censored`` of them; no interval below
    :data:`MIN_REPLICATIONS_CI` replications."""
    n = int(np.isfinite(values).sum())
    if n < len(values):
        return {"mean": math.nan, "ci95": math.nan, "n": n, "censored": len(values) - n}
    m, h = mean_ci(values)
    return {"mean": m, "ci95": h if n >= MIN_REPLICATIONS_CI else math.nan, "n": n}


def _aggregate(reps: list[Replication]) -> dict[str, object]:
    stages = {
        name: {k: _ci([float(r.stages[name][k]) for r in reps]) for k in reps[0].stages[name]}
        for name in reps[0].stages
    }
    levels = {
        lv: {k: _ci([float(r.levels[lv][k]) for r in reps]) for k in reps[0].levels[lv]}
        for lv in LEVELS
    }
    station = {k: _ci([float(r.station[k]) for r in reps]) for k in reps[0].station}
    return {"stages": stages, "levels": levels, "station": station}


def run_study(
    scn: CapacityScenario,
    out_dir: str | Path | None = None,
    sweep: tuple[str, list[str]] | list[tuple[str, list[str]]] | None = None,
    replications: int | None = None,
    plots: bool = True,
    service: Service | None = None,
    runner: Runner | None = None,
) -> dict[str, object]:
    """Replicate the scenario (for each sweep value); write the outputs to ``out_dir``.

    Every replication of every sweep value is a task of ``runner`` (:mod:`levels.tasks`:
    in this process by default, else on a Dask cluster); each draws its own random
    streams from the seed and its number, so the figures do not depend on where it ran.
    A replication that fails is named once the others ended. ``sweep``: one key and its
    values, or several (every combination of their values, in order: a grid)."""
    if out_dir is not None:
        check_writable(out_dir)  # now, not after the simulation; made only when written
    service = service or load_service(scn)
    n = replications or scn.simulation.replications
    sweeps = [sweep] if isinstance(sweep, tuple) else list(sweep or [])
    param = " × ".join(k for k, _ in sweeps)
    variants = []
    for combo in itertools.product(*(vals for _, vals in sweeps)):
        variant = scn
        for (key, _), v in zip(sweeps, combo, strict=True):
            variant = with_value(variant, key, v)
        variants.append((" × ".join(combo), variant))
    runner = runner or InProcess()
    shared = runner.share(service)
    handles = {}
    for k, (value, variant) in enumerate(variants):
        patterns = runner.share(pass_patterns(variant))  # once here, not in every task
        for r in range(n):
            name = f"{scn.name}{f'-{param}={value}' if param else ''}-r{r}"
            handles[runner.submit(name, simulate, variant, shared, r, patterns)] = (k, r)
    reps: dict[tuple[int, int], Replication] = {}
    failures = []
    for handle, result in runner.completed(handles):
        if isinstance(result, TaskFailure):
            failures.append(result)
        else:
            reps[handles[handle]] = result
    if failures:
        raise_first(failures, "replication")
    runs = [
        {"value": value, **_aggregate([reps[k, r] for r in range(n)])}
        for k, (value, _) in enumerate(variants)
    ]
    for run in runs:
        run["verdict"] = verdict(run)
        stages: Any = run["stages"]  # the aggregate's nested figures
        cor = stages["cor"]
        run["checked"] = checked(cor["utilisation"]["mean"], int(cor["units"]["mean"]))
    first = reps[0, 0]
    summary = {
        "format": "spot-station-capacity",
        "format_version": 1,
        "scenario": {
            "name": scn.name,
            "file": Path(scn.source).name if scn.source else "",
            "sha256": scn.source_sha256,
            "seed": scn.seed,
        },
        "service": {"file": scn.service.file, "machine": service.machine},
        "simulated_days": scn.simulation.days,
        "warmup_days": scn.simulation.warmup_days,
        "replications": n,
        "sweep": param,
        "sweeps": [{"key": k, "values": v} for k, v in sweeps],
        "runs": runs,
    }
    if out_dir is not None:
        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        _write(out, summary, first)
        if plots:
            _plots(out, summary, [reps[k, 0] for k in range(len(variants))])
    return summary


def _write(out: Path, summary: dict[str, Any], first: Replication | None) -> None:
    write_text(out / "summary.json", json.dumps(summary, indent=2, default=_plain) + "\n")
    for kind in ("stages", "levels"):
        with atomic_path(out / f"{kind}.csv") as tmp, open(tmp, "w", newline="") as f:
            w = csv.writer(f)
            w.writerow([summary["sweep"] or "value", kind[:-1], "figure", "mean", "ci95", "n"])
            for run in summary["runs"]:
                for name, figs in run[kind].items():
                    for k, v in figs.items():
                        w.writerow(
                            [run["value"], name, k, _plain(v["mean"]), _plain(v["ci95"]), v["n"]]
                        )
    with atomic_path(out / "station.csv") as tmp, open(tmp, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow([summary["sweep"] or "value", "figure", "mean", "ci95", "n"])
        for run in summary["runs"]:
            for k, v in run["station"].items():
                w.writerow([run["value"], k, _plain(v["mean"]), _plain(v["ci95"]), v["n"]])
    if first is not None:
        names = list(first.series)
        t = first.series[names[0]][0]
        with atomic_path(out / "queues.csv") as tmp, open(tmp, "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(["day", *names])
            for i, ti in enumerate(t):
                w.writerow([round(ti / 86400.0, 4), *(first.series[k][1][i] for k in names)])


def _plain(x: Any) -> Any:
    """Figures as the CSVs and summary.json hold them: to 6 decimals, NaN as empty/null."""
    return plain(x, 6)


def _savefig(fig: Any, path: Path) -> None:
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, format="png")


def _plots(out: Path, summary: dict[str, Any], firsts: list[Replication]) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    name = summary["scenario"]["name"]
    sweep = summary["sweep"]
    for k, first in enumerate(firsts):
        value = summary["runs"][k]["value"]
        fig, ax = plt.subplots(figsize=(9, 4))
        for stage, (t, q) in first.series.items():
            if max(q, default=0) > 0:
                ax.step(np.asarray(t) / 86400.0, q, where="post", label=stage, lw=0.8)
        title = f"{name}: queues (replication 0)" + (f", {sweep} = {value}" if sweep else "")
        ax.set(xlabel="day", ylabel="jobs waiting", title=title)
        ax.legend(loc="upper left", fontsize=8)
        fig.tight_layout()
        if k == 0:
            _savefig(fig, out / "queues.png")
        if sweep:
            _savefig(fig, out / f"queues_{k}.png")
        plt.close(fig)
    run = summary["runs"][0]
    fig, ax = plt.subplots(figsize=(6, 4))
    qs = (50, 90, 95, 99)
    for i, lv in enumerate(LEVELS):
        means = [run["levels"][lv][f"latency_p{q}_h"]["mean"] for q in qs]
        ax.bar(np.arange(len(qs)) + 0.27 * (i - 1), means, 0.27, label=f"level {lv}")
    ax.set_xticks(range(len(qs)), [f"p{q}" for q in qs])
    ax.set(
        ylabel="hours from acquisition",
        title=f"{name}: latency to each level"
        + (f" ({summary['sweep']} = {run['value']})" if summary["sweep"] else ""),
    )
    ax.legend(fontsize=8)
    fig.tight_layout()
    _savefig(fig, out / "latency.png")
    plt.close(fig)
    if summary["sweep"]:
        _sweep_plot(out, summary, plt)


def _sweep_plot(out: Path, summary: dict[str, Any], plt: Any) -> None:
    values = [r["value"] for r in summary["runs"]]
    x = np.arange(len(values))
    growth = [r["station"]["cor_backlog_growth_per_day"] for r in summary["runs"]]
    lat = [r["levels"]["2A"]["latency_p95_h"] for r in summary["runs"]]
    util = [r["stages"]["cor"]["utilisation"]["mean"] for r in summary["runs"]]
    fig, ax = plt.subplots(figsize=(7, 4.2))
    ax.errorbar(
        x,
        [g["mean"] for g in growth],
        yerr=[0 if not math.isfinite(g["ci95"]) else g["ci95"] for g in growth],
        marker="o",
        capsize=3,
        color="C3",
        label="COR backlog growth (jobs/day)",
    )
    ax.axhline(0.0, color="grey", lw=0.6)
    ax.set(
        xlabel=summary["sweep"],
        ylabel="COR backlog growth, jobs per day",
        title=f"{summary['scenario']['name']}: sweep of {summary['sweep']}",
    )
    ax.set_xticks(x, values)
    ax2 = ax.twinx()
    ax2.plot(x, [v["mean"] for v in lat], "s--", color="C0", label="2A latency p95 (h)")
    ax2.set_yscale("log")
    ax2.set_ylabel("2A latency p95, hours (log)")
    for xi, u in zip(x, util, strict=True):
        ax.annotate(
            f"COR {100 * u:.0f} % busy",
            (xi, 0),
            textcoords="offset points",
            xytext=(0, 8),
            ha="center",
            fontsize=7,
        )
    lines = ax.get_legend_handles_labels()
    lines2 = ax2.get_legend_handles_labels()
    ax.legend(lines[0] + lines2[0], lines[1] + lines2[1], fontsize=8, loc="upper right")
    fig.tight_layout()
    _savefig(fig, out / "sweep.png")
    plt.close(fig)


def verdict(run: dict[str, Any]) -> str:
    """What a run's figures say of the station, in one line: saturated (the COR backlog
    grows, its whole interval above zero: by how much a day), stable (the whole interval
    within ± :data:`STABLE_GROWTH_PER_DAY` jobs a day), or undecided; none without an
    interval (fewer than :data:`MIN_REPLICATIONS_CI` replications)."""
    g = run["station"]["cor_backlog_growth_per_day"]
    busy = 100.0 * run["stages"]["cor"]["utilisation"]["mean"]
    m, h = g["mean"], g["ci95"]
    if not math.isfinite(h):
        return (
            f"no verdict: {g['n']} replication(s), intervals from {MIN_REPLICATIONS_CI} "
            f"(COR backlog growth {m:+.2f} jobs/day, COR {busy:.0f} % busy)"
        )
    if m - h > 0:
        return (
            f"saturated: the COR backlog grows by {m:.1f} ± {h:.1f} jobs a day without bound "
            f"(COR {busy:.0f} % busy)"
        )
    if abs(m) + h <= STABLE_GROWTH_PER_DAY:
        return f"stable: COR backlog growth {m:+.2f} ± {h:.2f} jobs a day (COR {busy:.0f} % busy)"
    return (
        f"undecided: COR backlog growth {m:+.2f} ± {h:.2f} jobs a day (COR {busy:.0f} % "
        "busy); more days or replications"
    )


#: The loads at which the model has been checked against the station it models (``station
#: day`` then ``station capacity validate``, ``tools/day_workers.py``: docs/day.md): COR
#: utilisation and workers of the days run.
CHECKED_COR_UTILISATION = (0.10, 0.35)
CHECKED_COR_WORKERS = (1, 3)


def checked(busy: float, workers: int) -> str:
    """Whether a run's load (its COR utilisation ``busy`` on ``workers``) lies where the
    model was checked against a day at the station (:data:`CHECKED_COR_UTILISATION`,
    :data:`CHECKED_COR_WORKERS`), in one line."""
    lo, hi = CHECKED_COR_UTILISATION
    w_lo, w_hi = CHECKED_COR_WORKERS
    where = (
        f"checked against a day at the station at COR {100 * lo:.0f}–{100 * hi:.0f} % "
        f"busy on {w_lo}–{w_hi} workers (docs/day.md)"
    )
    if lo <= busy <= hi and w_lo <= workers <= w_hi:
        return f"inside the load {where}"
    return (
        f"outside the load the model was {where}: COR {100 * busy:.0f} % busy on "
        f"{workers} workers here, a prediction not checked"
    )


def study_table(summary: dict[str, Any]) -> str:
    """The human summary of a study: per sweep value, the station, its stages, its levels."""
    n = summary["replications"]
    lines = [
        f"{summary['scenario']['name']}: {summary['simulated_days']:g} days after "
        f"{summary['warmup_days']:g} of warm-up, {n} replication(s); mean"
        + (
            " ± 95 % CI"
            if n >= MIN_REPLICATIONS_CI
            else f" (no intervals: {MIN_REPLICATIONS_CI} replications or more give them)"
        )
    ]

    def f(v: dict[str, float], spec: str = ".2f") -> str:
        m, h = v["mean"], v["ci95"]
        if not math.isfinite(m):
            return "—"
        return format(m, spec) + ("" if not math.isfinite(h) else f" ±{h:{spec}}")

    for run in summary["runs"]:
        st = run["station"]
        if summary["sweep"]:
            lines.append(f"— {summary['sweep']} = {run['value']}")
        lines.append(
            f"passes {f(st['passes'], '.0f')} (imaging {f(st['imaging_passes'], '.0f')}"
            f", lost at the antenna {f(st['passes_lost'], '.1f')}); scenes/day "
            f"{f(st['scenes_per_day'], '.1f')}, products/day "
            f"{f(st['products_per_day'], '.1f')}; COR backlog growth "
            f"{f(st['cor_backlog_growth_per_day'], '.3f')} jobs/day"
        )
        if "outage_clear_days" in st:
            clear = st["outage_clear_days"]
            when = (
                f"cleared {f(clear, '.1f')} days after it ended"
                if not clear.get("censored")
                else f"not cleared by the end of the horizon in {clear['censored']} of {n} "
                "replication(s) (censored: no mean; simulate more days)"
            )
            lines.append(f"outage: backlog peak {f(st['outage_backlog_peak'], '.0f')} jobs; {when}")
        lines.append(
            f"{'stage':>13} {'units':>5} {'busy %':>12} {'down %':>6} "
            f"{'queue mean':>14} {'p95':>5} {'max':>5} {'wait h':>14} {'L/λW':>6}"
        )
        for name, s in run["stages"].items():
            lw = s["little_lambda_W"]["mean"]
            little = s["little_L"]["mean"] / lw if lw > 0 else math.nan
            lines.append(
                f"{name:>13} {s['units']['mean']:5.0f} "
                f"{f({k: 100 * v for k, v in s['utilisation'].items()}, '.1f'):>12} "
                f"{100 * s['down_fraction']['mean']:6.2f} {f(s['queue_mean']):>14} "
                f"{s['queue_p95']['mean']:5.1f} {s['queue_max']['mean']:5.0f} "
                f"{f(s['wait_mean_h']):>14} {little:6.3f}"
            )
        lines.append(
            f"{'level':>13} {'products':>8} {'p50 h':>12} {'p90 h':>12} {'p95 h':>12} "
            f"{'p99 h':>12} {'within service level':>21}"
        )
        for lv, v in run["levels"].items():
            lines.append(
                f"{lv:>13} {v['products']['mean']:8.0f} "
                + " ".join(f"{f(v[f'latency_p{q}_h'], '.1f'):>12}" for q in (50, 90, 95, 99))
                + f" {f({k: 100 * x for k, x in v['within_service_level'].items()}, '.1f'):>19} %"
            )
        lines.append(f"verdict: {run['verdict']}")
        lines.append(f"checked: {run['checked']}")
    return "\n".join(lines)
