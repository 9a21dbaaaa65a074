"""A day's report from its plan and events: per stage utilisation, waits and queue lengths
over time, per level latencies from acquisition and from order, the backlog at the end,
and what was made, listed or failed (``<out>/day.json``, ``<out>/queues.png``).

Every time is station time (the wall clock times the day's clock, from the window's
start), in hours in the report. A stage's unit is busy:

- **ingest**: a channel, from its stream's first byte at the front end to its archive
  written (``live.json``: ``archived_s``);
- **geo**: from then to its scenes catalogued as GEO places them (``catalogued_s``);
- **cor**: a worker, from an order's dispatch to its product made and catalogued (the
  job's end as its worker ends it, not as the day's loop sees it a tick later).

A stage's utilisation is its units' busy time within the window over units × window; a
wait is from an order's scene being ready (ordered, and its pass catalogued) to its
dispatch; latency from acquisition counts from the pass's AOS, from order from the order.
"""

from __future__ import annotations

import bisect
from pathlib import Path

import numpy as np

from station.capacity.plan import DayPlan
from station.day.config import DayScenario

__all__ = ["LEVELS", "day_report", "measure", "write_report"]

LEVELS = ("1A", "1B", "2A")
QUANTILES = (50, 95)


class _Timeline:
    """Wall clock → station time, through the day's starts (a resumed day has several)."""

    def __init__(self, events: list[dict]) -> None:
        starts = sorted(
            (e["unix"], e["station_s"], e["clock"]) for e in events if e["event"] == "start"
        )
        self.walls = [s[0] for s in starts]
        self.starts = starts

    def __call__(self, unix: float) -> float:
        k = max(0, bisect.bisect_right(self.walls, unix) - 1)
        wall0, station0, clock = self.starts[k]
        return station0 + (unix - wall0) * clock


def _busy(intervals: list[tuple[float, float]], end_s: float) -> float:
    return float(sum(max(0.0, min(b, end_s) - max(a, 0.0)) for a, b in intervals))


def _stats(x: list[float]) -> dict[str, object]:
    a = np.asarray(x, dtype=float) / 3600.0
    if not a.size:
        return {"n": 0, "mean_h": None, **{f"p{q}_h": None for q in QUANTILES}}
    return {
        "n": int(a.size),
        "mean_h": float(a.mean()),
        **{f"p{q}_h": float(np.percentile(a, q)) for q in QUANTILES},
    }


def _queue(up: list[float], down: list[float], end_s: float) -> dict[str, object]:
    """A queue's length over [0, end] from its arrivals and departures: its time-weighted
    mean, its maximum, and the series (hours, length) at each change."""
    times = np.r_[np.asarray(up, float), np.asarray(down, float)]
    steps = np.r_[np.ones(len(up)), -np.ones(len(down))]
    order = np.argsort(times, kind="stable")
    t, n = times[order], np.cumsum(steps[order])
    edges = np.clip(np.r_[0.0, t, end_s], 0.0, end_s)
    lengths = np.r_[0.0, n]
    mean = float(np.sum(np.diff(edges) * lengths) / end_s) if end_s > 0 else 0.0
    return {
        "mean": mean,
        "max": float(n.max()) if n.size else 0.0,
        "series_h": [[round(float(a) / 3600.0, 5), int(b)] for a, b in zip(t, n, strict=True)],
    }


def _last_events(events: list[dict]) -> dict[str, dict[str, dict]]:
    """Each order's last event of each kind."""
    last: dict[str, dict[str, dict]] = {}
    for e in events:
        if "order" in e:
            last.setdefault(e["order"], {})[e["event"]] = e
    return last


def _orders(plan: DayPlan, last: dict[str, dict[str, dict]], at: _Timeline) -> tuple:
    """The orders made: each's unit held (dispatch to return), its wait, its queue's
    arrivals and departures, and the latencies per level of those made in the window."""
    end_s = plan.hours * 3600.0
    aos = {p.name: p.aos_s for p in plan.passes}
    orders = {o.name: o for o in plan.orders}
    cor, waits, ready_t, dispatch_t = [], [], [], []
    lat_acq: dict[str, list[float]] = {lv: [] for lv in LEVELS}
    lat_order: dict[str, list[float]] = {lv: [] for lv in LEVELS}
    for name, ev in last.items():
        if "made" not in ev:
            continue
        m = ev["made"]
        o = orders[name]
        d, r = at(m["dispatched_unix"]), at(m["returned_unix"])
        cor.append((d, at(m.get("finished_unix", m["returned_unix"]))))  # the worker held
        if "ready" in ev:
            ready = ev["ready"]["station_s"]
            waits.append(max(0.0, d - ready))
            ready_t.append(ready)
            dispatch_t.append(d)
        if r <= end_s:
            lat_acq[o.level].append(r - aos[o.pass_name])
            lat_order[o.level].append(r - o.order_s)
    return cor, waits, ready_t, dispatch_t, lat_acq, lat_order


def measure(scn: DayScenario, plan: DayPlan, events: list[dict]) -> dict[str, object]:
    """The day's measured figures (module docstring)."""
    at = _Timeline(events)
    end_s = plan.hours * 3600.0
    ingest, geo = [], []
    for e in events:
        if e["event"] == "archived":
            for c in e["channels"]:
                t0 = c["started_unix"]
                ingest.append((at(t0), at(t0 + c["archived_s"])))
                geo.append((at(t0 + c["archived_s"]), at(t0 + c["catalogued_s"])))
    last = _last_events(events)
    made_events = [e for e in events if e["event"] == "made"]
    cor, waits, ready_t, dispatch_t, lat_acq, lat_order = _orders(plan, last, at)
    units = {
        "ingest": scn.capacity.resources.ingest_workers,
        "geo": scn.capacity.resources.geo_workers,
        "cor": scn.day.workers,
    }
    intervals = {"ingest": ingest, "geo": geo, "cor": cor}
    stages = {}
    for name, iv in intervals.items():
        w = waits if name == "cor" else [0.0] * len(iv)
        stages[name] = {
            "units": units[name],
            "jobs": len(iv),
            "utilisation": _busy(iv, end_s) / (units[name] * end_s),
            "service_mean_s": float(np.mean([b - a for a, b in iv])) / scn.day.clock
            if iv
            else None,
            "wait": _stats(w),
        }
    queue = _queue(ready_t, dispatch_t, end_s)
    stages["cor"]["queue"] = {"mean": queue["mean"], "max": queue["max"]}
    in_window = [o for o in plan.orders if o.order_s < end_s]
    backlog = sum(
        1
        for o in in_window
        if "made" not in last.get(o.name, {}) or at(last[o.name]["made"]["returned_unix"]) > end_s
    )
    made_per_order: dict[str, int] = {}
    for e in made_events:
        made_per_order[e["order"]] = made_per_order.get(e["order"], 0) + 1
    levels = {
        lv: {"from_acquisition": _stats(lat_acq[lv]), "from_order": _stats(lat_order[lv])}
        for lv in LEVELS
    }
    counts = {
        "passes": len(plan.passes),
        "passes_archived": len({e["pass"] for e in events if e["event"] == "archived"}),
        "passes_lost_at_antenna": plan.passes_lost,
        "segments": sum(len(p.segments) for p in plan.passes),
        "scenes": sum(s.scenes for p in plan.passes for s in p.segments),
        "orders": len(plan.orders),
        "orders_in_window": len(in_window),
        "urgent": sum(o.urgent for o in in_window),
        "made": len(made_per_order),
        "made_twice": sum(1 for n in made_per_order.values() if n > 1),
        "not_held": sum(1 for ev in last.values() if "not_held" in ev and "made" not in ev),
        "failed": sum(1 for ev in last.values() if "failed" in ev and "made" not in ev),
        "backlog_at_end": backlog,
        "runs": sum(1 for e in events if e["event"] == "start"),
    }
    return {
        "stages": stages,
        "levels": levels,
        "counts": counts,
        "cor_queue_series_h": queue["series_h"],
    }


def day_report(
    scn: DayScenario, plan: DayPlan, events: list[dict], failures: list[str]
) -> dict[str, object]:
    """The report of a day (module docstring)."""
    from station.reports import DAY

    figures = measure(scn, plan, events)
    d = scn.day
    return DAY.header(
        day=scn.name,
        scenario={"file": Path(scn.source).name, "sha256": scn.source_sha256},
        window={"start_day": d.start_day, "start_h": d.start_h, "hours": d.hours},
        clock=d.clock,
        workers=d.workers,
        **figures,
        failures=failures,
    )


def write_report(out: Path, report: dict[str, object], plots: bool = True) -> Path:
    """``day.json`` and, with matplotlib, ``queues.png``."""
    from levels.files import write_json

    path = write_json(out / "day.json", report)
    if plots:
        _plot(out, report)
    return path


def _plot(out: Path, report: dict) -> None:
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return
    series = np.asarray(report["cor_queue_series_h"], dtype=float).reshape(-1, 2)
    fig, ax = plt.subplots(figsize=(8, 3))
    if series.size:
        ax.step(series[:, 0], series[:, 1], where="post")
    ax.set_xlabel("station time from the window's start (h)")
    ax.set_ylabel("orders waiting for a worker")
    ax.set_title(
        f"{report['day']}: COR queue ({report['workers']} workers, clock {report['clock']:g}x)"
    )
    fig.tight_layout()
    fig.savefig(out / "queues.png", dpi=100)
    plt.close(fig)
