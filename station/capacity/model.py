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

Every stage is a :class:`~station.capacity.stage.Stage` (a pool of units with a priority
queue, failures, operators' hours and its measurements); the passes come from the orbit
(:mod:`station.capacity.passes`); :class:`StationSimulation` wires them into one
replication. Service times are the calibrated means (this
code's own stages, :mod:`station.capacity.calibrate`) times the scenario's factors, drawn
from a gamma law of the scenario's coefficient of variation.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import simpy

from levels.choices import Level
from levels.spot import MODES
from station.capacity.config import CapacityScenario, ServiceConfig
from station.capacity.passes import PassPattern, pass_pattern
from station.capacity.stage import Process, Shift, Stage
from station.errors import ScenarioError
from station.scenario import OrbitConfig

__all__ = [
    "LEVELS",
    "PassPattern",
    "Replication",
    "Service",
    "Shift",
    "Stage",
    "StationSimulation",
    "gamma_time",
    "pass_pattern",
    "pass_patterns",
    "simulate",
]

#: The levels ordered from the station (level 2 needs control points and its service time
#: is not calibrated yet: not in the capacity model).
LEVELS = (Level.L1A, Level.L1B, Level.L2A)

_DAY = 86400.0


@dataclass(frozen=True)
class Service:
    """Mean service times (s) on the calibration machine, per unit of work."""

    ingest_s_per_signal_s: float  # decoding one second of one HRV channel at 25 Mbit/s
    geo_s_per_scene: dict[str, float]  # per mode
    cor_s: dict[str, dict[str, float]]  # per mode, per level (everything from L0 up)
    archive_s: dict[str, dict[str, float]]  # writing one product, per mode and level
    machine: str = ""
    #: Raw lines one north-up 2A row reads, per mode, measured on this code's geometry at
    #: full size (INPE's 950 / 475 figure); empty in files that predate it.
    raw_lines_per_2a_row: dict[str, float] = field(default_factory=dict)
    #: Geocoding one full ERS-1 frame over a DEM (GTC, 12.5 m); 0 in files that predate it.
    sar_gtc_s_per_frame: float = 0.0

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> Service:
        return cls(
            float(d["ingest_s_per_signal_s"]),
            dict(d["geo_s_per_scene"]),
            {m: dict(v) for m, v in d["cor_s"].items()},
            {m: dict(v) for m, v in d["archive_s"].items()},
            str(d.get("machine", "")),
            {m: float(v) for m, v in d.get("raw_lines_per_2a_row", {}).items()},
            float(d.get("sar_gtc_s_per_frame", 0.0)),
        )


@dataclass
class Replication:
    """One run's figures: per stage, per level, and the station's totals."""

    stages: dict[str, dict[str, float]]
    levels: dict[str, dict[str, float]]
    station: dict[str, float]
    series: dict[str, tuple[list[float], list[int]]] = field(repr=False, default_factory=dict)


def gamma_time(rng: np.random.Generator, mean: float, cv: float) -> float:
    """A service time of mean ``mean`` and coefficient of variation ``cv`` (gamma law;
    ``cv`` 0: the mean itself)."""
    if cv <= 0 or mean <= 0:
        return mean
    k = 1.0 / (cv * cv)
    return float(rng.gamma(k, mean / k))


#: The counters of a replication (events of the horizon after the warm-up).
COUNTERS = (
    "passes",
    "imaging_passes",
    "segments",
    "segments_lost",
    "scenes",
    "orders",
    "products",
    "film_products",
    "landsat_passes_tracked",
    "landsat_passes_missed",
    "tm_jobs",
    "ers_passes_tracked",
    "ers_passes_missed",
    "sar_frames_recorded",
    "sar_frames",
)


class StationSimulation:
    """One replication of a capacity scenario as a simpy model (module docstring): the
    stages, the random streams, the counters; :meth:`run` runs it to the end."""

    def __init__(
        self,
        scn: CapacityScenario,
        service: Service,
        replication: int = 0,
        patterns: Patterns | None = None,
    ) -> None:
        rng = np.random.default_rng(np.random.SeedSequence(scn.seed, spawn_key=(replication,)))
        self.rng_plan, self.rng_service, rng_fail, self.rng_orders = rng.spawn(4)
        self.scn, self.service = scn, service
        sim = scn.simulation
        self.warmup = sim.warmup_days * _DAY
        self.t_end = self.warmup + sim.days * _DAY
        spot, landsat, ers = patterns or pass_patterns(scn)
        self.pattern = spot
        self.env = env = simpy.Environment()
        self.stages = self._stages(rng_fail)
        self.latency: dict[str, list[float]] = {lv: [] for lv in LEVELS}
        self.in_sla: dict[str, list[bool]] = {lv: [] for lv in LEVELS}
        self.counts = dict.fromkeys(COUNTERS, 0)
        self.mix = np.cumsum(scn.orders.mix)
        # streams of their own, after the first four: scenarios without Landsat or film
        # draw exactly as before
        self.rng_landsat, self.rng_tm = rng.spawn(2)
        self.extra_2a_s = {m: cor_window_s(service, scn.service, m) for m in ("P", "XS")}
        ls = scn.landsat
        if landsat is not None:
            env.process(self.shared_passes(landsat, ls.antenna_share, self.rng_landsat, "landsat"))
        if ls.tm_jobs_per_day > 0 and ls.tm_job_s > 0:
            env.process(self.tm_jobs())
        self.rng_ers = rng.spawn(1)[0]  # after the others: runs without ERS draw as before
        self._ers_passes(ers)

    def _stages(self, rng_fail: np.random.Generator) -> dict[str, Stage]:
        """The station's stages (a recorder's transcription only on tape, a film recorder
        only for analog products), each with its staffed shift, failures and outage."""
        scn, env = self.scn, self.env
        res, sh = scn.resources, scn.shifts
        shift = Shift(
            sh.start_h,
            sh.end_h,
            sh.days_per_week,
            scn.ground_station.lon_rad,
            self.pattern.weekday0,
        )
        sample = scn.simulation.queue_sample_h * 3600.0
        units = {
            "antenna": res.antennas,
            "recorder": res.recorders,
            "transcription": res.transcription_units,
            "ingest": res.ingest_workers,
            "geo": res.geo_workers,
            "cor": res.cor_workers,
            "archive": res.archive_writers,
            "film": res.film_recorders,
        }
        if scn.orders.film_fraction == 0:
            del units["film"]  # no analog products: no film recorder
        if res.recording == "disk":
            del units["transcription"]
        stages = {
            name: Stage(env, name, n, self.warmup, shift if name in sh.staffed else None, sample)
            for name, n in units.items()
        }
        fl = scn.failures
        for name, st in stages.items():
            mtbf, mttr = getattr(fl, f"{name}_mtbf_s"), getattr(fl, f"{name}_mttr_s")
            if mtbf > 0 and mttr > 0:
                env.process(st.failures(mtbf, mttr, rng_fail.spawn(1)[0]))
        og = scn.outage
        if og.days > 0 and og.stage in stages:
            env.process(stages[og.stage].outage(self.warmup + og.start_day * _DAY, og.days * _DAY))
        return stages

    def _ers_passes(self, ers: Any) -> None:
        """ERS-1's passes sharing the antenna (none when ``ers`` is None)."""
        scn = self.scn
        if ers is not None:
            if scn.ers.gtc_fraction > 0 and self.service.sar_gtc_s_per_frame <= 0:
                raise ScenarioError(
                    "[ers]: the service-time file predates SAR geocoding's "
                    "(no sar_gtc_s_per_frame); run `station capacity calibrate`"
                )
            self.env.process(
                self.shared_passes(ers, scn.ers.antenna_share, self.rng_ers, "ers", self.ers_frames)
            )

    def _draw(self, mean_s: float, scale: float) -> float:
        """A service time: the calibrated mean times the scenario's factor, gamma law."""
        return gamma_time(self.rng_service, mean_s * scale, self.scn.service.cv)

    def order(self, mode: str, t_acq: float, geo_done: simpy.Event) -> Process:
        """An order of one scene: its delay, its scene's GEO, COR (urgent first), archive."""
        od, sv, stages, env = self.scn.orders, self.scn.service, self.stages, self.env
        rng = self.rng_orders
        delay = rng.exponential(od.delay_mean_s) if od.delay_mean_s > 0 else 0.0
        level = LEVELS[int(np.searchsorted(self.mix, rng.random() * self.mix[-1], side="right"))]
        urgent = rng.random() < od.urgent_fraction
        # analog (film) 1A and 1B products, as INPE made them (paper 004_…)
        film = od.film_fraction > 0 and level != Level.L2A and rng.random() < od.film_fraction
        yield env.timeout(delay)
        t_order = env.now
        if not geo_done.triggered:
            yield geo_done
        cor_s = self.service.cor_s[mode][level] * sv.scale_cor
        if level == Level.L2A:  # the north-up rotation's window of raw lines (INPE's 950 / 475)
            cor_s += self.extra_2a_s[mode]
        yield from stages["cor"].serve(
            gamma_time(self.rng_service, cor_s, sv.cv), priority=0 if urgent else 1
        )
        if film:
            yield from stages["film"].serve(gamma_time(self.rng_service, sv.film_s, sv.cv))
        else:
            yield from stages["archive"].serve(
                self._draw(self.service.archive_s[mode][level], sv.scale_archive)
            )
        if t_acq >= self.warmup:
            self.counts["products"] += 1
            self.counts["film_products"] += film
            self.latency[level].append(env.now - t_acq)
            k = LEVELS.index(level)  # its service level counts from the order
            self.in_sla[level].append(env.now - t_order <= od.service_level_s[k])

    def segment(self, mode: str, n_scenes: int) -> Process:
        """One HRV segment: transcription (tape), ingest, GEO."""
        pl, sv, res, stages = self.scn.plan, self.scn.service, self.scn.resources, self.stages
        signal_s = n_scenes * pl.scene_s
        if "transcription" in stages:
            yield from stages["transcription"].serve(signal_s / res.transcription_speed)
        ingest = max(
            signal_s, self._draw(self.service.ingest_s_per_signal_s * signal_s, sv.scale_ingest)
        )  # at least real time
        yield from stages["ingest"].serve(ingest)
        yield from stages["geo"].serve(
            self._draw(self.service.geo_s_per_scene[mode] * n_scenes, sv.scale_geo)
        )

    def hrv_channel(self, mode: str, n_scenes: int, t_acq: float, duration: float) -> None:
        """An HRV's segment at AOS: a recorder, or the segment is lost; then its orders."""
        counted = t_acq >= self.warmup
        if not self.stages["recorder"].take(duration):
            if counted:
                self.counts["segments_lost"] += 1
            return
        if counted:
            self.counts["segments"] += 1
            self.counts["scenes"] += n_scenes
        geo = self.env.process(self.segment(mode, n_scenes))
        for _ in range(n_scenes):
            if self.rng_orders.random() < self.scn.orders.ordered_fraction:
                if counted:
                    self.counts["orders"] += 1
                self.env.process(self.order(mode, t_acq, geo))

    def one_pass(self, sat: Any, t_aos: float, duration: float, day: bool) -> None:
        """At AOS: the antenna, and each HRV's segment, or a loss."""
        pl = self.scn.plan
        counted = t_aos >= self.warmup
        self.counts["passes"] += counted
        imaging = (day or pl.night_passes_image) and self.rng_plan.random() < pl.imaging_probability
        if not imaging or not self.stages["antenna"].take(duration):
            return  # nothing programmed, or lost at the antenna (taken, or down)
        self.counts["imaging_passes"] += counted
        max_scenes = max(1, int(duration // pl.scene_s))
        for _ in range(sat.hrvs):
            n = min(max_scenes, max(1, int(self.rng_plan.poisson(pl.scenes_per_segment))))
            mode = "XS" if self.rng_plan.random() < sat.xs_fraction else "P"
            self.hrv_channel(mode, n, t_aos, duration)

    def passes_of(self, sat: Any) -> Process:
        """Each pass at its AOS, in order; a trailing satellite's first days are the end of
        its previous cycle."""
        pattern, env = self.pattern, self.env
        k0 = -1
        offset = sat.cycle_offset_days * _DAY
        while True:
            base = k0 * pattern.cycle_s + offset
            for t, d, day in zip(
                pattern.aos_s + base, pattern.duration_s, pattern.daylight, strict=True
            ):
                if t >= self.t_end:
                    return
                if t >= 0.0:
                    if t > env.now:
                        yield env.timeout(t - env.now)
                    self.one_pass(sat, t, d, bool(day))
            k0 += 1

    def shared_passes(
        self,
        pattern: PassPattern,
        share: float,
        rng: np.random.Generator,
        name: str,
        on_tracked: Callable[[float], None] | None = None,
    ) -> Process:
        """Another mission's passes at their AOS (Landsat's, ERS-1's): a tracked one (a
        ``share`` of them) takes the antenna (if free) for its visibility, and a SPOT pass
        meanwhile is lost; counted as ``<name>_passes_tracked`` or ``_missed``, and
        ``on_tracked(aos)`` called for a tracked one."""
        env = self.env
        k = 0
        while True:
            for t, d in zip(pattern.aos_s + k * pattern.cycle_s, pattern.duration_s, strict=True):
                if t >= self.t_end:
                    return
                if t > env.now:
                    yield env.timeout(t - env.now)
                if rng.random() < share:
                    got = self.stages["antenna"].take(d, count_loss=False)
                    if t >= self.warmup:
                        self.counts[f"{name}_passes_{'tracked' if got else 'missed'}"] += 1
                    if got and on_tracked is not None:
                        on_tracked(t)
            k += 1

    def ers_frames(self, t: float) -> None:
        """A tracked ERS-1 pass's frames to geocode, to COR."""
        ers = self.scn.ers
        n = int(self.rng_ers.poisson(ers.frames_per_pass * ers.gtc_fraction))
        self.counts["sar_frames_recorded"] += n if t >= self.warmup else 0
        for _ in range(n):
            self.env.process(self.sar_frame(t >= self.warmup))

    def sar_frame(self, counted: bool) -> Process:
        """One ERS-1 frame geocoded (GTC) on a COR unit, after SPOT's urgent orders;
        counted when done (``sar_frames``; ``sar_frames_recorded`` when its pass ends)."""
        sv = self.scn.service
        mean_s = self.service.sar_gtc_s_per_frame * sv.scale_cor
        yield from self.stages["cor"].serve(gamma_time(self.rng_ers, mean_s, sv.cv), priority=1)
        self.counts["sar_frames"] += counted

    def tm_jobs(self) -> Process:
        """Landsat TM processing on the shared COR units: Poisson arrivals."""
        env, ls = self.env, self.scn.landsat
        mean_gap_s = _DAY / ls.tm_jobs_per_day
        while True:
            yield env.timeout(self.rng_tm.exponential(mean_gap_s))
            env.process(self.tm_job())

    def tm_job(self) -> Process:
        ls, sv = self.scn.landsat, self.scn.service
        counted = self.env.now >= self.warmup
        yield from self.stages["cor"].serve(gamma_time(self.rng_tm, ls.tm_job_s, sv.cv), priority=1)
        self.counts["tm_jobs"] += counted

    def run(self) -> Replication:
        """Run to the end of the simulated time; the replication's figures."""
        for sat in self.scn.satellites:
            self.env.process(self.passes_of(sat))
        self.env.run(until=self.t_end)
        return self.figures()

    def figures(self) -> Replication:
        """Per stage, per level and the station's totals, from the end of the warm-up."""
        stages, t_end, og = self.stages, self.t_end, self.scn.outage
        figures = {name: st.figures(t_end) for name, st in stages.items()}
        levels = {}
        for lv in LEVELS:
            x = np.asarray(self.latency[lv]) / 3600.0
            levels[str(lv)] = {
                "products": int(x.size),
                **(
                    {f"latency_p{q}_h": float(np.percentile(x, q)) for q in (50, 90, 95, 99)}
                    if x.size
                    else {f"latency_p{q}_h": math.nan for q in (50, 90, 95, 99)}
                ),
                "within_service_level": float(np.mean(self.in_sla[lv]))
                if self.in_sla[lv]
                else math.nan,
            }
        days, counts = self.scn.simulation.days, self.counts
        station = {k: float(v) for k, v in counts.items()} | {
            "scenes_per_day": counts["scenes"] / days,
            "products_per_day": counts["products"] / days,
            "passes_lost": float(stages["antenna"].lost),
        }
        cor = stages["cor"]
        st, sq = np.asarray(cor.series_t), np.asarray(cor.series_wait, dtype=float)
        station["cor_backlog_growth_per_day"] = (
            float(np.polyfit(st / _DAY, sq, 1)[0]) if st.size > 2 else 0.0
        )
        if og.days > 0 and og.stage in stages:
            station |= _clearing(
                stages[og.stage], self.warmup + og.start_day * _DAY, og.days * _DAY
            )
        series = {name: (s.series_t, s.series_wait) for name, s in stages.items()}
        return Replication(figures, levels, station, series)


#: INPE's raw lines per north-up corrected line (paper 004_…), for service-time files that
#: predate the measured figure.
INPE_RAW_LINES_PER_2A_ROW = {"P": 950.0, "XS": 475.0}


def cor_window_s(service: Service, cfg: ServiceConfig, mode: str) -> float:
    """The extra time of a 2A job on a COR unit whose raw-line buffer is smaller than the
    window of raw lines one north-up row reads: the raw scene is read once per buffer-full
    beyond the first (``ceil(window / buffer) − 1`` times) at ``raw_read_mb_per_s``.

    The window is the code's measured figure (``raw_lines_per_2a_row``, P 980 / XS 490 at
    Cuiabá; INPE's 950 / 475), times a raw line's bytes (one byte per detector and band).
    """
    if cfg.cor_memory_mb <= 0:
        return 0.0
    m = MODES[mode]
    line_mb = m.detectors * len(m.bands) / 1e6
    rows = service.raw_lines_per_2a_row.get(mode, INPE_RAW_LINES_PER_2A_ROW[mode])
    passes = math.ceil(rows * line_mb / cfg.cor_memory_mb)
    return (passes - 1) * m.detectors * line_mb / cfg.raw_read_mb_per_s


#: The passes of SPOT, Landsat's and ERS-1's (None: the antenna is not shared with it).
Patterns = tuple[PassPattern, PassPattern | None, PassPattern | None]


def pass_patterns(scn: CapacityScenario) -> Patterns:
    """The passes over the scenario's station of SPOT and, when they share the antenna, of
    Landsat and ERS-1 (:func:`~station.capacity.passes.pass_pattern`)."""
    others: list[PassPattern | None] = []
    for other in (scn.landsat, scn.ers):
        pattern = None
        if other.antenna_share > 0:
            orbit = OrbitConfig(
                repeat_revs=other.repeat_revs,
                repeat_days=other.repeat_days,
                descending_node_local_time_h=other.descending_node_local_time_h,
            )
            pattern = pass_pattern(scn.ground_station, orbit)
        others.append(pattern)
    return pass_pattern(scn.ground_station), others[0], others[1]


def simulate(
    scn: CapacityScenario,
    service: Service,
    replication: int = 0,
    patterns: Patterns | None = None,
) -> Replication:
    """One replication of the scenario (module docstring); ``patterns``: its passes when
    already computed (:func:`pass_patterns`: 15 s of orbit propagation, which a task on
    another process would otherwise repeat)."""
    return StationSimulation(scn, service, replication, patterns).run()


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
    return {
        "outage_backlog_peak": float(peak.max()) if peak.size else 0.0,
        "outage_clear_days": float((cleared[0] - end) / _DAY) if cleared.size else math.nan,
    }
