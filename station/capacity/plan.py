"""A day's plan drawn as the capacity model draws it: the passes of a window of time over
the station, the segment each HRV takes, and the orders of their scenes.

The draws are the model's (:class:`~station.capacity.model.StationSimulation`): a daylight
pass images with the plan's probability and takes the antenna if no other pass holds it;
each HRV of the satellite takes a segment of a Poisson number of scenes (at least one, no
longer than the pass) in P or XS; each scene is ordered with the orders' share, at one
level of the mix, urgent with its share, an exponential delay after acquisition. The plan
is what ``station day`` runs on the clock and what ``station capacity validate`` gives the
model back, so that the model and the day see the same passes and orders (a trace-driven
check: only the service times are the model's to draw).
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from levels.choices import Level
from station.capacity.config import CapacityScenario
from station.capacity.passes import pass_pattern
from station.errors import ScenarioError

__all__ = ["DayPlan", "PlannedOrder", "PlannedPass", "PlannedSegment", "draw_plan", "read_plan"]

_DAY = 86400.0
#: The levels an order asks, in the order of ``[orders] mix``.
ORDER_LEVELS = (Level.L1A, Level.L1B, Level.L2A)
PLAN_FORMAT = "spot-station-day-plan"


@dataclass(frozen=True)
class PlannedSegment:
    """One HRV's segment of a pass: its instrument, mode and scenes."""

    hrv: int
    mode: str
    scenes: int


@dataclass(frozen=True)
class PlannedPass:
    """A pass that images: its satellite, AOS and visibility (s from the day's start)."""

    name: str
    satellite: str
    aos_s: float
    duration_s: float
    segments: tuple[PlannedSegment, ...]


@dataclass(frozen=True)
class PlannedOrder:
    """An order of one scene of a segment at one level (times from the day's start)."""

    name: str
    pass_name: str
    hrv: int
    scene: int
    level: str
    urgent: bool
    order_s: float


@dataclass(frozen=True)
class DayPlan:
    """The passes that image in the window, their orders, and what was not imaged."""

    start_s: float  # the window's start, from the SPOT cycle's start
    hours: float
    passes: tuple[PlannedPass, ...]
    orders: tuple[PlannedOrder, ...]
    passes_lost: int  # imaging passes the antenna could not take (held by another)

    def as_json(self) -> dict[str, object]:
        return {"format": PLAN_FORMAT, "format_version": 1, **asdict(self)}

    def write(self, path: str | Path) -> Path:
        path = Path(path)
        path.write_text(json.dumps(self.as_json(), indent=1) + "\n")
        return path

    def segment(self, pass_name: str, hrv: int) -> tuple[PlannedPass, PlannedSegment]:
        for p in self.passes:
            if p.name == pass_name:
                for s in p.segments:
                    if s.hrv == hrv:
                        return p, s
        raise KeyError(f"{pass_name} HRV {hrv}")


def read_plan(path: str | Path) -> DayPlan:
    """A plan written by :meth:`DayPlan.write` (or by hand: orders read from a file)."""
    path = Path(path)
    try:
        d = json.loads(path.read_text())
        if d.get("format") != PLAN_FORMAT:
            raise ScenarioError(f"{path}: not a day plan (format {d.get('format')!r})")
        passes = tuple(
            PlannedPass(
                str(p["name"]),
                str(p["satellite"]),
                float(p["aos_s"]),
                float(p["duration_s"]),
                tuple(
                    PlannedSegment(int(s["hrv"]), str(s["mode"]), int(s["scenes"]))
                    for s in p["segments"]
                ),
            )
            for p in d["passes"]
        )
        orders = tuple(
            PlannedOrder(
                str(o["name"]),
                str(o["pass_name"]),
                int(o["hrv"]),
                int(o["scene"]),
                str(Level(o["level"])),
                bool(o["urgent"]),
                float(o["order_s"]),
            )
            for o in d["orders"]
        )
        return DayPlan(
            float(d["start_s"]), float(d["hours"]), passes, orders, int(d.get("passes_lost", 0))
        )
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise ScenarioError(f"{path}: not a readable day plan: {exc}") from None


def draw_plan(scn: CapacityScenario, start_s: float, hours: float) -> DayPlan:
    """The plan of ``hours`` from ``start_s`` (s from the SPOT cycle's start), drawn from
    the scenario's seed (module docstring)."""
    rng = np.random.default_rng(np.random.SeedSequence(scn.seed, spawn_key=(7,)))
    rng_plan, rng_orders = rng.spawn(2)
    pattern = pass_pattern(scn.ground_station)
    end_s = start_s + hours * 3600.0
    candidates = []
    for sat in scn.satellites:
        offset = sat.cycle_offset_days * _DAY
        for k in (-1, 0, 1):
            t = pattern.aos_s + k * pattern.cycle_s + offset
            keep = (t >= start_s) & (t < end_s)
            for aos, dur, day in zip(
                t[keep], pattern.duration_s[keep], pattern.daylight[keep], strict=True
            ):
                candidates.append((float(aos), float(dur), bool(day), sat))
    candidates.sort(key=lambda c: c[0])
    pl, od = scn.plan, scn.orders
    mix = np.cumsum(od.mix)
    passes: list[PlannedPass] = []
    orders: list[PlannedOrder] = []
    lost, busy_until = 0, -np.inf
    for aos, dur, day, sat in candidates:
        if not ((day or pl.night_passes_image) and rng_plan.random() < pl.imaging_probability):
            continue
        if aos < busy_until:  # the antenna tracks another pass
            lost += 1
            continue
        busy_until = aos + dur
        name = f"{scn.name}_p{len(passes):02d}"
        max_scenes = max(1, int(dur // pl.scene_s))
        segments = []
        for hrv in range(1, sat.hrvs + 1):
            n = min(max_scenes, max(1, int(rng_plan.poisson(pl.scenes_per_segment))))
            mode = "XS" if rng_plan.random() < sat.xs_fraction else "P"
            segments.append(PlannedSegment(hrv, mode, n))
            for scene in range(n):
                if rng_orders.random() >= od.ordered_fraction:
                    continue
                delay = rng_orders.exponential(od.delay_mean_s) if od.delay_mean_s > 0 else 0.0
                level = ORDER_LEVELS[
                    int(np.searchsorted(mix, rng_orders.random() * mix[-1], side="right"))
                ]
                urgent = bool(rng_orders.random() < od.urgent_fraction)
                orders.append(
                    PlannedOrder(
                        f"o{len(orders):03d}",
                        name,
                        hrv,
                        scene,
                        str(level),
                        urgent,
                        aos - start_s + delay,
                    )
                )
        passes.append(PlannedPass(name, sat.name, aos - start_s, dur, tuple(segments)))
    orders.sort(key=lambda o: o.order_s)
    return DayPlan(start_s, hours, tuple(passes), tuple(orders), lost)
