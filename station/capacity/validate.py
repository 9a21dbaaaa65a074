"""The capacity model checked against a day at the station: ``station capacity validate``.

The model is given the day's own plan (its passes, segments and orders, at their times:
a trace-driven run, only the service times are drawn), its units (the front end's two
channel threads for ingest and GEO, its workers for COR), its clock, and service times
measured on this machine on a calibration pass of their own
(:func:`station.day.calibrate.day_service`): never the day's. Its replications give, for
every figure, the model's mean and its 95 % prediction interval (the 2.5th and 97.5th
percentiles over the replications: where one day's figure should fall), and the measured
figure is said inside or not; a stage's utilisation is checked within
:data:`UTILISATION_TOLERANCE` of the model's mean, or inside its interval where that is
wider: a stage of few short jobs (GEO: a dozen channels of 50 ms, spread 30 %) cannot be
measured on one day within 10 % of anything, its own mean included.

The model of the day (:class:`PlannedSimulation`) is :class:`~station.capacity.model.
StationSimulation`'s stages with the plan's arrivals, in wall seconds:

- **ingest** of a segment: at least its signal's time on the clock (its seconds of signal
  over the clock: the sender's pace), else the measured law: a fixed cost, a cost a second
  of its pass's signal, less what the fill after its own scenes saves;
- **GEO**: a channel's measured fixed cost and its cost a scene, times its scenes; ingest
  and GEO are the front end's one process, processor-shared (:class:`SharedStage`'s
  companions), and slowed by the workers' jobs on the same cores;
- **COR**: each order, at its time, once its segment's GEO is done, on a worker (urgent
  first), for its mode and level's measured time, and its cost a scene of the archive
  (the job reads the archive whole and sets GEO up for its pass): the level and its
  product written and catalogued.

Service times are drawn from a gamma law of the measured coefficient of variation.
"""

from __future__ import annotations

import heapq
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np
import simpy

from station.capacity.model import gamma_time
from station.capacity.plan import DayPlan, PlannedOrder, PlannedPass
from station.capacity.stage import Process
from station.day.preflight import SCENE_S
from station.day.run import TICK_S

__all__ = [
    "UTILISATION_TOLERANCE",
    "PlannedSimulation",
    "as_day",
    "compare",
    "cor_mean_s",
    "own_days",
    "predict",
]

#: A stage's measured utilisation within this share of the model's mean (the issue's 10 %).
UTILISATION_TOLERANCE = 0.10
#: The prediction interval's coverage.
COVERAGE = 0.95
LEVELS = ("1A", "1B", "2A")


@dataclass(frozen=True)
class DayUnits:
    """The day's units per stage and its clock."""

    ingest: int
    geo: int
    cor: int
    clock: float


def cor_mean_s(entry: Mapping[str, float], scenes: int) -> float:
    """An order kind's calibrated mean time (``cor_s``'s entry) on an archive of ``scenes``
    scenes: its time on the calibration's archive and its cost an archive scene."""
    per = float(entry.get("s_per_archive_scene", 0.0))
    return max(0.0, float(entry["mean_s"]) + per * (scenes - entry.get("archive_scenes", scenes)))


class SharedStage:
    """A pool of ``units`` on one machine, processor-shared: ``n`` jobs running at once each
    progress at ``1 / slowdown[n]`` of their speed alone, and slower still by ``load()``
    when given (another stage's jobs on the same cores); a priority queue before it (urgent
    first, then in turn). Its measurements as :class:`Stage`'s: utilisation (the
    time-average of the units held over the units) and waits. The jobs of ``companions``
    (stages in the same process: the front end's ingest and GEO) count in ``n``. A stage
    whose jobs slow this one's tells it before each change (``listeners``)."""

    def __init__(
        self,
        env: simpy.Environment,
        units: int,
        slowdown: dict[int, float],
        load: Callable[[], float] | None = None,
    ) -> None:
        self.env, self.units, self.load = env, units, load
        self.slowdown = {1: 1.0, **slowdown}
        self.queue: list[tuple[int, int, float, simpy.Event, float]] = []
        self.running: dict[int, tuple[float, simpy.Event]] = {}
        self.listeners: list[SharedStage] = []
        self.companions: list[SharedStage] = []
        self.waits: list[float] = []
        self.area_busy = 0.0
        self._t = 0.0
        self._seq = 0
        self._poke = env.event()
        env.process(self._run())

    def serve(self, work_s: float, priority: int = 0) -> Process:
        done = self.env.event()
        self._seq += 1
        heapq.heappush(self.queue, (priority, self._seq, work_s, done, self.env.now))
        self.poke()
        yield done

    def poke(self) -> None:
        if not self._poke.triggered:
            self._poke.succeed()

    def _rate(self) -> float:
        n = len(self.running) + sum(len(c.running) for c in self.companions)
        top = max(self.slowdown)
        factor = self.slowdown.get(n, self.slowdown[top] * n / top)  # beyond: shared evenly
        return 1.0 / (factor * (self.load() if self.load is not None else 1.0))

    def advance(self) -> None:
        dt = self.env.now - self._t
        if dt > 0 and self.running:
            step = dt * self._rate()
            self.running = {k: (w - step, d) for k, (w, d) in self.running.items()}
            self.area_busy += len(self.running) * dt
        self._t = self.env.now

    def _run(self) -> Process:
        env = self.env
        while True:
            self.advance()
            ended = [k for k, (w, _) in self.running.items() if w <= 1e-12]
            starting = self.queue and len(self.running) - len(ended) < self.units
            changed = bool(ended or starting)
            if changed:
                for other in self.listeners:  # at the old rate up to now
                    other.advance()
            for k in ended:
                self.running.pop(k)[1].succeed()
            while self.queue and len(self.running) < self.units:
                _, seq, work_s, done, t0 = heapq.heappop(self.queue)
                self.waits.append(env.now - t0)
                self.running[seq] = (work_s, done)
            if changed:
                for other in self.listeners:  # at the new rate from now
                    other.poke()
            if self._poke.triggered:
                self._poke = env.event()
            if self.running:
                nearest = min(w for w, _ in self.running.values()) / self._rate()
                yield env.timeout(max(nearest, 0.0)) | self._poke
            else:
                yield self._poke

    def figures(self, t_end: float) -> dict[str, float]:
        self.advance()
        w = np.asarray(self.waits)
        return {
            "utilisation": self.area_busy / (self.units * t_end),
            "wait_mean_h": float(w.mean()) / 3600.0 if w.size else 0.0,
        }


class PlannedSimulation:
    """One replication of the day's model (module docstring), in wall seconds."""

    def __init__(
        self, plan: DayPlan, units: DayUnits, service: dict, seed: int, tick_s: float = TICK_S
    ) -> None:
        self.plan, self.units, self.service, self.tick_s = plan, units, service, tick_s
        self.rng = np.random.default_rng(seed)
        self.env = env = simpy.Environment()
        self.t_end = plan.hours * 3600.0 / units.clock
        slowdown = {int(k): float(v) for k, v in service.get("cor_contention", {}).items()}
        ingesting = float(service.get("cor_slowdown_ingesting", 1.0))

        def front_end_busy() -> float:  # the front end decoding slows the workers' jobs
            return ingesting if self.ingest.running or self.geo.running else 1.0

        self.cor = SharedStage(env, units.cor, slowdown, front_end_busy)
        ing = service["ingest"]
        busy = float(ing.get("slowdown_workers_busy", 1.0))

        def cores_taken() -> float:  # the workers' jobs slow the front end as measured
            return 1.0 + (busy - 1.0) * min(1.0, len(self.cor.running) / units.cor)

        channels = {2: float(ing.get("slowdown_two_channels", 1.0))}
        self.ingest = SharedStage(env, units.ingest, channels, cores_taken)
        self.geo = SharedStage(env, units.geo, channels, cores_taken)  # the same process
        self.ingest.companions.append(self.geo)
        self.geo.companions.append(self.ingest)
        self.cor.listeners += [self.ingest, self.geo]
        self.ingest.listeners += [self.cor, self.geo]
        self.geo.listeners += [self.cor, self.ingest]
        # this replication's means: the calibration's samples resampled (the uncertainty of
        # means measured on a few jobs belongs in the interval)
        self.cor_means = {
            mode: {lv: self._resampled(e) for lv, e in levels.items()}
            for mode, levels in service["cor_s"].items()
        }
        self.latency: dict[str, list[float]] = {lv: [] for lv in LEVELS}
        self.from_order: dict[str, list[float]] = {lv: [] for lv in LEVELS}

    def _resampled(self, entry: dict) -> dict[str, float]:
        samples = np.asarray(entry.get("samples_s", [entry["mean_s"]]), float)
        mean = float(self.rng.choice(samples, samples.size).mean())
        return {
            "mean_s": mean,
            "cv": float(entry["cv"]),
            "archive_scenes": float(entry.get("archive_scenes", 0.0)),
            "s_per_archive_scene": float(entry.get("s_per_archive_scene", 0.0)),
        }

    def _cor_time(self, mode: str, level: str, scenes: int) -> float:
        """A job's time: its kind's, on an archive of the segment's ``scenes`` (the job
        reads its archive whole and sets GEO up for its pass)."""
        e = self.cor_means[mode][level]
        return gamma_time(self.rng, cor_mean_s(e, scenes), e["cv"])

    def _tick(self) -> float:
        """The day's loop sees an event at its next look (``station.day.run.TICK_S``)."""
        return float(self.rng.uniform(0.0, self.tick_s))

    def segment(self, mode: str, scenes: int, pass_scenes: int) -> Process:
        """A channel: its pass's signal (both channels of a pass are as long as its longest
        segment, the shorter's end is fill), then GEO of its own scenes."""
        ing = self.service["ingest"]
        signal_s = pass_scenes * SCENE_S + float(ing.get("lead_s", 0.2))
        fill_s = (pass_scenes - scenes) * SCENE_S
        beside = (
            ing["fixed_s"] + ing["s_per_signal_s"] * signal_s - ing.get("fill_saving", 0.0) * fill_s
        )
        alone = beside / ing.get("slowdown_two_channels", 1.0)  # measured two at once
        ingest = max(signal_s / self.units.clock, gamma_time(self.rng, alone, ing["cv"]))
        yield from self.ingest.serve(ingest)
        geo = self.service["geo"][mode]  # a channel's fixed cost and its cost a scene
        t = geo["fixed_s"] + geo["s_per_scene"] * scenes
        yield from self.geo.serve(gamma_time(self.rng, t, geo["cv"]))

    def order(
        self, o: PlannedOrder, p: PlannedPass, mode: str, scenes: int, geo: simpy.Event
    ) -> Process:
        env, c = self.env, self.units.clock
        yield env.timeout(max(0.0, o.order_s / c - env.now))
        if not geo.triggered:  # the pass archived and catalogued, every channel of it
            yield geo
        yield env.timeout(self._tick())  # seen by the day's loop
        yield from self.cor.serve(
            self._cor_time(mode, o.level, scenes), priority=0 if o.urgent else 1
        )
        yield env.timeout(self._tick())  # its end seen by the loop
        if env.now <= self.t_end:
            self.latency[o.level].append(env.now - p.aos_s / c)
            self.from_order[o.level].append(env.now - o.order_s / c)

    def arrivals(self) -> Process:
        env, c = self.env, self.units.clock
        by_segment: dict[tuple[str, int], list[PlannedOrder]] = {}
        for o in self.plan.orders:
            by_segment.setdefault((o.pass_name, o.hrv), []).append(o)
        for p in sorted(self.plan.passes, key=lambda p: p.aos_s):
            yield env.timeout(max(0.0, p.aos_s / c - env.now))
            longest = max(s.scenes for s in p.segments)
            geo = env.all_of(
                [env.process(self.segment(s.mode, s.scenes, longest)) for s in p.segments]
            )
            for s in p.segments:
                for o in by_segment.get((p.name, s.hrv), []):
                    env.process(self.order(o, p, s.mode, s.scenes, geo))

    def run(self) -> dict[str, float]:
        """The replication's figures (station hours for waits and latencies)."""
        self.env.process(self.arrivals())
        self.env.run(until=self.t_end)
        c = self.units.clock
        out: dict[str, float] = {}
        figures = {
            name: st.figures(self.t_end)
            for name, st in (("ingest", self.ingest), ("geo", self.geo), ("cor", self.cor))
        }
        for name, f in figures.items():
            out[f"{name}.utilisation"] = f["utilisation"]
            out[f"{name}.wait_mean_h"] = f["wait_mean_h"] * c
        for lv in LEVELS:
            for what, x in (
                ("from_acquisition", self.latency[lv]),
                ("from_order", self.from_order[lv]),
            ):
                a = np.asarray(x) * c / 3600.0
                out[f"{lv}.{what}.mean_h"] = float(a.mean()) if a.size else math.nan
                out[f"{lv}.{what}.p95_h"] = float(np.percentile(a, 95)) if a.size else math.nan
        return out


def predict(
    plan: DayPlan, units: DayUnits, service: dict, replications: int, seed: int
) -> dict[str, np.ndarray]:
    """Every figure over ``replications`` runs of the day's model. A service table of
    several calibration sessions (``sessions``) gives each its share of the replications:
    the machine's variability from one session to the next is in the interval too."""
    tables = service.get("sessions", [service])
    runs = [
        PlannedSimulation(plan, units, tables[k % len(tables)], seed + k).run()
        for k in range(replications)
    ]
    return {key: np.array([r[key] for r in runs]) for key in runs[0]}


def _measured(day: dict) -> dict[str, float]:
    out: dict[str, float] = {}
    for name, s in day["stages"].items():
        out[f"{name}.utilisation"] = s["utilisation"]
        out[f"{name}.wait_mean_h"] = s["wait"]["mean_h"] or 0.0
    for lv, s in day["levels"].items():
        for what in ("from_acquisition", "from_order"):
            for stat in ("mean_h", "p95_h"):
                v = s[what][stat]
                out[f"{lv}.{what}.{stat}"] = math.nan if v is None else v
    return out


def compare(day: dict, predicted: dict[str, np.ndarray]) -> list[dict[str, object]]:
    """Each figure measured beside predicted: the model's mean, its interval, inside."""
    measured = _measured(day)
    rows = []
    lo_q, hi_q = 50.0 * (1 - COVERAGE), 100.0 - 50.0 * (1 - COVERAGE)
    for key, values in predicted.items():
        m = measured.get(key, math.nan)
        v = values[np.isfinite(values)]
        if not v.size or not math.isfinite(m):
            continue
        mean = float(v.mean())
        lo, hi = float(np.percentile(v, lo_q)), float(np.percentile(v, hi_q))
        lo, hi = min(lo, mean), max(hi, mean)  # a constant figure: one rounding apart
        what, _, figure = key.partition(".")
        row: dict[str, object] = {
            "stage" if what in ("ingest", "geo", "cor") else "level": what,
            "figure": figure,
            "measured": m,
            "predicted": mean,
            "interval": [lo, hi],
            "inside": bool(lo <= m <= hi),
        }
        if figure == "utilisation":  # within 10 %, or its interval where that is wider
            rel = abs(m - mean) / mean if mean > 0 else math.inf
            row["relative_error"] = rel
            row["inside"] = bool(rel <= UTILISATION_TOLERANCE or lo <= m <= hi)
        rows.append(row)
    return rows


def as_day(figures: Mapping[str, float]) -> dict[str, dict]:
    """One replication's figures as a day's report holds them (what :func:`compare`
    reads): a day played by the model itself."""
    return {
        "stages": {
            s: {
                "utilisation": figures[f"{s}.utilisation"],
                "wait": {"mean_h": figures[f"{s}.wait_mean_h"]},
            }
            for s in ("ingest", "geo", "cor")
        },
        "levels": {
            lv: {
                w: {"mean_h": figures[f"{lv}.{w}.mean_h"], "p95_h": figures[f"{lv}.{w}.p95_h"]}
                for w in ("from_acquisition", "from_order")
            }
            for lv in LEVELS
        },
    }


def own_days(predicted: dict[str, np.ndarray], days: dict[str, np.ndarray]) -> np.ndarray:
    """How many figures of each of the model's own days (replications of seeds of their
    own, ``days``) :func:`compare` finds inside: what a day the model describes exactly
    scores. With eighteen figures each inside 95 % of the time, and tied to each other,
    all eighteen inside is not what such a day gives every time."""
    n = len(next(iter(days.values())))
    return np.array(
        [
            sum(
                bool(r["inside"])
                for r in compare(as_day({k: v[j] for k, v in days.items()}), predicted)
            )
            for j in range(n)
        ]
    )
