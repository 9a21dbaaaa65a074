"""A day's file: a capacity scenario (:mod:`station.capacity.config`: the station, its
satellites, plan and orders) and a ``[day]`` table saying which hours of it run on the
clock, how fast, on how many workers, and how each pass is emulated (reduced scenes).

``[day]`` keys:

- ``start_day``, ``start_h``: where the window begins, from the SPOT cycle's start (day 0
  is the capacity model's first day);
- ``hours``: the window's length (station time);
- ``clock``: how many times faster than real the day runs (60: an hour in a minute);
- ``workers``: processing workers (the capacity model's COR workers);
- ``p_detectors``: detectors of a P scene as emulated (XS: half as many, as ``station
  capacity calibrate`` reduces them); a scene is as many lines as detectors;
- ``bit_rate_mbps``: each channel's rate as emulated (a share of 25 Mbit/s like the
  detectors);
- ``calibration_repeats``: how many times each order kind (mode × level) is made alone
  when the service times are measured (:mod:`station.day.calibrate`; half as many on the
  one-scene archive).
"""

from __future__ import annotations

import dataclasses
import hashlib
from dataclasses import dataclass, field
from pathlib import Path

from levels.options import build_section, option
from station.capacity.config import CapacityScenario, capacity_from_dict
from station.errors import ScenarioError
from station.scenario import read_toml

__all__ = ["DayConfig", "DayScenario", "load_day"]


@dataclass(frozen=True)
class DayConfig:
    """Which hours of the capacity scenario run, how fast, on what (module docstring)."""

    start_day: float = option(
        0.0, "start_day", "day of the SPOT cycle the window opens", 1.0, 0.0, 26.0
    )
    start_h: float = option(12.0, "start_h", "hour (UTC) the window opens", 1.0, 0.0, 24.0)
    hours: float = option(8.0, "hours", "length of the window (station time)", 1.0, 0.1, 240.0)
    clock: float = option(60.0, "clock", "times faster than real time", 1.0, 1.0, 10000.0)
    workers: int = option(2, "workers", "processing workers (COR)", lo=1, hi=64)
    p_detectors: int = option(
        1000, "p_detectors", "detectors of a P scene as emulated (XS: half)", lo=50, hi=6000
    )
    bit_rate_mbps: float = option(
        4.0, "bit_rate_mbps", "each channel's rate as emulated", 1.0, 0.1, 25.0
    )
    seed: int = option(
        0, "seed", "added to the scenario's seed for the emulated passes", lo=0, hi=2**31
    )
    calibration_repeats: int = option(
        4, "calibration_repeats", "times each order kind is made to calibrate COR", lo=2, hi=50
    )

    @property
    def start_s(self) -> float:
        """The window's start, from the SPOT cycle's start (s)."""
        return self.start_day * 86400.0 + self.start_h * 3600.0


@dataclass(frozen=True)
class DayScenario:
    """A day file: its station and load (the capacity scenario) and its ``[day]``."""

    capacity: CapacityScenario
    day: DayConfig = field(default_factory=DayConfig)
    source: str = ""
    source_sha256: str = ""

    @property
    def name(self) -> str:
        return self.capacity.name


def load_day(path: str | Path) -> DayScenario:
    """Read and check a day file."""
    p = Path(path)
    data, raw = read_toml(p, "day")
    table = data.pop("day", None)
    if not isinstance(table, dict):
        raise ScenarioError(
            f"{p}: a day file has a [day] table (the window, the clock, the workers)"
        )
    day = build_section(DayConfig, "day", table, ScenarioError)
    cap = capacity_from_dict(data, p.resolve().parent)
    cap = dataclasses.replace(
        cap,
        resources=dataclasses.replace(cap.resources, cor_workers=day.workers),
        source=str(p.resolve()),
        source_sha256=hashlib.sha256(raw).hexdigest(),
    )
    return DayScenario(cap, day, str(p.resolve()), hashlib.sha256(raw).hexdigest())


def with_workers(scn: DayScenario, workers: int | None, clock: float | None) -> DayScenario:
    """The day with ``--workers`` and ``--clock`` given on the command line."""
    day = scn.day
    if workers is not None:
        if not 1 <= workers <= 64:
            raise ScenarioError(f"--workers {workers}: expected 1 to 64")
        day = dataclasses.replace(day, workers=workers)
    if clock is not None:
        if not 1.0 <= clock <= 10000.0:
            raise ScenarioError(f"--clock {clock}: expected 1 to 10000 (times real time)")
        day = dataclasses.replace(day, clock=clock)
    cap = dataclasses.replace(
        scn.capacity, resources=dataclasses.replace(scn.capacity.resources, cor_workers=day.workers)
    )
    return dataclasses.replace(scn, capacity=cap, day=day)
