"""Scenario files: a TOML description of a pass, turned at once into frozen dataclasses.

A scenario can be three lines long: every section and every key has a default, the SPOT 1–4
facts of ``DESIGN.md`` sized so that the system-corrected levels land in Spot Image's
published error budget. Keys carry their unit as a suffix (``altitude_km``,
``roll_offset_urad``); the dataclasses hold SI values (``altitude_m``, ``roll0_rad``),
converted here once. An unknown key, a wrong type or a value out of range is rejected with
a :class:`ScenarioError` naming the key, the value and what is allowed.

Every field of every section is declared once with :func:`_key`: its TOML name, the factor
to SI, its allowed range and a one-line meaning. The error messages and the listing of
:func:`describe_keys` are generated from those declarations, so they cannot drift apart.
"""

from __future__ import annotations

import dataclasses
import hashlib
import math
import tomllib
import typing
from dataclasses import MISSING, dataclass, field, fields
from pathlib import Path
from typing import Any

import numpy as np

from station.errors import ScenarioError

__all__ = [
    "AttitudeConfig",
    "BulletinConfig",
    "CalibrationConfig",
    "ChannelConfig",
    "DownlinkConfig",
    "GcpConfig",
    "GroundStationConfig",
    "InstrumentConfig",
    "OrbitConfig",
    "PassConfig",
    "ProcessingConfig",
    "Scenario",
    "ScenarioError",
    "WorldConfig",
    "describe_keys",
    "load_scenario",
    "read_toml",
    "scenario_from_dict",
]

_DEG = math.pi / 180.0
_URAD = 1e-6


def _key(
    default: Any,
    key: str,
    doc: str,
    scale: float = 1.0,
    lo: float | None = None,
    hi: float | None = None,
    choices: tuple[str, ...] | None = None,
) -> Any:
    """Declare a scenario field: TOML ``key`` (unit-suffixed), factor to SI, range, meaning.

    ``default`` is given in TOML units (degrees, km, µrad) and converted like a read value.
    """
    meta = {"key": key, "doc": doc, "scale": scale, "lo": lo, "hi": hi, "choices": choices}
    if isinstance(default, list | tuple) and all(isinstance(v, str) for v in default):
        return field(default=tuple(default), metadata=meta)
    if isinstance(default, list | tuple):
        si = tuple(float(v) * scale for v in default)
        return field(default=si, metadata=meta)
    if isinstance(default, float):
        default = default * scale
    return field(default=default, metadata=meta)


@dataclass(frozen=True)
class OrbitConfig:
    """The truth orbit: a phased sun-synchronous orbit, given mean elements, or a TLE.

    ``kind = "phased"`` solves the mean semi-major axis and inclination for which the orbit
    repeats after ``repeat_revs`` revolutions in ``repeat_days`` days and its node drifts with
    the mean Sun (SPOT: 369 revolutions in 26 days, 14 + 5/26 rev/day, 822 km, 98.7°).
    ``kind = "elements"`` takes ``altitude_km`` and ``inclination_deg`` as given mean elements.
    ``kind = "tle"`` starts from record ``tle_index`` of ``tle_path``.
    """

    kind: str = _key("phased", "kind", "how the orbit is given",
                     choices=("phased", "elements", "tle"))
    repeat_revs: int = _key(369, "repeat_revs", "revolutions in one repeat cycle", lo=1, hi=10000)
    repeat_days: int = _key(26, "repeat_days", "days of one repeat cycle", lo=1, hi=1000)
    altitude_m: float = _key(822.0, "altitude_km", "mean altitude above the equator (elements)",
                             1e3, 200.0, 2000.0)
    inclination_rad: float = _key(98.7, "inclination_deg", "mean inclination (elements)",
                                  _DEG, 0.0, 180.0)
    eccentricity: float = _key(0.0, "eccentricity", "mean eccentricity (elements, phased)",
                               1.0, 0.0, 0.05)
    descending_node_local_time_h: float = _key(
        10.5, "descending_node_local_time_h", "mean local solar time of the descending node",
        1.0, 0.0, 24.0)
    tle_path: str = _key("", "tle_path", "TLE file (kind = 'tle'), relative to the scenario")
    tle_index: int = _key(0, "tle_index", "which record of the TLE file", lo=0, hi=10000)

    def __post_init__(self) -> None:
        if self.kind == "tle" and not self.tle_path:
            raise ScenarioError("[orbit] kind = 'tle' needs tle_path = '<file>'")


@dataclass(frozen=True)
class PassConfig:
    """Where and when the imaged strip is: its centre, on the descending (daylight) branch.

    For a phased or elements orbit the orbit's phase is chosen so that the strip's centre
    is seen at the target on ``date_utc`` (nadir track there, or the mirror's view there with
    ``aim = "view"``); for a TLE the strip is centred where the track passes closest to the
    target within ``search_days`` after the TLE epoch (``date_utc`` is then unused: the day
    is the TLE's, and the strip lies where that orbit's track crosses the target latitude).
    """

    date_utc: str = _key("1998-02-20", "date_utc", "day of the pass (UTC, YYYY-MM-DD)")
    target_lat_rad: float = _key(-15.6, "target_lat_deg", "latitude of the strip centre",
                                 _DEG, -80.0, 80.0)
    target_lon_rad: float = _key(-56.1, "target_lon_deg", "longitude of the strip centre",
                                 _DEG, -180.0, 180.0)
    aim: str = _key("view", "aim", "put the nadir track or the tilted view on the target",
                    choices=("nadir", "view"))
    search_days: float = _key(3.0, "search_days", "TLE: days searched for the closest pass",
                              1.0, 0.1, 30.0)
    ground_pass_days: float = _key(1.0, "ground_pass_days",
                                   "days over which receiving-station passes are listed",
                                   1.0, 0.0, 30.0)

    def __post_init__(self) -> None:
        try:
            np.datetime64(self.date_utc, "D")
        except ValueError:
            raise ScenarioError(
                f"[pass] date_utc = {self.date_utc!r}: expected a UTC day 'YYYY-MM-DD'"
            ) from None


@dataclass(frozen=True)
class GroundStationConfig:
    """The receiving station (Cuiabá by default) and its antenna's elevation mask."""

    name: str = _key("Cuiabá", "name", "station name for reports")
    lat_rad: float = _key(-15.555, "lat_deg", "geodetic latitude", _DEG, -90.0, 90.0)
    lon_rad: float = _key(-56.07, "lon_deg", "longitude", _DEG, -180.0, 180.0)
    height_m: float = _key(200.0, "height_m", "ellipsoidal height", 1.0, -500.0, 9000.0)
    elevation_mask_rad: float = _key(5.0, "elevation_mask_deg", "lowest elevation tracked",
                                     _DEG, 0.0, 45.0)


@dataclass(frozen=True)
class AttitudeConfig:
    """Truth attitude and the gyros that measure it.

    Offsets are Westin's constant ω0, ρ0, κ0 (unknown to the station: rates do not see them).
    The drift follows Westin's SPOT 1 variograms (paper ``000_…`` eqs. 24–26) scaled by
    ``drift_scale`` (0 switches it off). Jitter is a sinusoid per axis. The gyros report the
    mean angular rate over each ``gyro_period_s`` with white noise, quantised to ``gyro_lsb``.
    """

    roll0_rad: float = _key(150.0, "roll_offset_urad", "constant roll offset ω0", _URAD,
                            -5e4, 5e4)
    pitch0_rad: float = _key(-200.0, "pitch_offset_urad", "constant pitch offset ρ0", _URAD,
                             -5e4, 5e4)
    yaw0_rad: float = _key(300.0, "yaw_offset_urad", "constant yaw offset κ0", _URAD,
                           -5e4, 5e4)
    drift_scale: float = _key(1.0, "drift_scale", "factor on Westin's variograms (0: none)",
                              1.0, 0.0, 100.0)
    jitter_amplitude_rad: tuple[float, float, float] = _key(
        [0.3, 0.3, 0.1], "jitter_amplitude_urad", "jitter amplitude in roll, pitch, yaw",
        _URAD, 0.0, 100.0)
    jitter_frequency_hz: tuple[float, float, float] = _key(
        [27.0, 31.0, 13.0], "jitter_frequency_hz", "jitter frequency in roll, pitch, yaw",
        1.0, 0.0, 300.0)
    gyro_period_s: float = _key(0.125, "gyro_period_s", "gyro sampling period", 1.0,
                                0.001, 10.0)
    gyro_noise_rad_per_s: float = _key(0.5, "gyro_noise_urad_per_s", "gyro white noise (1σ)",
                                       _URAD, 0.0, 1e3)
    gyro_lsb_rad_per_s: float = _key(0.2, "gyro_lsb_urad_per_s", "gyro quantisation step",
                                     _URAD, 0.0, 1e3)


@dataclass(frozen=True)
class InstrumentConfig:
    """The HRV that images the strip, its mode and mirror, and the sizes rendered.

    Sizes can be reduced without changing the physics: ``n_detectors`` fewer detectors
    spread over the same swath (a proportionally wider IFOV), ``first_detector`` and
    ``detector_count`` a window of the array, ``n_lines`` the lines rendered.

    Written ``[[instrument]]`` twice, both HRVs image the pass at once, each with its own
    mode, mirror and sizes, and each sent on its own X-band channel: the first one given
    aims the orbit (``[pass] aim``).
    """

    hrv: int = _key(1, "hrv", "which HRV (the twins look 3.926° apart)", lo=1, hi=2)
    mode: str = _key("P", "mode", "panchromatic or multispectral", choices=("P", "XS"))
    twin: bool = _key(False, "twin", "twin configuration: the HRVs look 3.926° apart")
    mirror_step: int = _key(48, "mirror_step", "mirror step (48 = nadir, 0.6° per step)",
                            lo=3, hi=93)
    n_detectors: int = _key(0, "n_detectors", "detectors across the swath (0: 6000 P, 3000 XS)",
                            lo=0, hi=6000)
    first_detector: int = _key(0, "first_detector", "first detector rendered (0-based)",
                               lo=0, hi=5999)
    detector_count: int = _key(0, "detector_count", "detectors rendered (0: all)",
                               lo=0, hi=6000)
    n_lines: int = _key(0, "n_lines", "lines rendered (0: one 60 km scene)", lo=0, hi=10**6)
    butting_offsets_rad: tuple[float, float, float, float] = _key(
        [0.0, 4.0, -3.0, 2.0], "butting_offsets_urad",
        "along-track offset of each of the 4 CCDs", _URAD, -200.0, 200.0)
    calibration_error_rad: float = _key(1.0, "calibration_error_urad",
                                        "1σ error of the nominal look angles (unknown)", _URAD,
                                        0.0, 100.0)
    gain_spread: float = _key(0.05, "gain_spread", "1σ relative spread of detector gains",
                              1.0, 0.0, 0.5)
    offset_spread_counts: float = _key(2.0, "offset_spread_counts",
                                       "1σ spread of detector dark offsets (counts)", 1.0,
                                       0.0, 50.0)
    noise_counts: float = _key(0.7, "noise_counts", "1σ read noise (counts)", 1.0, 0.0, 20.0)
    psf_fwhm_px: float = _key(1.2, "psf_fwhm_px", "FWHM of the Gaussian PSF (0: none)", 1.0,
                              0.0, 5.0)
    psf_samples: int = _key(3, "psf_samples", "PSF samples per pixel side (1: centre only)",
                            lo=1, hi=7)

    def __post_init__(self) -> None:
        full = 6000 if self.mode == "P" else 3000
        n = self.n_detectors or full
        if n > full:
            raise ScenarioError(
                f"[instrument] n_detectors = {n}: mode {self.mode} has at most {full}"
            )
        count = self.detector_count or n - self.first_detector
        if self.first_detector + count > n or count < 1:
            raise ScenarioError(
                f"[instrument] first_detector = {self.first_detector}, detector_count = "
                f"{self.detector_count}: the window must lie within the {n} detectors"
            )


@dataclass(frozen=True)
class WorldConfig:
    """The ground: fractal relief and reflectance, continuous in latitude and longitude."""

    kind: str = _key("fractal", "kind", "synthetic world or a DEM file",
                     choices=("fractal", "dem"))
    dem_path: str = _key("", "dem_path", "DEM file (kind = 'dem'), relative to the scenario")
    base_height_m: float = _key(450.0, "base_height_m", "mean terrain height", 1.0,
                                -400.0, 6000.0)
    relief_m: float = _key(250.0, "relief_m", "relief amplitude (std of the fractal)", 1.0,
                           0.0, 3000.0)
    seed: int = _key(7, "seed", "seed of the world's noise", lo=0, hi=2**31 - 1)

    def __post_init__(self) -> None:
        if self.kind == "dem" and not self.dem_path:
            raise ScenarioError("[world] kind = 'dem' needs dem_path = '<file>'")


@dataclass(frozen=True)
class BulletinConfig:
    """Ephemeris bulletins handed to the station, with their errors (along, across, radial)."""

    period_s: float = _key(60.0, "period_s", "spacing of the bulletin points", 1.0, 1.0, 600.0)
    bias_m: tuple[float, float, float] = _key(
        [150.0, -100.0, 20.0], "bias_m", "position bias along, across track, radial", 1.0,
        -1e5, 1e5)
    drift_m_per_s: tuple[float, float, float] = _key(
        [0.05, 0.02, 0.0], "drift_m_per_s", "growth of that bias per second", 1.0, -100.0,
        100.0)
    margin_s: float = _key(240.0, "margin_s", "bulletin span beyond the strip at each end",
                           1.0, 0.0, 3600.0)


@dataclass(frozen=True)
class CalibrationConfig:
    """The calibration table handed to the station (gains and offsets, with its own error)."""

    gain_error: float = _key(0.002, "gain_error", "1σ relative error of the table's gains",
                             1.0, 0.0, 0.1)
    offset_error_counts: float = _key(0.2, "offset_error_counts",
                                      "1σ error of the table's offsets (counts)", 1.0, 0.0, 10.0)


@dataclass(frozen=True)
class GcpConfig:
    """Ground control points: truth points with map-like errors, and their raw-image place."""

    count: int = _key(12, "count", "control points in the strip", lo=0, hi=10000)
    horizontal_error_m: float = _key(8.0, "horizontal_error_m", "1σ map error per axis", 1.0,
                                     0.0, 1000.0)
    vertical_error_m: float = _key(5.0, "vertical_error_m", "1σ map height error", 1.0,
                                   0.0, 1000.0)
    pointing_error_px: float = _key(0.3, "pointing_error_px",
                                    "1σ error of the image measurement per axis", 1.0, 0.0, 10.0)


@dataclass(frozen=True)
class DownlinkConfig:
    """The sender on board: bit rate and framing of the X-band session (docs/telemetry.md)."""

    bit_rate_bit_per_s: float = _key(25.0, "bit_rate_mbps", "channel bit rate per HRV",
                                     1e6, 0.1, 1000.0)
    preamble_s: float = _key(0.2, "preamble_s", "fill frames sent before the first data",
                             1.0, 0.0, 60.0)
    postamble_s: float = _key(0.2, "postamble_s", "fill frames sent after the last data",
                              1.0, 0.0, 60.0)
    first_frame_count: int = _key(-1, "first_frame_count",
                                  "first frame count of the data channel (-1: drawn)",
                                  lo=-1, hi=2**24 - 1)
    first_line_counter: int = _key(-1, "first_line_counter",
                                   "line counter of the strip's first line (-1: drawn)",
                                   lo=-1, hi=2**31)


@dataclass(frozen=True)
class ChannelConfig:
    """The impairments between the sender and the station's recorder.

    Random bit errors at ``ber``; Gilbert–Elliott bursts (a bad state entered at
    ``burst_rate_per_s`` at zenith, rising as 1/sin²(elevation) towards the horizon, lasting
    ``burst_length_bits`` on average, with ``burst_ber`` inside); fades that replace whole
    stretches with noise and slip the bit clock; stretches of frames replayed twice (tape
    replay overlap); frames displaced by a few places. An outage is one fade placed by hand
    (``outage_start_s`` after the first frame, for ``outage_duration_s``): the antenna
    losing track, a demodulator fault; being the station's, it strikes both HRVs' channels.
    """

    ber: float = _key(1e-7, "ber", "random bit error rate", 1.0, 0.0, 0.01)
    burst_rate_per_s: float = _key(0.2, "burst_rate_per_s", "bursts per second at zenith",
                                   1.0, 0.0, 1e4)
    burst_length_bits: float = _key(300.0, "burst_length_bits", "mean burst length", 1.0,
                                    1.0, 1e7)
    burst_ber: float = _key(0.05, "burst_ber", "bit error rate inside a burst", 1.0, 0.0, 0.5)
    fade_rate_per_min: float = _key(0.0, "fade_rate_per_min", "fades per minute", 1.0,
                                    0.0, 600.0)
    fade_duration_s: float = _key(20.0, "fade_duration_ms", "mean duration of a fade", 1e-3,
                                  0.001, 60000.0)
    replay_runs: int = _key(0, "replay_runs", "stretches of frames sent twice", lo=0, hi=10000)
    replay_frames: int = _key(50, "replay_frames", "frames in each replayed stretch", lo=1,
                              hi=10**6)
    reorder_fraction: float = _key(0.0, "reorder_fraction", "fraction of frames displaced",
                                   1.0, 0.0, 0.5)
    reorder_distance: int = _key(3, "reorder_distance", "largest displacement, in frames",
                                 lo=1, hi=1000)
    outage_start_s: float = _key(0.0, "outage_start_s",
                                 "start of an outage, after the first frame sent", 1.0,
                                 0.0, 86400.0)
    outage_duration_s: float = _key(0.0, "outage_duration_s", "its duration (0: none)", 1.0,
                                    0.0, 3600.0)


@dataclass(frozen=True)
class ProcessingConfig:
    """The processing centre: which levels, how scenes are cut, GEO's and COR's options.

    The reference height is the scene's mean altitude the producer would take from a global
    DEM: levels 1B and 2A are located on the ellipsoid raised by it. The PSF is the
    instrument's nominal one, which the deconvolution of 1B and 2A inverts.
    """

    levels: tuple[str, ...] = _key(["1A", "1B", "2A"], "levels", "levels to produce",
                                   choices=("1A", "1B", "2A"))
    scene_lines: int = _key(0, "scene_lines", "lines per scene (0: as many as detectors)",
                            lo=0, hi=10**6)
    overlap_lines: int = _key(0, "overlap_lines", "lines shared by consecutive scenes",
                              lo=0, hi=10**6)
    reference_height_m: float = _key(450.0, "reference_height_m",
                                     "mean scene altitude of levels 1B and 2A", 1.0,
                                     -500.0, 9000.0)
    pixel_size_m: float = _key(0.0, "pixel_size_m",
                               "output pixel (0: 10 m P, 20 m XS, times the detector scale)",
                               1.0, 0.0, 10000.0)
    interpolation_1b: str = _key("cubic", "interpolation_1b", "1B column interpolation",
                                 choices=("nearest", "cubic"))
    resampling_2a: str = _key("cubic", "resampling_2a", "2A resampling",
                              choices=("nearest", "bilinear", "cubic"))
    inverse_2a: str = _key("nearest4", "inverse_2a", "2A inverse mapping",
                           choices=("nearest4", "poly3", "poly4", "poly5"))
    grid_rows: str = _key("attitude", "grid_rows",
                          "2A direct-grid rows: at the attitude samples or INPE's regular 61",
                          choices=("attitude", "regular"))
    crs: str = _key("utm", "crs", "2A map: 'utm' (zone of the centre), 'som', or EPSG/WKT")
    deconvolution: bool = _key(True, "deconvolution", "deconvolve 1B and 2A")
    psf_fwhm_px: float = _key(1.2, "psf_fwhm_px", "nominal PSF of the instrument (FWHM)",
                              1.0, 0.0, 5.0)
    noise_to_signal: float = _key(0.05, "noise_to_signal",
                                  "Wiener noise-to-signal ratio of the deconvolution", 1.0,
                                  1e-4, 10.0)
    checkpoints_per_side: int = _key(11, "checkpoints_per_side",
                                     "checkpoint lattice of the quality figures", lo=2, hi=101)

    def __post_init__(self) -> None:
        if self.overlap_lines and self.scene_lines and self.overlap_lines >= self.scene_lines:
            raise ScenarioError(f"[processing] overlap_lines = {self.overlap_lines} must be "
                                f"less than scene_lines = {self.scene_lines}")


_SECTIONS = {
    "orbit": OrbitConfig,
    "pass": PassConfig,
    "ground_station": GroundStationConfig,
    "attitude": AttitudeConfig,
    "instrument": InstrumentConfig,
    "world": WorldConfig,
    "bulletins": BulletinConfig,
    "calibration": CalibrationConfig,
    "gcps": GcpConfig,
    "downlink": DownlinkConfig,
    "channel": ChannelConfig,
    "processing": ProcessingConfig,
}


@dataclass(frozen=True)
class Scenario:
    """A whole scenario: a name, a seed for every random draw, and one config per section.

    ``base_dir`` is the directory of the scenario file; relative paths in it are resolved
    from there.
    """

    name: str = "default"
    seed: int = 1
    orbit: OrbitConfig = field(default_factory=OrbitConfig)
    pass_: PassConfig = field(default_factory=PassConfig)
    ground_station: GroundStationConfig = field(default_factory=GroundStationConfig)
    attitude: AttitudeConfig = field(default_factory=AttitudeConfig)
    instrument: InstrumentConfig = field(default_factory=InstrumentConfig)
    world: WorldConfig = field(default_factory=WorldConfig)
    bulletins: BulletinConfig = field(default_factory=BulletinConfig)
    calibration: CalibrationConfig = field(default_factory=CalibrationConfig)
    gcps: GcpConfig = field(default_factory=GcpConfig)
    downlink: DownlinkConfig = field(default_factory=DownlinkConfig)
    channel: ChannelConfig = field(default_factory=ChannelConfig)
    processing: ProcessingConfig = field(default_factory=ProcessingConfig)
    #: The second HRV of a pass imaged by both (``[[instrument]]`` given twice), or ().
    more_instruments: tuple[InstrumentConfig, ...] = ()
    base_dir: str = "."
    #: The scenario file and the SHA-256 of its bytes ("" when built from a dict).
    source: str = ""
    source_sha256: str = ""

    def __post_init__(self) -> None:
        numbers = [i.hrv for i in self.instruments]
        if len(set(numbers)) != len(numbers):
            raise ScenarioError(f"[[instrument]]: hrv = {numbers}: each HRV images once "
                                "per pass; give each [[instrument]] its own hrv (1 or 2)")

    @property
    def instruments(self) -> tuple[InstrumentConfig, ...]:
        """Every HRV imaging the pass: ``instrument`` first (it aims the orbit)."""
        return (self.instrument, *self.more_instruments)

    def path(self, relative: str) -> Path:
        """A path of the scenario, resolved from the scenario file's directory."""
        p = Path(relative)
        return p if p.is_absolute() else Path(self.base_dir) / p


def _describe(meta: dict[str, Any], typ: Any) -> str:
    if meta["choices"] and typing.get_args(typ) == (str, Ellipsis):
        return "a list, without repeats, of " + ", ".join(repr(c) for c in meta["choices"])
    if meta["choices"]:
        return "one of " + ", ".join(repr(c) for c in meta["choices"])
    kind = {int: "an integer", float: "a number", str: "a string", bool: "true or false"}.get(
        typ, "")
    if typing.get_origin(typ) is tuple:
        kind = f"a list of {len(typing.get_args(typ))} numbers"
    lo, hi = meta["lo"], meta["hi"]
    if lo is not None and hi is not None:
        return f"{kind} in [{lo:g}, {hi:g}]"
    return kind


def _convert(section: str, f: Any, typ: Any, value: Any) -> Any:
    meta = f.metadata
    name = f"[{section}] {meta['key']}" if section else meta["key"]
    allowed = _describe(meta, typ)

    def bad() -> ScenarioError:
        return ScenarioError(f"{name} = {value!r}: expected {allowed}")

    def number(v: Any) -> float:
        if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
            raise bad()
        lo, hi = meta["lo"], meta["hi"]
        if (lo is not None and v < lo) or (hi is not None and v > hi):
            raise bad()
        return float(v) * meta["scale"]

    if typ is bool:
        if not isinstance(value, bool):
            raise bad()
        return value
    if typ is str:
        if not isinstance(value, str):
            raise bad()
        if meta["choices"] and value not in meta["choices"]:
            raise bad()
        return value
    if typ is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise bad()
        number(value)
        return value
    if typ is float:
        return number(value)
    if typing.get_args(typ) == (str, Ellipsis):
        if (not isinstance(value, list) or not value or len(set(value)) != len(value)
                or any(v not in (meta["choices"] or ()) for v in value)):
            raise bad()
        return tuple(value)
    if typing.get_origin(typ) is tuple:
        n = len(typing.get_args(typ))
        if not isinstance(value, list) or len(value) != n:
            raise bad()
        return tuple(number(v) for v in value)
    raise TypeError(f"unsupported field type {typ!r}")  # a declaration bug, not user input


def _build(cls: type, section: str, table: Any) -> Any:
    if not isinstance(table, dict):
        raise ScenarioError(f"[{section}] must be a table, got {table!r}")
    hints = typing.get_type_hints(cls)
    by_key = {f.metadata["key"]: f for f in fields(cls) if "key" in f.metadata}
    unknown = sorted(set(table) - set(by_key))
    if unknown:
        raise ScenarioError(
            f"[{section}] unknown key {unknown[0]!r}; allowed: {', '.join(sorted(by_key))}"
        )
    kwargs = {
        f.name: _convert(section, f, hints[f.name], table[key])
        for key, f in by_key.items()
        if key in table
    }
    try:
        return cls(**kwargs)
    except ScenarioError:
        raise
    except (TypeError, ValueError) as exc:  # cross-field checks of __post_init__
        raise ScenarioError(f"[{section}]: {exc}") from None


def scenario_from_dict(data: dict[str, Any], base_dir: str | Path = ".") -> Scenario:
    """A :class:`Scenario` from a parsed TOML table (see the module docstring)."""
    top = {"name": str, "seed": int}
    allowed = sorted([*top, *_SECTIONS])
    kwargs: dict[str, Any] = {"base_dir": str(base_dir)}
    for key, value in data.items():
        if key in top:
            ok = isinstance(value, top[key]) and not isinstance(value, bool)
            if not ok or (key == "seed" and not 0 <= value < 2**63):
                want = "a string" if key == "name" else "an integer in [0, 2**63)"
                raise ScenarioError(f"{key} = {value!r}: expected {want}")
            kwargs[key] = value
        elif key == "instrument" and isinstance(value, list):
            if not 1 <= len(value) <= 2:
                raise ScenarioError(f"[[instrument]] given {len(value)} times: a SPOT "
                                    "carries two HRVs, give one or two")
            built = [_build(InstrumentConfig, "instrument", v) for v in value]
            kwargs["instrument"], kwargs["more_instruments"] = built[0], tuple(built[1:])
        elif key in _SECTIONS:
            kwargs["pass_" if key == "pass" else key] = _build(_SECTIONS[key], key, value)
        else:
            raise ScenarioError(f"unknown key {key!r}; allowed: {', '.join(allowed)}")
    return Scenario(**kwargs)


def read_toml(path: str | Path, what: str = "scenario") -> tuple[dict[str, Any], bytes]:
    """A TOML file's table and its bytes; :class:`ScenarioError` names what is wrong."""
    p = Path(path)
    try:
        raw = p.read_bytes()
        return tomllib.loads(raw.decode("utf-8")), raw
    except FileNotFoundError:
        raise ScenarioError(f"{what} file {p} not found") from None
    except IsADirectoryError:
        raise ScenarioError(f"{what} {p} is a directory, not a .toml file") from None
    except UnicodeDecodeError:
        raise ScenarioError(f"{p}: not a text file (UTF-8)") from None
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(f"{p}: not valid TOML ({exc})") from None


def load_scenario(path: str | Path) -> Scenario:
    """Read and validate a scenario file; :class:`ScenarioError` says what is wrong."""
    p = Path(path)
    data, raw = read_toml(p)
    scn = scenario_from_dict(data, p.resolve().parent)
    return dataclasses.replace(scn, source=str(p.resolve()),
                               source_sha256=hashlib.sha256(raw).hexdigest())


def describe_keys() -> str:
    """Every key of every section, with its default (TOML units), range and meaning."""
    lines = []
    for section, cls in _SECTIONS.items():
        lines.append(f"[{section}]")
        hints = typing.get_type_hints(cls)
        for f in fields(cls):
            meta = f.metadata
            default = f.default if f.default is not MISSING else None
            if isinstance(default, float):
                default = default / meta["scale"]
            elif isinstance(default, tuple):
                default = [v if isinstance(v, str) else round(v / meta["scale"], 12)
                           for v in default]
            lines.append(
                f"  {meta['key']} = {default!r}  # {meta['doc']}; {_describe(meta, hints[f.name])}"
            )
    return "\n".join(lines)

