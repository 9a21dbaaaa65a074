"""Scenario files: a TOML description of a pass, turned at once into frozen dataclasses.

A scenario can be three lines long: every section and every key has a default, the SPOT 1–4
facts of ``DESIGN.md`` sized so that the system-corrected levels land in Spot Image's
published error budget. Keys carry their unit as a suffix (``altitude_km``,
``roll_offset_urad``); the dataclasses hold SI values (``altitude_m``, ``roll0_rad``),
converted here once. An unknown key, a wrong type or a value out of range is rejected with
a :class:`ScenarioError` naming the key, the value and what is allowed.

Every field of every section is declared once with :func:`levels.options.option`: its TOML
name, the factor to SI, its allowed range and a one-line meaning. The error messages and the
listing of :func:`station.loader.describe_keys` are generated from those declarations, so
they cannot drift apart.
"""

from __future__ import annotations

import math
import re
import tomllib
import unicodedata
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from levels.options import ProcessingOptions, build_section, option
from levels.spot import MODES
from station.errors import ScenarioError
from station.telemetry.format import CNES_EPOCH

__all__ = [
    "ERRORS_OFF",
    "AttitudeConfig",
    "BulletinConfig",
    "CalibrationConfig",
    "ChannelConfig",
    "DemConfig",
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
    "check_name",
    "merge_tables",
    "read_toml",
    "scenario_from_dict",
]

_DEG = math.pi / 180.0
_URAD = 1e-6


@dataclass(frozen=True)
class OrbitConfig:
    """The truth orbit: a phased sun-synchronous orbit, given mean elements, or a TLE.

    ``kind = "phased"`` solves the mean semi-major axis and inclination for which the orbit
    repeats after ``repeat_revs`` revolutions in ``repeat_days`` days and its node drifts with
    the mean Sun (SPOT: 369 revolutions in 26 days, 14 + 5/26 rev/day, 822 km, 98.7°).
    ``kind = "elements"`` takes ``altitude_km`` and ``inclination_deg`` as given mean elements.
    ``kind = "tle"`` starts from record ``tle_index`` of ``tle_path``.
    """

    kind: str = option(
        "phased", "kind", "how the orbit is given", choices=("phased", "elements", "tle")
    )
    repeat_revs: int = option(369, "repeat_revs", "revolutions in one repeat cycle", lo=1, hi=10000)
    repeat_days: int = option(26, "repeat_days", "days of one repeat cycle", lo=1, hi=1000)
    altitude_m: float = option(
        822.0, "altitude_km", "mean altitude above the equator (elements)", 1e3, 200.0, 2000.0
    )
    inclination_rad: float = option(
        98.7, "inclination_deg", "mean inclination (elements)", _DEG, 0.0, 180.0
    )
    eccentricity: float = option(
        0.0, "eccentricity", "mean eccentricity (elements, phased)", 1.0, 0.0, 0.05
    )
    descending_node_local_time_h: float = option(
        10.5,
        "descending_node_local_time_h",
        "mean local solar time of the descending node",
        1.0,
        0.0,
        24.0,
    )
    tle_path: str = option("", "tle_path", "TLE file (kind = 'tle'), relative to the scenario")
    tle_index: int = option(0, "tle_index", "which record of the TLE file", lo=0, hi=10000)

    def __post_init__(self) -> None:
        if self.kind == "tle" and not self.tle_path:
            raise ScenarioError("[orbit] kind = 'tle' needs tle_path = '<file>'")


#: The last day a pass may be asked for (excluded): nanoseconds since 1950 in 64 bits
#: reach 2242 (the telemetry's time codes, a 2⁴⁴ ms counter, reach 2507).
LAST_PASS_DAY = np.datetime64("2200-01-01", "D")


@dataclass(frozen=True)
class PassConfig:
    """Where and when the imaged strip is: its centre, on the descending (daylight) branch.

    For a phased or elements orbit the orbit's phase is chosen so that the strip's centre
    is seen at the target on ``date_utc`` (nadir track there, or the mirror's view there with
    ``aim = "view"``); for a TLE the strip is centred where the track passes closest to the
    target within ``search_days`` after the TLE epoch (``date_utc`` is then unused: the day
    is the TLE's, and the strip lies where that orbit's track crosses the target latitude).
    """

    date_utc: str = option("1998-02-20", "date_utc", "day of the pass (UTC, YYYY-MM-DD)")
    target_lat_rad: float = option(
        -15.6, "target_lat_deg", "latitude of the strip centre", _DEG, -80.0, 80.0
    )
    target_lon_rad: float = option(
        -56.1, "target_lon_deg", "longitude of the strip centre", _DEG, -180.0, 180.0
    )
    aim: str = option(
        "view",
        "aim",
        "put the nadir track or the tilted view on the target",
        choices=("nadir", "view"),
    )
    search_days: float = option(
        3.0, "search_days", "TLE: days searched for the closest pass", 1.0, 0.1, 30.0
    )
    ground_pass_days: float = option(
        1.0,
        "ground_pass_days",
        "days over which receiving-station passes are listed",
        1.0,
        0.0,
        30.0,
    )

    def __post_init__(self) -> None:
        try:
            day = np.datetime64(self.date_utc, "D")
        except ValueError:
            raise ScenarioError(
                f"[pass] date_utc = {self.date_utc!r}: expected a UTC day 'YYYY-MM-DD'"
            ) from None
        first = CNES_EPOCH.astype("datetime64[D]")
        if not first <= day < LAST_PASS_DAY:
            raise ScenarioError(
                f"[pass] date_utc = {self.date_utc!r}: give a day from {first} (CNES day 0, "
                f"where SPOT's time codes start) to {LAST_PASS_DAY - 1} (the emulator's "
                "nanosecond clocks end in 2242)"
            )


@dataclass(frozen=True)
class GroundStationConfig:
    """The receiving station (Cuiabá by default) and its antenna's elevation mask."""

    name: str = option("Cuiabá", "name", "station name for reports")
    lat_rad: float = option(-15.555, "lat_deg", "geodetic latitude", _DEG, -90.0, 90.0)
    lon_rad: float = option(-56.07, "lon_deg", "longitude", _DEG, -180.0, 180.0)
    height_m: float = option(200.0, "height_m", "ellipsoidal height", 1.0, -500.0, 9000.0)
    elevation_mask_rad: float = option(
        5.0, "elevation_mask_deg", "lowest elevation tracked", _DEG, 0.0, 45.0
    )


@dataclass(frozen=True)
class AttitudeConfig:
    """Truth attitude and the gyros that measure it.

    Offsets are Westin's constant ω0, ρ0, κ0 (unknown to the station: rates do not see them).
    The drift follows Westin's SPOT 1 variograms (paper ``000_…`` eqs. 24–26) scaled by
    ``drift_scale`` (0 switches it off). Jitter is a sinusoid per axis. The gyros report the
    mean angular rate over each ``gyro_period_s`` with white noise, quantised to ``gyro_lsb``.
    """

    roll0_rad: float = option(
        150.0, "roll_offset_urad", "constant roll offset ω0", _URAD, -5e4, 5e4
    )
    pitch0_rad: float = option(
        -200.0, "pitch_offset_urad", "constant pitch offset ρ0", _URAD, -5e4, 5e4
    )
    yaw0_rad: float = option(300.0, "yaw_offset_urad", "constant yaw offset κ0", _URAD, -5e4, 5e4)
    drift_scale: float = option(
        1.0, "drift_scale", "factor on Westin's variograms (0: none)", 1.0, 0.0, 100.0
    )
    jitter_amplitude_rad: tuple[float, float, float] = option(
        [0.3, 0.3, 0.1],
        "jitter_amplitude_urad",
        "jitter amplitude in roll, pitch, yaw",
        _URAD,
        0.0,
        100.0,
    )
    jitter_frequency_hz: tuple[float, float, float] = option(
        [27.0, 31.0, 13.0],
        "jitter_frequency_hz",
        "jitter frequency in roll, pitch, yaw",
        1.0,
        0.0,
        300.0,
    )
    gyro_period_s: float = option(0.125, "gyro_period_s", "gyro sampling period", 1.0, 0.001, 10.0)
    gyro_noise_rad_per_s: float = option(
        0.5, "gyro_noise_urad_per_s", "gyro white noise (1σ)", _URAD, 0.0, 1e3
    )
    gyro_lsb_rad_per_s: float = option(
        0.2, "gyro_lsb_urad_per_s", "gyro quantisation step", _URAD, 0.0, 1e3
    )
    reference_velocity: str = option(
        "inertial",
        "reference_velocity",
        "velocity the attitude's orbital frame follows: inertial (SPOT 1–4) or Earth-fixed "
        "(SPOT 5); the ephemeris bulletins carry the same",
        choices=("inertial", "earth_fixed"),
    )


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

    hrv: int = option(1, "hrv", "which HRV (the twins look 3.926° apart)", lo=1, hi=2)
    mode: str = option("P", "mode", "panchromatic or multispectral", choices=("P", "XS"))
    twin: bool = option(False, "twin", "twin configuration: the HRVs look 3.926° apart")
    mirror_step: int = option(
        48, "mirror_step", "mirror step (48 = nadir, 0.6° per step)", lo=3, hi=93
    )
    n_detectors: int = option(
        0, "n_detectors", "detectors across the swath (0: 6000 P, 3000 XS)", lo=0, hi=6000
    )
    first_detector: int = option(
        0, "first_detector", "first detector rendered (0-based)", lo=0, hi=5999
    )
    detector_count: int = option(0, "detector_count", "detectors rendered (0: all)", lo=0, hi=6000)
    n_lines: int = option(0, "n_lines", "lines rendered (0: one 60 km scene)", lo=0, hi=10**6)
    butting_offsets_rad: tuple[float, float, float, float] = option(
        [0.0, 4.0, -3.0, 2.0],
        "butting_offsets_urad",
        "along-track offset of each of the 4 CCDs",
        _URAD,
        -200.0,
        200.0,
    )
    calibration_error_rad: float = option(
        1.0,
        "calibration_error_urad",
        "1σ error of the nominal look angles (unknown)",
        _URAD,
        0.0,
        100.0,
    )
    gain_spread: float = option(
        0.05, "gain_spread", "1σ relative spread of detector gains", 1.0, 0.0, 0.5
    )
    offset_spread_counts: float = option(
        2.0, "offset_spread_counts", "1σ spread of detector dark offsets (counts)", 1.0, 0.0, 50.0
    )
    noise_counts: float = option(0.7, "noise_counts", "1σ read noise (counts)", 1.0, 0.0, 20.0)
    psf_fwhm_px: float = option(
        1.2, "psf_fwhm_px", "FWHM of the Gaussian PSF (0: none)", 1.0, 0.0, 5.0
    )
    psf_samples: int = option(
        3, "psf_samples", "PSF samples per pixel side (1: centre only)", lo=1, hi=7
    )

    def __post_init__(self) -> None:
        if self.n_lines == 1:
            raise ScenarioError(
                "[instrument] n_lines = 1: a strip needs at least 2 lines (0: one 60 km scene)"
            )
        full = MODES[self.mode].detectors
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

    kind: str = option(
        "fractal", "kind", "synthetic world or a DEM file", choices=("fractal", "dem")
    )
    dem_path: str = option("", "dem_path", "DEM file (kind = 'dem'), relative to the scenario")
    base_height_m: float = option(
        450.0, "base_height_m", "mean terrain height", 1.0, -400.0, 6000.0
    )
    relief_m: float = option(
        250.0, "relief_m", "relief amplitude (std of the fractal)", 1.0, 0.0, 3000.0
    )
    seed: int = option(7, "seed", "seed of the world's noise", lo=0, hi=2**31 - 1)
    rows_m: float = option(
        0.0,
        "rows_m",
        "rows planted in every parcel, of this period (0: none): a periodic field",
        1.0,
        0.0,
        10000.0,
    )

    def __post_init__(self) -> None:
        if self.kind == "dem" and not self.dem_path:
            raise ScenarioError("[world] kind = 'dem' needs dem_path = '<file>'")


@dataclass(frozen=True)
class ReferenceConfig:
    """A reference ortho-image of the world, as another sensor gives it
    (:mod:`station.spacecraft.reference`), written as ``<name>.reference.tif`` into the run
    directory with its truth: what control points are found on (``station gcps``)."""

    pixel_size_m: float = option(10.0, "pixel_size_m", "its pixel (m)", 1.0, 1.0, 1000.0)
    band: str = option("P", "band", "the band it sees", choices=("P", "XS1", "XS2", "XS3"))
    projection: str = option("utm", "projection", "its map grid", choices=("utm", "EPSG:4326"))
    error_ce95_m: float = option(
        0.0, "error_ce95_m", "its geolocation error, 95 % circular (a bias drawn)", 1.0, 0.0, 1e4
    )
    bias_east_m: float = option(0.0, "bias_east_m", "a bias added east (m)", 1.0, -1e4, 1e4)
    bias_north_m: float = option(0.0, "bias_north_m", "a bias added north (m)", 1.0, -1e4, 1e4)
    gain: float = option(1.0, "gain", "its radiometric gain on reflectance", 1.0, 1e-3, 1e3)
    offset: float = option(0.0, "offset", "its radiometric offset", 1.0, -1e3, 1e3)
    season: float = option(
        0.0, "season", "a smooth relative change over 3 km (another season)", 1.0, 0.0, 1.0
    )
    cloud_fraction: float = option(0.0, "cloud_fraction", "its cloud cover", 1.0, 0.0, 0.9)
    margin_km: float = option(2.0, "margin_km", "its margin around the pass", 1.0, 0.0, 100.0)
    file: str = option(
        "",
        "file",
        "an existing reference image (relative to the scenario; its truth <stem>.json beside "
        "it, if any) used as it is: the options above are then not used",
    )


@dataclass(frozen=True)
class DemConfig:
    """The DEM the station is handed for level 3: the world's terrain sampled on a
    latitude–longitude grid over the pass (ellipsoidal heights), with errors of a known
    size, written as ``<name>.dem.tif`` into the run directory
    (:func:`station.spacecraft.dem.export_dem`); never the truth itself."""

    spacing_arcsec: float = option(
        1.0, "spacing_arcsec", 'grid spacing (1: SRTM 1", about 30 m)', 1.0, 0.1, 3600.0
    )
    error_rms_m: float = option(
        0.0, "error_rms_m", "1σ of the height error added at each node", 1.0, 0.0, 1000.0
    )
    error_correlation_m: float = option(
        0.0,
        "error_correlation_m",
        "correlation length of that error (0: white from node to node); the error keeps its 1σ",
        1.0,
        0.0,
        1e5,
    )
    margin_km: float = option(
        5.0, "margin_km", "the grid's margin around the pass's footprint", 1.0, 0.0, 500.0
    )


@dataclass(frozen=True)
class BulletinConfig:
    """Ephemeris bulletins handed to the station, with their errors (along, across, radial)."""

    period_s: float = option(60.0, "period_s", "spacing of the bulletin points", 1.0, 1.0, 600.0)
    bias_m: tuple[float, float, float] = option(
        [150.0, -100.0, 20.0], "bias_m", "position bias along, across track, radial", 1.0, -1e5, 1e5
    )
    drift_m_per_s: tuple[float, float, float] = option(
        [0.05, 0.02, 0.0], "drift_m_per_s", "growth of that bias per second", 1.0, -100.0, 100.0
    )
    margin_s: float = option(
        240.0, "margin_s", "bulletin span beyond the strip at each end", 1.0, 0.0, 3600.0
    )


@dataclass(frozen=True)
class CalibrationConfig:
    """The calibration table handed to the station (gains and offsets, with its own error)."""

    gain_error: float = option(
        0.002, "gain_error", "1σ relative error of the table's gains", 1.0, 0.0, 0.1
    )
    offset_error_counts: float = option(
        0.2, "offset_error_counts", "1σ error of the table's offsets (counts)", 1.0, 0.0, 10.0
    )


@dataclass(frozen=True)
class GcpConfig:
    """Ground control points: truth points with map-like errors, and their raw-image place."""

    count: int = option(12, "count", "control points in the strip", lo=0, hi=10000)
    horizontal_error_m: float = option(
        8.0, "horizontal_error_m", "1σ map error per axis", 1.0, 0.0, 1000.0
    )
    vertical_error_m: float = option(
        5.0, "vertical_error_m", "1σ map height error", 1.0, 0.0, 1000.0
    )
    pointing_error_px: float = option(
        0.3, "pointing_error_px", "1σ error of the image measurement per axis", 1.0, 0.0, 10.0
    )
    line_ranges: tuple[float, ...] = option(
        [0.05, 0.95],
        "line_ranges",
        "where along the strip the points lie: pairs [from, to, from, to, …] of fractions "
        "of its lines (the count shared by their lengths)",
        1.0,
        0.0,
        1.0,
    )
    blunder_fraction: float = option(
        0.0,
        "blunder_fraction",
        "share of the points whose map position is a blunder",
        1.0,
        0.0,
        0.5,
    )
    blunder_m: float = option(
        100.0, "blunder_m", "how far a blunder's map position is off", 1.0, 0.0, 1e5
    )
    hrvs: tuple[float, ...] = option(
        [1, 2],
        "hrvs",
        "the HRVs whose control points were measured (a twin pass may have them in one "
        "only: the other's file then holds none)",
        1.0,
        1.0,
        2.0,
    )
    source: str = option(
        "drawn",
        "source",
        "drawn (the truth with the errors above) or reference (found on the run's [reference] "
        "ortho-image and [dem], station gcps)",
        choices=("drawn", "reference"),
    )
    shared: bool = option(
        False,
        "shared",
        "a block: the first pass's points are also measured in every other pass's images "
        "where they see them (stereo control points, as PHOTOMOD's: one map position, "
        "pointed in both images), beside that pass's own",
    )

    def __post_init__(self) -> None:
        if any(h not in (1.0, 2.0) for h in self.hrvs):
            raise ScenarioError(f"[gcps] hrvs = {list(self.hrvs)}: HRV numbers, 1 or 2")
        r = self.line_ranges
        if len(r) % 2 or any(a >= b for a, b in zip(r[::2], r[1::2], strict=True)):
            raise ScenarioError(
                f"[gcps] line_ranges = {list(r)}: expected pairs [from, to, …] with from < to"
            )


@dataclass(frozen=True)
class DownlinkConfig:
    """The sender on board: bit rate and framing of the X-band session (docs/telemetry.md)."""

    bit_rate_bit_per_s: float = option(
        25.0, "bit_rate_mbps", "channel bit rate per HRV", 1e6, 0.1, 1000.0
    )
    preamble_s: float = option(
        0.2, "preamble_s", "fill frames sent before the first data", 1.0, 0.0, 60.0
    )
    postamble_s: float = option(
        0.2, "postamble_s", "fill frames sent after the last data", 1.0, 0.0, 60.0
    )
    one_connection: bool = option(
        False,
        "one_connection",
        "the channels of a two-HRV pass multiplexed on one connection to a live front end",
    )
    first_frame_count: int = option(
        -1,
        "first_frame_count",
        "first frame count of the data channel (-1: drawn)",
        lo=-1,
        hi=2**24 - 1,
    )
    first_line_counter: int = option(
        -1,
        "first_line_counter",
        "line counter of the strip's first line (-1: drawn)",
        lo=-1,
        hi=2**31,
    )


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

    ber: float = option(1e-7, "ber", "random bit error rate", 1.0, 0.0, 0.01)
    burst_rate_per_s: float = option(
        0.2, "burst_rate_per_s", "bursts per second at zenith", 1.0, 0.0, 1e4
    )
    burst_length_bits: float = option(
        300.0, "burst_length_bits", "mean burst length", 1.0, 1.0, 1e7
    )
    burst_ber: float = option(0.05, "burst_ber", "bit error rate inside a burst", 1.0, 0.0, 0.5)
    fade_rate_per_min: float = option(0.0, "fade_rate_per_min", "fades per minute", 1.0, 0.0, 600.0)
    fade_duration_s: float = option(
        20.0, "fade_duration_ms", "mean duration of a fade", 1e-3, 0.001, 60000.0
    )
    replay_runs: int = option(0, "replay_runs", "stretches of frames sent twice", lo=0, hi=10000)
    replay_frames: int = option(
        50, "replay_frames", "frames in each replayed stretch", lo=1, hi=10**6
    )
    reorder_fraction: float = option(
        0.0, "reorder_fraction", "fraction of frames displaced", 1.0, 0.0, 0.5
    )
    reorder_distance: int = option(
        3, "reorder_distance", "largest displacement, in frames", lo=1, hi=1000
    )
    outage_start_s: float = option(
        0.0, "outage_start_s", "start of an outage, after the first frame sent", 1.0, 0.0, 86400.0
    )
    outage_duration_s: float = option(
        0.0, "outage_duration_s", "its duration (0: none)", 1.0, 0.0, 3600.0
    )


#: The ``[processing]`` section is the processing centre's own type (``levels.options``).
ProcessingConfig = ProcessingOptions


#: A pass's sections, by table name: what each holds (:func:`station.loader.describe_keys`).
SECTIONS = {
    "orbit": OrbitConfig,
    "pass": PassConfig,
    "ground_station": GroundStationConfig,
    "attitude": AttitudeConfig,
    "instrument": InstrumentConfig,
    "world": WorldConfig,
    "bulletins": BulletinConfig,
    "calibration": CalibrationConfig,
    "gcps": GcpConfig,
    "dem": DemConfig,
    "reference": ReferenceConfig,
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
    #: The DEM exported for level 3 (``[dem]`` given), or None.
    dem: DemConfig | None = None
    #: The reference ortho-image written beside the run (``[reference]`` given), or None.
    reference: ReferenceConfig | None = None
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
        check_name(self.name)
        if self.gcps.source == "reference" and (self.reference is None or self.dem is None):
            raise ScenarioError(
                '[gcps] source = "reference" finds the points on the run\'s reference '
                "ortho-image and DEM: give [reference] and [dem]"
            )
        numbers = [i.hrv for i in self.instruments]
        if len(set(numbers)) != len(numbers):
            raise ScenarioError(
                f"[[instrument]]: hrv = {numbers}: each HRV images once "
                "per pass; give each [[instrument]] its own hrv (1 or 2)"
            )

    @property
    def instruments(self) -> tuple[InstrumentConfig, ...]:
        """Every HRV imaging the pass: ``instrument`` first (it aims the orbit)."""
        return (self.instrument, *self.more_instruments)

    def provenance(self) -> dict[str, object]:
        """What a product and an L0 archive record of the scenario they were made from."""
        return {
            "scenario": self.name,
            "scenario_file": Path(self.source).name,
            "scenario_sha256": self.source_sha256,
            "seed": self.seed,
        }

    def inputs(self) -> list[Path]:
        """The files the scenario reads: itself, its TLE, its world's and its level 3 DEM, its
        reference image."""
        given = [self.orbit.tle_path, self.world.dem_path, self.processing.dem_path]
        given += [self.reference.file] if self.reference is not None else []
        return [Path(self.source)] * bool(self.source) + [self.path(p) for p in given if p]

    def path(self, relative: str) -> Path:
        """A path of the scenario, resolved from the scenario file's directory."""
        p = Path(relative)
        return p if p.is_absolute() else Path(self.base_dir) / p


#: A name that names files and directories, never a path (scenarios, --name, archives).
NAME_PATTERN = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]{0,99}")


def check_name(name: str, what: str = "name") -> str:
    """A scenario's name, which names its files and run directory: letters, digits, ``_``,
    ``.``, ``-``, starting with a letter or digit, at most 100 characters; never a path."""
    if not isinstance(name, str) or not NAME_PATTERN.fullmatch(name):
        odd = sorted({c for c in str(name) if not c.isascii()})
        hint = ""
        if odd and isinstance(name, str):
            plain = unicodedata.normalize("NFKD", name).encode("ascii", "ignore").decode()
            hint = f" ({', '.join(map(repr, odd))} not ASCII"
            hint += f"; e.g. {plain!r})" if NAME_PATTERN.fullmatch(plain) else ")"
        raise ScenarioError(
            f"{what} = {name!r}: expected ASCII letters, digits, '_', '.' or '-', starting "
            f"with a letter or a digit (at most 100): it names the run's files and "
            f"directory{hint}"
        )
    return name


#: Every error source of the emulator switched off, and a flat world at the default
#: reference height of the products: merged into a scenario's table
#: (:func:`merge_tables`), the chain's remaining errors are its approximations alone.
ERRORS_OFF: dict[str, dict[str, object]] = {
    "attitude": {
        "roll_offset_urad": 0.0,
        "pitch_offset_urad": 0.0,
        "yaw_offset_urad": 0.0,
        "drift_scale": 0.0,
        "jitter_amplitude_urad": [0.0, 0.0, 0.0],
    },
    "bulletins": {"bias_m": [0.0, 0.0, 0.0], "drift_m_per_s": [0.0, 0.0, 0.0]},
    "instrument": {"calibration_error_urad": 0.0},
    "world": {"relief_m": 0.0, "base_height_m": 450.0},
}


def merge_tables(*tables: dict[str, Any]) -> dict[str, Any]:
    """Scenario tables merged section by section, the later keys winning."""
    out: dict[str, Any] = {}
    for table in tables:
        for section, value in table.items():
            out[section] = {**out.get(section, {}), **value} if isinstance(value, dict) else value
    return out


def scenario_from_dict(data: dict[str, Any], base_dir: str | Path = ".") -> Scenario:
    """A :class:`Scenario` from a parsed TOML table (see the module docstring)."""
    top = {"name": str, "seed": int}
    allowed = sorted([*top, *SECTIONS])
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
                raise ScenarioError(
                    f"[[instrument]] given {len(value)} times: a SPOT "
                    "carries two HRVs, give one or two"
                )
            built = [build_section(InstrumentConfig, "instrument", v, ScenarioError) for v in value]
            kwargs["instrument"], kwargs["more_instruments"] = built[0], tuple(built[1:])
        elif key in SECTIONS:
            kwargs["pass_" if key == "pass" else key] = build_section(
                SECTIONS[key], key, value, ScenarioError
            )
        elif key == "passes":
            raise ScenarioError(
                "[[passes]] makes a block of several passes: `station run` runs it "
                "(station.loader.load_any reads it), not as one pass"
            )
        else:
            raise ScenarioError(f"unknown key {key!r}; allowed: {', '.join(allowed)}")
    scn = Scenario(**kwargs)
    if scn.processing.dem_path:  # the scenario's paths are relative to its file
        scn = replace(
            scn, processing=replace(scn.processing, dem_path=str(scn.path(scn.processing.dem_path)))
        )
    return scn


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
