"""A stage of the station as a queue: a pool of identical units with a priority queue,
failures and repairs, operators' hours, and the measurements of its load.

A unit fails after an exponential time of mean MTBF, at the end of the job it is running,
and is repaired in an exponential time of mean MTTR, ahead of the queue; a job holding a
unit of a staffed stage waits for the shift to start. Time-weighted numbers in queue, in
service and in the stage, arrivals, waits and sojourns are counted from the end of the
warm-up.
"""

from __future__ import annotations

import math
from collections.abc import Generator
from typing import Any

import numpy as np
import simpy

from station.capacity.stats import time_weighted

__all__ = ["Process", "Shift", "Stage", "mmc_wait_h"]

_DAY = 86400.0
#: A simpy process: a generator of events.
Process = Generator[simpy.Event, Any, Any]


class Shift:
    """Operator hours: ``start_h`` to ``end_h`` local mean time, ``days_per_week`` days from
    Monday; ``t = 0`` falls on ``weekday0`` (0 = Monday) at 00:00 UTC."""

    def __init__(
        self, start_h: float, end_h: float, days_per_week: int, lon_rad: float, weekday0: int
    ) -> None:
        self.start_s, self.end_s = start_h * 3600.0, end_h * 3600.0
        self.days = days_per_week
        self.offset_s = lon_rad / (2 * math.pi) * _DAY + weekday0 * _DAY

    def wait_s(self, t_s: float) -> float:
        """Time from ``t_s`` to the next moment on shift (0 if on shift now)."""
        local = t_s + self.offset_s
        day = math.floor(local / _DAY)
        for k in range(8):  # at most a week ahead
            d = day + k
            if d % 7 >= self.days:
                continue
            start, end = d * _DAY + self.start_s, d * _DAY + self.end_s
            if local < end:
                return max(0.0, start - local)
        raise AssertionError("a staffed day within a week")  # days_per_week >= 1


class Stage:
    """A pool of ``units`` identical servers with a priority queue, and its measurements
    (module docstring). ``shift``: jobs start only on shift."""

    def __init__(
        self,
        env: simpy.Environment,
        name: str,
        units: int,
        warmup_s: float,
        shift: Shift | None = None,
        sample_s: float = 3600.0,
    ) -> None:
        self.env, self.name, self.units = env, name, units
        self.res = simpy.PriorityResource(env, capacity=units)
        self.warmup_s, self.shift = warmup_s, shift
        self.n_wait = self.n_busy = self.n_down = 0
        self._t = warmup_s
        self.area_wait = self.area_busy = self.area_down = 0.0
        self.arrivals = 0
        self.waits: list[float] = []
        self.sojourns: list[float] = []
        self.lost = 0
        self._sample_s = sample_s
        self._next_sample = warmup_s
        self.series_t: list[float] = []
        self.series_wait: list[int] = []

    # -- bookkeeping: integrate the counts since the last change --------------------------
    def _advance(self) -> None:
        t = self.env.now
        if t > self.warmup_s:
            dt = t - max(self._t, self.warmup_s)
            self.area_wait += self.n_wait * dt
            self.area_busy += self.n_busy * dt
            self.area_down += self.n_down * dt
            while self._next_sample <= t:  # the queue as it stood at each sample time
                self.series_t.append(self._next_sample)
                self.series_wait.append(self.n_wait)
                self._next_sample += self._sample_s
        self._t = t

    def serve(self, service_s: float, priority: int = 0) -> Process:
        """Queue, (wait for the shift,) be served, leave: a simpy process."""
        env = self.env
        t0 = env.now
        self._advance()
        self.n_wait += 1
        req = self.res.request(priority=priority)
        yield req
        if self.shift is not None:
            off = self.shift.wait_s(env.now)
            if off > 0:
                yield env.timeout(off)
        self._advance()
        self.n_wait -= 1
        self.n_busy += 1
        t1 = env.now
        yield env.timeout(service_s)
        self.res.release(req)
        self._advance()
        self.n_busy -= 1
        if t0 >= self.warmup_s:
            self.arrivals += 1
            self.waits.append(t1 - t0)
            self.sojourns.append(env.now - t0)

    def take(self, duration_s: float, count_loss: bool = True) -> bool:
        """Take a free unit for ``duration_s`` now, or count a loss: no queue (an antenna
        or a recorder cannot wait for the satellite). ``count_loss=False``: the caller
        counts its own (another mission's passes)."""
        if self.res.count >= self.units:
            if count_loss and self.env.now >= self.warmup_s:
                self.lost += 1
            return False
        self.env.process(self.serve(duration_s))  # granted at once: a unit is free
        return True

    def failures(self, mtbf_s: float, mttr_s: float, rng: np.random.Generator) -> Process:
        """Failures of any of the units (rate units/MTBF) and their repairs, forever."""
        env = self.env
        while True:
            yield env.timeout(rng.exponential(mtbf_s / self.units))
            yield from self._down(rng.exponential(mttr_s))

    def _down(self, duration_s: float) -> Process:
        req = self.res.request(priority=-10)  # the repair goes before any queued job
        yield req
        self._advance()
        self.n_down += 1
        yield self.env.timeout(duration_s)
        self.res.release(req)
        self._advance()
        self.n_down -= 1

    def outage(self, start_s: float, duration_s: float) -> Process:
        """Every unit down from ``start_s`` for ``duration_s`` (each after its current job)."""
        yield self.env.timeout(start_s)
        for _ in range(self.units):
            self.env.process(self._down(duration_s))

    def figures(self, t_end: float) -> dict[str, float]:
        """The stage's measurements over [warm-up, t_end]."""
        self._advance()
        span = t_end - self.warmup_s
        w = np.asarray(self.waits)
        s = np.asarray(self.sojourns)
        q = time_weighted(self.series_t, self.series_wait, t_end, (0.95,))
        lam = self.arrivals / span
        in_stage = (self.area_wait + self.area_busy) / span
        return {
            "units": self.units,
            "utilisation": self.area_busy / (self.units * span),
            "down_fraction": self.area_down / (self.units * span),
            "arrivals_per_day": lam * _DAY,
            "lost": self.lost,
            "wait_mean_h": float(w.mean()) / 3600.0 if w.size else 0.0,
            "wait_p95_h": float(np.percentile(w, 95)) / 3600.0 if w.size else 0.0,
            "sojourn_mean_h": float(s.mean()) / 3600.0 if s.size else 0.0,
            "queue_mean": self.area_wait / span,
            "queue_p95": q["p95"],
            "queue_max": q["max"],
            # Little's law: L = λW, the time-average in the stage against rate × sojourn
            "little_L": in_stage,
            "little_lambda_W": lam * (float(s.mean()) if s.size else 0.0),
        }


def mmc_wait_h(arrival_rate: float, service_rate: float, c: int, n_jobs: int, seed: int) -> float:
    """Mean wait (h) of an M/M/c queue simulated through :class:`Stage`: Poisson arrivals,
    exponential service, ``c`` units, a warm-up of 200 arrivals (the check of the stage
    against Erlang C)."""
    env = simpy.Environment()
    stage = Stage(env, "mmc", c, warmup_s=200.0 / arrival_rate)
    rng = np.random.default_rng(seed)

    def arrivals() -> Process:
        for _ in range(n_jobs):
            yield env.timeout(rng.exponential(1.0 / arrival_rate))
            env.process(stage.serve(rng.exponential(1.0 / service_rate)))

    env.process(arrivals())
    env.run()
    return stage.figures(env.now)["wait_mean_h"]
