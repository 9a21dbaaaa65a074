"""The capacity model checked against a day at the station: ``station capacity validate``.

The model is given the day's own plan (its passes, segments and orders, at their times:
a trace-driven run, only the service times are drawn), its units (the front end's two
channel threads for ingest and GEO, its workers for COR), its clock, and service times
measured on this machine on a calibration pass of their own
(:func:`station.day.calibrate.day_service`): never the day's. Its replications give, for
every figure, the model's mean and its 95 % prediction interval (the 2.5th and 97.5th
percentiles over the replications: where one day's figure should fall), and the measured
figure is said inside or not; a stage's utilisation is checked within
:data:`UTILISATION_TOLERANCE` of the model's mean.

The model of the day (:class:`PlannedSimulation`) is :class:`~station.capacity.model.
StationSimulation`'s stages with the plan's arrivals, in wall seconds:

- **ingest** of a segment: at least its signal's time on the clock (its seconds of signal
  over the clock: the sender's pace), else the measured time per second of signal;
- **GEO**: the measured time per scene, times the segment's scenes;
- **COR**: each order, at its time, once its segment's GEO is done, on a worker (urgent
  first), for its mode and level's measured time: reading the archive, GEO's set-up of
  the pass again, the level and its product written and catalogued.

Service times are drawn from a gamma law of the measured coefficient of variation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import simpy

from station.capacity.plan import DayPlan, PlannedOrder, PlannedPass
from station.capacity.stage import Process, Stage
from station.day.preflight import SCENE_S

__all__ = ["UTILISATION_TOLERANCE", "PlannedSimulation", "compare", "predict"]

#: A stage's measured utilisation within this share of the model's mean (the issue's 10 %).
UTILISATION_TOLERANCE = 0.10
#: The prediction interval's coverage.
COVERAGE = 0.95
LEVELS = ("1A", "1B", "2A")


def _gamma(rng: np.random.Generator, mean: float, cv: float) -> float:
    if cv <= 0 or mean <= 0:
        return mean
    k = 1.0 / (cv * cv)
    return float(rng.gamma(k, mean / k))


@dataclass(frozen=True)
class DayUnits:
    """The day's units per stage and its clock."""

    ingest: int
    geo: int
    cor: int
    clock: float


class PlannedSimulation:
    """One replication of the day's model (module docstring), in wall seconds."""

    def __init__(self, plan: DayPlan, units: DayUnits, service: dict, seed: int) -> None:
        self.plan, self.units, self.service = plan, units, service
        self.rng = np.random.default_rng(seed)
        self.env = env = simpy.Environment()
        self.t_end = plan.hours * 3600.0 / units.clock
        self.stages = {
            "ingest": Stage(env, "ingest", units.ingest, 0.0),
            "geo": Stage(env, "geo", units.geo, 0.0),
            "cor": Stage(env, "cor", units.cor, 0.0),
        }
        self.latency: dict[str, list[float]] = {lv: [] for lv in LEVELS}
        self.from_order: dict[str, list[float]] = {lv: [] for lv in LEVELS}

    def _draw(self, entry: dict[str, float], times: float = 1.0) -> float:
        return _gamma(self.rng, entry["mean_s"] * times, entry["cv"])

    def segment(self, mode: str, scenes: int) -> Process:
        signal_s = scenes * SCENE_S + 0.2
        ingest = max(
            signal_s / self.units.clock, self._draw(self.service["ingest_s_per_signal_s"], signal_s)
        )
        yield from self.stages["ingest"].serve(ingest)
        yield from self.stages["geo"].serve(
            self._draw(self.service["geo_s_per_scene"][mode], scenes)
        )

    def order(self, o: PlannedOrder, p: PlannedPass, mode: str, geo: simpy.Event) -> Process:
        env, c = self.env, self.units.clock
        yield env.timeout(max(0.0, o.order_s / c - env.now))
        if not geo.triggered:
            yield geo
        yield from self.stages["cor"].serve(
            self._draw(self.service["cor_s"][mode][o.level]), priority=0 if o.urgent else 1
        )
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
            for s in p.segments:
                geo = env.process(self.segment(s.mode, s.scenes))
                for o in by_segment.get((p.name, s.hrv), []):
                    env.process(self.order(o, p, s.mode, geo))

    def run(self) -> dict[str, float]:
        """The replication's figures (station hours for waits and latencies)."""
        self.env.process(self.arrivals())
        self.env.run(until=self.t_end)
        c = self.units.clock
        out: dict[str, float] = {}
        for name, st in self.stages.items():
            f = st.figures(self.t_end)
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
    """Every figure over ``replications`` runs of the day's model."""
    runs = [PlannedSimulation(plan, units, service, seed + k).run() for k in range(replications)]
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
        what, _, figure = key.partition(".")
        row: dict[str, object] = {
            "stage" if what in ("ingest", "geo", "cor") else "level": what,
            "figure": figure,
            "measured": m,
            "predicted": mean,
            "interval": [lo, hi],
            "inside": bool(lo <= m <= hi),
        }
        if figure == "utilisation":
            rel = abs(m - mean) / mean if mean > 0 else math.inf
            row["relative_error"] = rel
            row["inside"] = bool(rel <= UTILISATION_TOLERANCE)
        rows.append(row)
    return rows
