"""Capacity scenarios: a TOML description of a station's size and load, as frozen dataclasses.

Declared like the pass scenarios (:mod:`station.scenario`): every key has a unit suffix, a
default, a range and a meaning, and a bad key or value is rejected naming it. The sections:

- ``[simulation]``: length, warm-up, replications, seed;
- ``[[satellite]]``: one table per satellite, all on SPOT's phased orbit, each trailing the
  first by ``cycle_offset_days`` (13 days is 180° of orbital phase: SPOT 1 and 2);
- ``[ground_station]``: where the antenna is and its elevation mask (as in a pass scenario);
- ``[plan]``: which passes image and how many scenes each HRV takes;
- ``[resources]``: the antenna, demodulator-recorder chains, tape or disk, and the worker
  pool of every stage;
- ``[shifts]``: operator hours, and which stages need an operator;
- ``[failures]``: MTBF and MTTR per stage (0: never fails);
- ``[orders]``: the share of scenes ordered, the mix over levels, urgent orders, service
  levels;
- ``[service]``: the service-time file (``station capacity calibrate``) and the factors
  that scale it to the modelled machines;
- ``[outage]``: one stage down for a while, to see the backlog grow and clear.
"""

from __future__ import annotations

import dataclasses
import hashlib
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from levels.options import build_section, option
from station.errors import ScenarioError
from station.scenario import GroundStationConfig, check_name, read_toml

__all__ = ["STAGES", "CapacityScenario", "capacity_from_dict", "load_capacity", "with_value"]

#: The stages of the model, in the order a pass goes through them.
STAGES = ("antenna", "recorder", "transcription", "ingest", "geo", "cor", "archive", "film")


@dataclass(frozen=True)
class SimulationConfig:
    """How long, how often, and from which random seed."""

    days: float = option(365.0, "days", "simulated time after the warm-up", 1.0, 1.0, 3650.0)
    warmup_days: float = option(
        14.0, "warmup_days", "time simulated before statistics start", 1.0, 0.0, 365.0
    )
    replications: int = option(
        5, "replications", "independent runs (confidence intervals)", lo=1, hi=1000
    )
    queue_sample_h: float = option(
        6.0, "queue_sample_h", "step of the queue time series", 1.0, 0.01, 240.0
    )


@dataclass(frozen=True)
class SatelliteConfig:
    """One satellite on the phased orbit (the pass scenario's ``[orbit]`` defaults)."""

    name: str = option("SPOT 1", "name", "name for reports")
    cycle_offset_days: int = option(
        0,
        "cycle_offset_days",
        "days this satellite trails the first on the same track",
        lo=0,
        hi=25,
    )
    hrvs: int = option(2, "hrvs", "HRVs imaging (each on its own channel)", lo=1, hi=2)
    xs_fraction: float = option(
        0.5, "xs_fraction", "share of HRV segments taken in XS", 1.0, 0.0, 1.0
    )


@dataclass(frozen=True)
class PlanConfig:
    """The acquisition plan: which passes image and how long each HRV's segment is."""

    imaging_probability: float = option(
        0.8,
        "imaging_probability",
        "share of daylight passes with a programmed segment",
        1.0,
        0.0,
        1.0,
    )
    scenes_per_segment: float = option(
        6.0,
        "scenes_per_segment",
        "mean scenes per HRV segment (Poisson, at least 1)",
        1.0,
        0.0,
        100.0,
    )
    scene_s: float = option(9.0, "scene_s", "flight time of one 60 km scene", 1.0, 1.0, 60.0)
    night_passes_image: bool = option(
        False, "night_passes_image", "whether night (ascending) passes image too"
    )


@dataclass(frozen=True)
class ResourcesConfig:
    """What the station has: units per stage; ``recording`` on tape needs transcription."""

    antennas: int = option(1, "antennas", "tracking antennas", lo=1, hi=10)
    recorders: int = option(
        2, "recorders", "demodulator-recorder chains (one per HRV channel)", lo=1, hi=20
    )
    recording: str = option(
        "tape", "recording", "high-density tape, or straight to disk", choices=("tape", "disk")
    )
    transcription_speed: float = option(
        1.0, "transcription_speed", "tape playback speed (× real time)", 1.0, 0.1, 100.0
    )
    transcription_units: int = option(1, "transcription_units", "tape playback units", lo=1, hi=20)
    ingest_workers: int = option(
        1, "ingest_workers", "decoding and L0 archiving chains", lo=1, hi=100
    )
    geo_workers: int = option(
        1, "geo_workers", "GEO workers (one pass and HRV at a time)", lo=1, hi=100
    )
    cor_workers: int = option(
        2, "cor_workers", "COR workers (one scene and level at a time)", lo=1, hi=1000
    )
    archive_writers: int = option(1, "archive_writers", "product archive writers", lo=1, hi=100)
    film_recorders: int = option(
        1, "film_recorders", "film recorders for the analog 1A/1B products", lo=1, hi=100
    )


@dataclass(frozen=True)
class ShiftsConfig:
    """Operator hours (local time at the station's longitude), and who needs an operator."""

    start_h: float = option(8.0, "start_h", "shift start", 1.0, 0.0, 24.0)
    end_h: float = option(18.0, "end_h", "shift end", 1.0, 0.0, 24.0)
    days_per_week: int = option(5, "days_per_week", "staffed days, from Monday", lo=1, hi=7)
    staffed: tuple[str, ...] = option(
        ["transcription"], "staffed", "stages that start a job only on shift", choices=STAGES[2:]
    )

    def __post_init__(self) -> None:
        if self.end_h <= self.start_h:
            raise ScenarioError(
                f"[shifts] end_h = {self.end_h:g} must be after start_h = {self.start_h:g}"
            )


def _mtbf(stage: str, hours: float) -> Any:
    return option(
        hours,
        f"{stage}_mtbf_h",
        f"{stage}: mean time between failures of a unit (0: never)",
        3600.0,
        0.0,
        1e6,
    )


def _mttr(stage: str, hours: float) -> Any:
    return option(hours, f"{stage}_mttr_h", f"{stage}: mean time to repair", 3600.0, 0.0, 1e4)


@dataclass(frozen=True)
class FailuresConfig:
    """Failures and repairs of each unit (exponential), given in hours, held in seconds."""

    antenna_mtbf_s: float = _mtbf("antenna", 2000.0)
    antenna_mttr_s: float = _mttr("antenna", 12.0)
    recorder_mtbf_s: float = _mtbf("recorder", 1000.0)
    recorder_mttr_s: float = _mttr("recorder", 8.0)
    transcription_mtbf_s: float = _mtbf("transcription", 500.0)
    transcription_mttr_s: float = _mttr("transcription", 8.0)
    ingest_mtbf_s: float = _mtbf("ingest", 2000.0)
    ingest_mttr_s: float = _mttr("ingest", 4.0)
    geo_mtbf_s: float = _mtbf("geo", 2000.0)
    geo_mttr_s: float = _mttr("geo", 4.0)
    cor_mtbf_s: float = _mtbf("cor", 2000.0)
    cor_mttr_s: float = _mttr("cor", 4.0)
    archive_mtbf_s: float = _mtbf("archive", 4000.0)
    archive_mttr_s: float = _mttr("archive", 8.0)
    film_mtbf_s: float = _mtbf("film", 2000.0)
    film_mttr_s: float = _mttr("film", 8.0)


@dataclass(frozen=True)
class OrdersConfig:
    """What users order: a share of the scenes acquired, at one level each."""

    ordered_fraction: float = option(
        0.6, "ordered_fraction", "share of scenes ordered", 1.0, 0.0, 1.0
    )
    mix: tuple[float, float, float] = option(
        [0.2, 0.3, 0.5], "mix", "shares of levels 1A, 1B, 2A among orders", 1.0, 0.0, 1.0
    )
    urgent_fraction: float = option(
        0.1, "urgent_fraction", "share of urgent orders (served first)", 1.0, 0.0, 1.0
    )
    delay_mean_s: float = option(
        24.0,
        "delay_mean_h",
        "mean time from acquisition to the order (exponential)",
        3600.0,
        0.0,
        1e4,
    )
    service_level_s: tuple[float, float, float] = option(
        [24.0, 48.0, 72.0],
        "service_level_h",
        "promised time from order to product, levels 1A, 1B, 2A",
        3600.0,
        0.1,
        1e4,
    )
    film_fraction: float = option(
        0.0,
        "film_fraction",
        "share of 1A and 1B orders delivered on film (analog), through a film recorder",
        1.0,
        0.0,
        1.0,
    )

    def __post_init__(self) -> None:
        if abs(sum(self.mix) - 1.0) > 1e-9:
            raise ScenarioError(f"[orders] mix = {list(self.mix)}: the shares must add to 1")


@dataclass(frozen=True)
class ServiceConfig:
    """Where the service times come from and how they scale to the modelled machines.

    The file holds this code's stages measured on one machine (``station capacity
    calibrate``); each factor says how many times slower the modelled stage is (1990
    workstations: about a thousand). The front end decodes at least at real time: it was
    hardware.
    """

    file: str = option("service_times.json", "file", "service-time file, relative to the scenario")
    scale_ingest: float = option(1.0, "scale_ingest", "factor on decoding", 1.0, 1e-3, 1e5)
    scale_geo: float = option(1.0, "scale_geo", "factor on GEO", 1.0, 1e-3, 1e5)
    scale_cor: float = option(1.0, "scale_cor", "factor on COR", 1.0, 1e-3, 1e5)
    scale_archive: float = option(1.0, "scale_archive", "factor on archiving", 1.0, 1e-3, 1e5)
    cv: float = option(
        0.2, "cv", "coefficient of variation of service times (gamma; 0: fixed)", 1.0, 0.0, 3.0
    )
    film_s: float = option(
        15.0, "film_min", "film recorder time per scene (analog 1A/1B)", 60.0, 0.0, 1e4
    )
    cor_memory_mb: float = option(
        0.0,
        "cor_memory_mb",
        "raw-line buffer of a COR unit (0: unlimited): a 2A row's window of raw lines "
        "larger than it is read again, once per extra buffer-full",
        1.0,
        0.0,
        1e6,
    )
    raw_read_mb_per_s: float = option(
        1.0, "raw_read_mb_per_s", "raw-image read rate of a COR unit", 1.0, 1e-3, 1e5
    )


@dataclass(frozen=True)
class LandsatConfig:
    """Landsat at the same station (paper ``004_…``: the SRRS antenna is shared with the
    Landsat receiving station, and SIPC's hardware with TM processing).

    Landsat's passes take the antenna when tracked (a share of them); a SPOT pass that
    finds it taken is lost, as one that finds it down. TM processing jobs take COR units.
    The orbit is Landsat 4/5's (233 revolutions in 16 days, 705 km, descending node at
    9:45), the mission's published facts, not a seed's.
    """

    antenna_share: float = option(
        0.0, "antenna_share", "share of Landsat passes over the station tracked", 1.0, 0.0, 1.0
    )
    repeat_revs: int = option(233, "repeat_revs", "Landsat revolutions per cycle", lo=1, hi=10000)
    repeat_days: int = option(16, "repeat_days", "Landsat repeat cycle", lo=1, hi=1000)
    descending_node_local_time_h: float = option(
        9.75, "descending_node_local_time_h", "Landsat's descending node", 1.0, 0.0, 24.0
    )
    tm_jobs_per_day: float = option(
        0.0,
        "tm_jobs_per_day",
        "TM processing jobs on the shared COR units (Poisson)",
        1.0,
        0.0,
        1000.0,
    )
    tm_job_s: float = option(2.0, "tm_job_h", "mean duration of a TM job", 3600.0, 0.0, 1000.0)


@dataclass(frozen=True)
class ErsConfig:
    """ERS-1 at the same station (issue 38: Cuiabá received ERS-1 as well as SPOT and
    Landsat; ADRIN's geocoding, paper ``001_…`` §5).

    Its passes take the antenna when tracked (a share of them), as Landsat's do; each
    tracked pass records ``frames_per_pass`` frames on average (Poisson), of which
    ``gtc_fraction`` are geocoded over a DEM (GTC) on the shared COR units, each for the
    service time measured on this code (``service_times.json``: ``sar_gtc_s_per_frame``, a
    full 100 km frame at 12.5 m) times ``[service] scale_cor``. The orbit is ERS-1's (501
    revolutions in 35 days, 785 km, descending node at 10:30): the mission's published
    facts, not a seed's.
    """

    antenna_share: float = option(
        0.0, "antenna_share", "share of ERS-1 passes over the station tracked", 1.0, 0.0, 1.0
    )
    repeat_revs: int = option(501, "repeat_revs", "ERS-1 revolutions per cycle", lo=1, hi=10000)
    repeat_days: int = option(35, "repeat_days", "ERS-1 repeat cycle", lo=1, hi=1000)
    descending_node_local_time_h: float = option(
        10.5, "descending_node_local_time_h", "ERS-1's descending node", 1.0, 0.0, 24.0
    )
    frames_per_pass: float = option(
        4.0, "frames_per_pass", "frames recorded per tracked pass (mean)", 1.0, 0.0, 100.0
    )
    gtc_fraction: float = option(
        0.5, "gtc_fraction", "share of the frames geocoded (GTC) on COR", 1.0, 0.0, 1.0
    )


@dataclass(frozen=True)
class OutageConfig:
    """One stage entirely down for a while (all its units), to watch the backlog."""

    stage: str = option("cor", "stage", "which stage", choices=STAGES)
    start_day: float = option(120.0, "start_day", "start, days after the warm-up", 1.0, 0.0, 3650.0)
    days: float = option(0.0, "days", "how long (0: no outage)", 1.0, 0.0, 365.0)


_SECTIONS = {
    "simulation": SimulationConfig,
    "ground_station": GroundStationConfig,
    "plan": PlanConfig,
    "resources": ResourcesConfig,
    "shifts": ShiftsConfig,
    "failures": FailuresConfig,
    "orders": OrdersConfig,
    "service": ServiceConfig,
    "outage": OutageConfig,
    "landsat": LandsatConfig,
    "ers": ErsConfig,
}


@dataclass(frozen=True)
class CapacityScenario:
    """A whole capacity scenario (module docstring)."""

    name: str = "capacity"
    seed: int = 1
    satellites: tuple[SatelliteConfig, ...] = (SatelliteConfig(),)
    simulation: SimulationConfig = field(default_factory=SimulationConfig)
    ground_station: GroundStationConfig = field(default_factory=GroundStationConfig)
    plan: PlanConfig = field(default_factory=PlanConfig)
    resources: ResourcesConfig = field(default_factory=ResourcesConfig)
    shifts: ShiftsConfig = field(default_factory=ShiftsConfig)
    failures: FailuresConfig = field(default_factory=FailuresConfig)
    orders: OrdersConfig = field(default_factory=OrdersConfig)
    service: ServiceConfig = field(default_factory=ServiceConfig)
    outage: OutageConfig = field(default_factory=OutageConfig)
    landsat: LandsatConfig = field(default_factory=LandsatConfig)
    ers: ErsConfig = field(default_factory=ErsConfig)
    base_dir: str = "."
    source: str = ""
    source_sha256: str = ""

    def path(self, relative: str) -> Path:
        p = Path(relative)
        return p if p.is_absolute() else Path(self.base_dir) / p


def capacity_from_dict(data: dict[str, object], base_dir: str | Path = ".") -> CapacityScenario:
    """A :class:`CapacityScenario` from a parsed TOML table."""
    kwargs: dict[str, Any] = {"base_dir": str(base_dir)}
    allowed = sorted(["name", "seed", "satellite", *_SECTIONS])
    for key, value in data.items():
        if key == "name" and isinstance(value, str):
            kwargs["name"] = check_name(value)
        elif (
            key == "seed"
            and isinstance(value, int)
            and not isinstance(value, bool)
            and 0 <= value < 2**63
        ):
            kwargs["seed"] = value
        elif key in ("name", "seed"):
            raise ScenarioError(
                f"{key} = {value!r}: expected "
                f"{'a string' if key == 'name' else 'an integer in [0, 2**63)'}"
            )
        elif key == "satellite":
            if not isinstance(value, list) or not value:
                raise ScenarioError("satellite: expected one or more [[satellite]] tables")
            kwargs["satellites"] = tuple(
                build_section(SatelliteConfig, "satellite", v, ScenarioError) for v in value
            )
        elif key in _SECTIONS:
            kwargs[key] = build_section(_SECTIONS[key], key, value, ScenarioError)
        else:
            raise ScenarioError(f"unknown key {key!r}; allowed: {', '.join(allowed)}")
    return CapacityScenario(**kwargs)


def load_capacity(path: str | Path) -> CapacityScenario:
    """Read and validate a capacity scenario file."""
    p = Path(path)
    data, raw = read_toml(p, "capacity scenario")
    scn = capacity_from_dict(data, p.resolve().parent)
    return dataclasses.replace(
        scn, source=str(p.resolve()), source_sha256=hashlib.sha256(raw).hexdigest()
    )


def with_value(scn: CapacityScenario, param: str, text: str) -> CapacityScenario:
    """``scn`` with one key changed, named ``section.key`` as in the file (a sweep's step);
    ``text`` is parsed as a TOML value ("3", "0.5", '"disk"')."""
    section, _, key = param.partition(".")
    if section not in _SECTIONS or not key:
        raise ScenarioError(
            f"--sweep {param}: expected SECTION.KEY with SECTION one of {', '.join(_SECTIONS)}"
        )
    try:
        value = tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        value = text  # a bare word: a string
    cls = _SECTIONS[section]
    current = getattr(scn, section)
    table = {}
    for f in dataclasses.fields(cls):
        if "key" in f.metadata:
            v = getattr(current, f.name)
            scale = f.metadata["scale"]
            if isinstance(v, float):
                v = v / scale
            elif isinstance(v, tuple) and v and isinstance(v[0], float):
                v = [x / scale for x in v]
            elif isinstance(v, tuple):
                v = list(v)
            table[f.metadata["key"]] = v
    if key not in table:
        raise ScenarioError(
            f"--sweep {param}: [{section}] has no key {key!r}; allowed: {', '.join(sorted(table))}"
        )
    table[key] = value
    return dataclasses.replace(scn, **{section: build_section(cls, section, table, ScenarioError)})
