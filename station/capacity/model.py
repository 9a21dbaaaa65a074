"""The station as a network of queues, in simpy: passes in, products out.

A pass of a satellite over the station (from its orbit and the antenna's elevation mask)
takes the antenna for its whole visibility; if the antenna is taken by another satellite's
pass or down for repair, the pass is lost. A daylight pass images with a programmed
probability; each of the satellite's HRVs then takes a segment of scenes (Poisson, at least
one, no longer than the pass) in P or XS, sent on its own channel to its own
demodulator-recorder chain (none free: that HRV's segment is lost). Then, per HRV segment:

    transcription (tape only; playback at a set speed, operators' hours)
    → ingest (decoding, L0 archive) → GEO (the segment's scenes) → scenes in the catalogue

A share of the scenes is ordered, each at one level with one priority, an exponential
delay after acquisition; an order waits for its scene's GEO, then takes a COR worker
(urgent orders first) for its level's processing, then an archive writer.

Every stage is a :class:`Stage`: a pool of identical units with a priority queue, failures
(each unit fails after an exponential time of mean MTBF, at the end of the job it is
running, and is repaired in an exponential time of mean MTTR, ahead of the queue), optional
operator hours (a job holding a unit waits for the shift to start), and its measurements:
time-weighted numbers in queue, in service and in the stage, arrivals, waits and sojourns,
all counted from the end of the warm-up. Service times are the calibrated means (this
code's own stages, :mod:`station.capacity.calibrate`) times the scenario's factors, drawn
from a gamma law of the scenario's coefficient of variation.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Generator
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import simpy

from levels.geometry.times import Epoch
from station.capacity.config import CapacityScenario
from station.capacity.stats import time_weighted
from station.scenario import GroundStationConfig

__all__ = ["LEVELS", "PassPattern", "Replication", "Service", "Shift", "Stage", "pass_pattern",
           "simulate"]

LEVELS = ("1A", "1B", "2A")
_DAY = 86400.0
#: A simpy process: a generator of events.
Process = Generator[simpy.Event, Any, Any]


@dataclass(frozen=True)
class Service:
    """Mean service times (s) on the calibration machine, per unit of work."""

    ingest_s_per_signal_s: float  # decoding one second of one HRV channel at 25 Mbit/s
    geo_s_per_scene: dict[str, float]  # per mode
    cor_s: dict[str, dict[str, float]]  # per mode, per level (everything from L0 up)
    archive_s: dict[str, dict[str, float]]  # writing one product, per mode and level
    machine: str = ""

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> Service:
        return cls(float(d["ingest_s_per_signal_s"]), dict(d["geo_s_per_scene"]),
                   {m: dict(v) for m, v in d["cor_s"].items()},
                   {m: dict(v) for m, v in d["archive_s"].items()}, str(d.get("machine", "")))


class Shift:
    """Operator hours: ``start_h`` to ``end_h`` local mean time, ``days_per_week`` days from
    Monday; ``t = 0`` falls on ``weekday0`` (0 = Monday) at 00:00 UTC."""

    def __init__(self, start_h: float, end_h: float, days_per_week: int, lon_rad: float,
                 weekday0: int) -> None:
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

    def __init__(self, env: simpy.Environment, name: str, units: int, warmup_s: float,
                 shift: Shift | None = None, sample_s: float = 3600.0) -> None:
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

    def take(self, duration_s: float) -> bool:
        """Take a free unit for ``duration_s`` now, or count a loss: no queue (an antenna
        or a recorder cannot wait for the satellite)."""
        if self.res.count >= self.units:
            if self.env.now >= self.warmup_s:
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


@dataclass(frozen=True, eq=False)
class PassPattern:
    """The passes over a station in one repeat cycle of the phased orbit."""

    aos_s: np.ndarray  # since the cycle's start
    duration_s: np.ndarray
    daylight: np.ndarray  # descending in daylight: the imaging passes
    cycle_s: float
    weekday0: int  # weekday of the cycle's start (0 = Monday)


@functools.lru_cache(maxsize=8)
def pass_pattern(gs: GroundStationConfig) -> PassPattern:
    """The passes over ``gs`` above its mask in one repeat cycle of the phased orbit.

    The orbit repeats its ground track every cycle (SPOT: 369 revolutions in 26 days), so
    a year is this pattern laid end to end; a satellite trailing by whole days on the same
    orbit has the same pattern, delayed.
    """
    from station.scenario import OrbitConfig, PassConfig, WorldConfig
    from station.spacecraft.orbit import TruthOrbit, mean_element_orbit, swath_centre_view
    from station.spacecraft.passes import find_passes

    # SPOT's phased orbit, placed as a default pass would place it (nadir view on the
    # default target); only its reference state matters: the cycle is propagated from it
    oc, pc = OrbitConfig(), PassConfig()
    epoch = Epoch(np.datetime64(pc.date_utc, "ns"), name="00:00 UTC of the pass day")
    o, _t = mean_element_orbit(oc, pc, epoch, (0.0, _DAY),
                               swath_centre_view(0.0, WorldConfig().base_height_m))
    cycle_s = oc.repeat_days * _DAY
    orbit = TruthOrbit(o.epoch, o.t_ref_s, o.r_ref_eci_m, o.v_ref_eci_m_per_s,
                       min(0.0, o.t_ref_s), cycle_s + _DAY)
    passes = [p for p in find_passes(orbit, gs.lat_rad, gs.lon_rad, gs.height_m,
                                     gs.elevation_mask_rad, 0.0, cycle_s + _DAY, step_s=20.0)
              if p.aos_s < cycle_s]
    return PassPattern(
        aos_s=np.array([p.aos_s for p in passes]),
        duration_s=np.array([p.duration_s for p in passes]),
        daylight=np.array([p.daylight and p.descending for p in passes]),
        cycle_s=cycle_s,
        weekday0=int((o.epoch.t0_utc.astype("datetime64[D]").astype(np.int64) + 3) % 7))


@dataclass
class Replication:
    """One run's figures: per stage, per level, and the station's totals."""

    stages: dict[str, dict[str, float]]
    levels: dict[str, dict[str, float]]
    station: dict[str, float]
    series: dict[str, tuple[list[float], list[int]]] = field(repr=False, default_factory=dict)


def _gamma(rng: np.random.Generator, mean: float, cv: float) -> float:
    if cv <= 0 or mean <= 0:
        return mean
    k = 1.0 / (cv * cv)
    return float(rng.gamma(k, mean / k))


def simulate(scn: CapacityScenario, service: Service, replication: int = 0) -> Replication:
    """One replication of the scenario (module docstring)."""
    rng = np.random.default_rng(np.random.SeedSequence(scn.seed, spawn_key=(replication,)))
    rng_plan, rng_service, rng_fail, rng_orders = rng.spawn(4)
    sim, res, sv = scn.simulation, scn.resources, scn.service
    warmup = sim.warmup_days * _DAY
    t_end = warmup + sim.days * _DAY
    pattern = pass_pattern(scn.ground_station)
    env = simpy.Environment()
    sh = scn.shifts
    shift = Shift(sh.start_h, sh.end_h, sh.days_per_week, scn.ground_station.lon_rad,
                  pattern.weekday0)
    sample = sim.queue_sample_h * 3600.0
    units = {"antenna": res.antennas, "recorder": res.recorders,
             "transcription": res.transcription_units, "ingest": res.ingest_workers,
             "geo": res.geo_workers, "cor": res.cor_workers, "archive": res.archive_writers}
    stages = {name: Stage(env, name, n, warmup, shift if name in sh.staffed else None, sample)
              for name, n in units.items()}
    if res.recording == "disk":
        del stages["transcription"]
    fl = scn.failures
    for name, st in stages.items():
        mtbf, mttr = getattr(fl, f"{name}_mtbf_s"), getattr(fl, f"{name}_mttr_s")
        if mtbf > 0 and mttr > 0:
            env.process(st.failures(mtbf, mttr, rng_fail.spawn(1)[0]))
    og = scn.outage
    if og.days > 0 and og.stage in stages:
        env.process(stages[og.stage].outage(warmup + og.start_day * _DAY, og.days * _DAY))

    latency: dict[str, list[float]] = {lv: [] for lv in LEVELS}
    in_sla: dict[str, list[bool]] = {lv: [] for lv in LEVELS}
    counts = {"passes": 0, "imaging_passes": 0, "segments": 0, "segments_lost": 0,
              "scenes": 0, "orders": 0, "products": 0}
    od, pl = scn.orders, scn.plan
    mix = np.cumsum(od.mix)

    def order(mode: str, t_acq: float, geo_done: simpy.Event) -> Process:
        delay = rng_orders.exponential(od.delay_mean_s) if od.delay_mean_s > 0 else 0.0
        level = LEVELS[int(np.searchsorted(mix, rng_orders.random() * mix[-1], side="right"))]
        urgent = rng_orders.random() < od.urgent_fraction
        yield env.timeout(delay)
        t_order = env.now
        if not geo_done.triggered:
            yield geo_done
        yield from stages["cor"].serve(
            _gamma(rng_service, service.cor_s[mode][level] * sv.scale_cor, sv.cv),
            priority=0 if urgent else 1)
        yield from stages["archive"].serve(
            _gamma(rng_service, service.archive_s[mode][level] * sv.scale_archive, sv.cv))
        if t_acq >= warmup:
            counts["products"] += 1
            latency[level].append(env.now - t_acq)
            k = LEVELS.index(level)  # its service level counts from the order
            in_sla[level].append(env.now - t_order <= od.service_level_s[k])

    def segment(mode: str, n_scenes: int) -> Process:
        signal_s = n_scenes * pl.scene_s
        if "transcription" in stages:
            yield from stages["transcription"].serve(signal_s / res.transcription_speed)
        ingest = max(signal_s, _gamma(rng_service, service.ingest_s_per_signal_s * signal_s
                                      * sv.scale_ingest, sv.cv))  # at least real time
        yield from stages["ingest"].serve(ingest)
        yield from stages["geo"].serve(_gamma(
            rng_service, service.geo_s_per_scene[mode] * n_scenes * sv.scale_geo, sv.cv))

    def hrv_channel(mode: str, n_scenes: int, t_acq: float, duration: float) -> None:
        if not stages["recorder"].take(duration):
            if t_acq >= warmup:
                counts["segments_lost"] += 1
            return
        if t_acq >= warmup:
            counts["segments"] += 1
            counts["scenes"] += n_scenes
        geo = env.process(segment(mode, n_scenes))
        for _ in range(n_scenes):
            if rng_orders.random() < od.ordered_fraction:
                if t_acq >= warmup:
                    counts["orders"] += 1
                env.process(order(mode, t_acq, geo))

    def one_pass(sat: Any, t_aos: float, duration: float, day: bool) -> None:
        """At AOS: the antenna, and each HRV's segment, or a loss."""
        counted = t_aos >= warmup
        counts["passes"] += counted
        imaging = (day or pl.night_passes_image) and rng_plan.random() < pl.imaging_probability
        if not imaging or not stages["antenna"].take(duration):
            return  # nothing programmed, or lost at the antenna (taken, or down)
        counts["imaging_passes"] += counted
        max_scenes = max(1, int(duration // pl.scene_s))
        for _ in range(sat.hrvs):
            n = min(max_scenes, max(1, int(rng_plan.poisson(pl.scenes_per_segment))))
            mode = "XS" if rng_plan.random() < sat.xs_fraction else "P"
            hrv_channel(mode, n, t_aos, duration)

    def passes_of(sat: Any) -> Process:
        """Each pass at its AOS, in order; a trailing satellite's first days are the end of
        its previous cycle."""
        k0 = -1
        offset = sat.cycle_offset_days * _DAY
        while True:
            base = k0 * pattern.cycle_s + offset
            for t, d, day in zip(pattern.aos_s + base, pattern.duration_s, pattern.daylight,
                                 strict=True):
                if t >= t_end:
                    return
                if t >= 0.0:
                    if t > env.now:
                        yield env.timeout(t - env.now)
                    one_pass(sat, t, d, bool(day))
            k0 += 1

    for sat in scn.satellites:
        env.process(passes_of(sat))
    env.run(until=t_end)

    figures = {name: st.figures(t_end) for name, st in stages.items()}
    levels = {}
    for lv in LEVELS:
        x = np.asarray(latency[lv]) / 3600.0
        levels[lv] = {"products": int(x.size), **(
            {f"latency_p{q}_h": float(np.percentile(x, q)) for q in (50, 90, 95, 99)}
            if x.size else {f"latency_p{q}_h": math.nan for q in (50, 90, 95, 99)}),
            "within_service_level": float(np.mean(in_sla[lv])) if in_sla[lv] else math.nan}
    days = sim.days
    station = {k: float(v) for k, v in counts.items()} | {
        "scenes_per_day": counts["scenes"] / days, "products_per_day": counts["products"] / days,
        "passes_lost": float(stages["antenna"].lost)}
    cor = stages["cor"]
    st, sq = np.asarray(cor.series_t), np.asarray(cor.series_wait, dtype=float)
    station["cor_backlog_growth_per_day"] = float(np.polyfit(st / _DAY, sq, 1)[0]) \
        if st.size > 2 else 0.0
    if og.days > 0 and og.stage in stages:
        station |= _clearing(stages[og.stage], warmup + og.start_day * _DAY, og.days * _DAY)
    series = {name: (s.series_t, s.series_wait) for name, s in stages.items()}
    return Replication(figures, levels, station, series)


def _clearing(stage: Stage, start_s: float, duration_s: float) -> dict[str, float]:
    """The backlog an outage left and how long after it the queue came back to its level
    of the week before (NaN: not within the run)."""
    t = np.asarray(stage.series_t)
    q = np.asarray(stage.series_wait, dtype=float)
    end = start_s + duration_s
    before = q[(t >= start_s - 7 * _DAY) & (t < start_s)]
    level = float(before.mean()) if before.size else 0.0
    after = (t >= end) & (q <= max(level, 0.0) + 0.5)
    peak = q[(t >= start_s) & (t <= end + _DAY)]
    cleared = t[after]
    return {"outage_backlog_peak": float(peak.max()) if peak.size else 0.0,
            "outage_clear_days": float((cleared[0] - end) / _DAY) if cleared.size else math.nan}
