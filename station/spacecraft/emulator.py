"""The spacecraft emulator: a scenario in, the raw lines of a pass and their truth out.

:func:`emulate` sets up, in order, the truth orbit (placed so that the strip's centre falls
on the scenario's target), the truth attitude and its gyro record, the HRV, the world, and
renders every band; then it prepares what the station is handed besides telemetry:
ephemeris bulletins with errors, the nominal look-angle and calibration tables (in
:class:`~station.spacecraft.instrument.BandModel`), and control points.

All randomness comes from one ``numpy.random.Generator`` seeded with the scenario's seed,
spawned into independent streams per component, so that changing, say, the GCP count does
not change the attitude drift.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from levels.geometry.ellipsoid import WGS84
from levels.geometry.ephemeris import Ephemeris
from levels.geometry.frames import apply, ecef_from_orbital
from levels.geometry.model import LineClock, PushbroomModel
from levels.geometry.sensor import mirror_angle_rad
from levels.geometry.times import Epoch
from station.scenario import GcpConfig, Scenario
from station.spacecraft.attitude import GyroRecord, TruthAttitude, sample_gyros
from station.spacecraft.hgt import read_hgt
from station.spacecraft.imaging import RenderedBand, render_band, trace_pixels
from station.spacecraft.instrument import TWIN_SEPARATION_RAD, Hrv, build_hrv
from station.spacecraft.orbit import OrbitError, TruthOrbit
from station.spacecraft.passes import Pass, find_passes
from station.spacecraft.placement import mean_element_orbit, swath_centre_view
from station.spacecraft.sun import sun_direction_ecef
from station.spacecraft.tle import Tle, read_tle, tle_state_eci
from station.spacecraft.world import World

__all__ = [
    "Acquisition",
    "ControlPoints",
    "emulate",
    "emulate_pass",
    "make_bulletins",
    "truth_model",
]

_ATTITUDE_MARGIN_S = 3.0  # truth attitude and gyros beyond the strip's ends


@dataclass(frozen=True)
class ControlPoints:
    """Ground control points: map coordinates with map-like errors, and where they were
    measured in the raw image; the truth is kept beside them for evaluation.

    Arrays of shape (N,): ``line``, ``column`` (measured, 0-based), ``lat_rad``,
    ``lon_rad``, ``h_m`` (map); ``true_line``, ``true_column``, ``true_lat_rad``,
    ``true_lon_rad``, ``true_h_m``; ``blunder`` marks the points whose map position is a
    blunder (``[gcps] blunder_fraction``).
    """

    line: NDArray[np.float64]
    column: NDArray[np.float64]
    lat_rad: NDArray[np.float64]
    lon_rad: NDArray[np.float64]
    h_m: NDArray[np.float64]
    true_line: NDArray[np.float64]
    true_column: NDArray[np.float64]
    true_lat_rad: NDArray[np.float64]
    true_lon_rad: NDArray[np.float64]
    true_h_m: NDArray[np.float64]
    blunder: NDArray[np.bool_]


@dataclass(frozen=True, eq=False)
class Acquisition:
    """Everything the emulator produced for one strip (times in s since ``epoch``)."""

    scenario: Scenario
    epoch: Epoch
    orbit: TruthOrbit
    attitude: TruthAttitude
    hrv: Hrv
    world: World
    t_centre_s: float
    line_times_s: NDArray[np.float64]
    bands: tuple[RenderedBand, ...]
    gyros: GyroRecord
    bulletins: Ephemeris
    gcps: ControlPoints
    passes: tuple[Pass, ...]
    sun_ecef: NDArray[np.float64]
    #: Which of the scenario's HRVs (0: its first ``[[instrument]]``).
    index: int = 0


def _world(scn: Scenario) -> World:
    wc = scn.world
    grid = read_hgt(scn.path(wc.dem_path)) if wc.kind == "dem" else None
    return World(scn.pass_.target_lon_rad, wc.base_height_m, wc.relief_m, wc.seed, grid, wc.rows_m)


def _tle(scn: Scenario) -> Tle:
    """The scenario's element set, read once."""
    oc = scn.orbit
    sets = read_tle(scn.path(oc.tle_path))
    if oc.tle_index >= len(sets):
        raise OrbitError(
            f"{oc.tle_path} has {len(sets)} element sets; tle_index = "
            f"{oc.tle_index} is out of range"
        )
    return sets[oc.tle_index]


def _orbit(
    scn: Scenario,
    epoch: Epoch,
    span: tuple[float, float],
    margin_s: float,
    mirror_rad: float,
    tle: Tle | None,
) -> tuple[TruthOrbit, float]:
    oc, pc = scn.orbit, scn.pass_
    view = swath_centre_view(
        mirror_rad if pc.aim == "view" else 0.0,
        scn.world.base_height_m,
        scn.attitude.reference_velocity,
    )
    if oc.kind in ("phased", "elements"):
        return mean_element_orbit(oc, pc, epoch, span, view)
    assert tle is not None  # kind == "tle": emulate() read it
    t0, r0, v0 = tle_state_eci(tle, epoch)
    search = TruthOrbit(epoch, t0, r0, v0, t0, t0 + pc.search_days * 86400.0)
    t = np.arange(t0, t0 + pc.search_days * 86400.0, 5.0)
    lat, lon = view(search, t)
    crossing = np.flatnonzero(np.diff(np.sign(lat - pc.target_lat_rad)) < 0)
    if crossing.size == 0:
        raise OrbitError("the TLE's orbit never crosses the target latitude southward")
    miss = np.abs(np.angle(np.exp(1j * (lon[crossing] - pc.target_lon_rad))))
    k = crossing[np.argmin(miss)]
    frac = (lat[k] - pc.target_lat_rad) / (lat[k] - lat[k + 1])
    t_c = float(t[k] + frac * 5.0)
    lo, hi = min(span[0], t0, t_c - margin_s), max(span[1], t_c + margin_s)
    return TruthOrbit(epoch, t0, r0, v0, lo, hi), t_c


def make_bulletins(
    orbit: TruthOrbit,
    t_from_s: float,
    t_to_s: float,
    period_s: float,
    bias_m: NDArray[np.float64],
    drift_m_per_s: NDArray[np.float64],
    t_ref_s: float,
) -> Ephemeris:
    """Bulletin points every ``period_s`` (on multiples of it) covering [from, to], with a
    position error ``bias + drift (t − t_ref)`` along, across track and radially (the local
    orbital axes Y, X, Z) and the matching velocity error ``drift``."""
    k0 = np.floor(t_from_s / period_s)
    k1 = np.ceil(t_to_s / period_s)
    t = period_s * np.arange(k0, k1 + 1)
    r, v = orbit.frame_state_ecef(t)  # bulletins carry the platform's reference velocity
    axes = ecef_from_orbital(r, v)  # columns X (across), Y (along), Z (radial)
    along_across_radial = np.asarray(bias_m, float) + np.outer(t - t_ref_s, drift_m_per_s)
    local = along_across_radial[:, [1, 0, 2]]  # to (X, Y, Z) order
    dr = apply(axes, local)
    dv = apply(axes, np.asarray(drift_m_per_s, float)[[1, 0, 2]])
    return Ephemeris(t, r + dr, v + dv, reference_velocity=orbit.reference_velocity)


def truth_model(acq: Acquisition, band: int = 0, step_s: float = 1.0) -> PushbroomModel:
    """The geometry core's model built on the truth (orbit sampled every ``step_s``, truth
    attitude, truth look angles): it must see every raw pixel where the emulator put it."""
    t0, t1 = acq.line_times_s[0] - 10 * step_s, acq.line_times_s[-1] + 10 * step_s
    t = np.arange(t0, t1 + step_s, step_s)
    r, v = acq.orbit.frame_state_ecef(t)
    clock = LineClock(float(acq.line_times_s[0]), 0.0, acq.hrv.line_period_s)
    return PushbroomModel(
        acq.epoch,
        clock,
        Ephemeris(t, r, v, reference_velocity=acq.orbit.reference_velocity),
        acq.attitude,
        acq.hrv.bands[band].look_true,
        acq.line_times_s.size,
    )


def _control_points(
    cfg: GcpConfig,
    hrv: Hrv,
    times: NDArray[np.float64],
    orbit: TruthOrbit,
    attitude: TruthAttitude,
    world: World,
    rng: np.random.Generator,
) -> ControlPoints:
    n = cfg.count if hrv.number in cfg.hrvs else 0
    starts, ends = np.array(cfg.line_ranges[::2]), np.array(cfg.line_ranges[1::2])
    lengths = ends - starts
    ends_laid = np.cumsum(lengths)  # the ranges laid end to end
    u = rng.uniform(0.0, ends_laid[-1], n)
    k = np.minimum(np.searchsorted(ends_laid, u, side="right"), lengths.size - 1)
    line = (starts[k] + u - (ends_laid[k] - lengths[k])) * (times.size - 1)
    col = rng.uniform(0.05, 0.95, n) * (hrv.n_columns - 1)
    t = times[0] + line * hrv.line_period_s
    pts, _ok = trace_pixels(orbit, attitude, hrv.bands[0], world, t, col)
    lat, lon, h = pts.T
    east, north = cfg.horizontal_error_m * rng.standard_normal((2, n))
    blunder = np.zeros(n, dtype=bool)
    line_m = line + cfg.pointing_error_px * rng.standard_normal(n)
    col_m = col + cfg.pointing_error_px * rng.standard_normal(n)
    h_m = h + cfg.vertical_error_m * rng.standard_normal(n)
    n_blunders = round(cfg.blunder_fraction * n)
    if n_blunders:
        blunder[rng.choice(n, n_blunders, replace=False)] = True
        azimuth = rng.uniform(0.0, 2 * np.pi, n_blunders)
        east[blunder] += cfg.blunder_m * np.sin(azimuth)
        north[blunder] += cfg.blunder_m * np.cos(azimuth)
    radius = WGS84.a_m
    return ControlPoints(
        line=line_m,
        column=col_m,
        lat_rad=lat + north / radius,
        lon_rad=lon + east / (radius * np.cos(lat)),
        h_m=h_m,
        true_line=line,
        true_column=col,
        true_lat_rad=lat,
        true_lon_rad=lon,
        true_h_m=h,
        blunder=blunder,
    )


def emulate(scn: Scenario, render: bool = True, instrument: int = 0) -> Acquisition:
    """Run the spacecraft emulator on a scenario (module docstring): the acquisition of its
    ``instrument``-th HRV (0: the first ``[[instrument]]``).

    With ``render=False`` the bands are left empty (geometry, gyros, bulletins and control
    points only): the fast path for geometry tests and pass planning.
    """
    return emulate_pass(scn, render, (instrument,))[0]


def emulate_pass(
    scn: Scenario, render: bool = True, instruments: tuple[int, ...] | None = None
) -> tuple[Acquisition, ...]:
    """The acquisitions of every HRV of the pass (or of those listed), in scenario order.

    Both HRVs ride the same platform: one orbit (aimed at the first HRV's view), one truth
    attitude and one gyro record spanning every HRV's lines, one set of bulletins; each
    HRV has its own detectors, line times (centred on the same instant; XS lines last
    twice as long as P lines), renders and control points. An HRV's acquisition is the same
    whether it is emulated alone or with the other: the random streams are per component
    and per HRV, and the platform's spans are those of the whole scenario.
    """
    configs = scn.instruments
    chosen = tuple(range(len(configs))) if instruments is None else instruments
    for k in chosen:
        if not 0 <= k < len(configs):
            raise IndexError(f"instrument {k}: the scenario has {len(configs)}")
    streams = np.random.default_rng(scn.seed).spawn(6)
    rng_att, rng_hrv, rng_gyro, rng_noise, rng_gcp, rng_more = streams
    # per HRV: (detectors, noise, control points); the first keeps the original streams
    per_hrv = [(rng_hrv, rng_noise, rng_gcp)] + [
        tuple(g.spawn(3)) for g in rng_more.spawn(len(configs))[1:]
    ]
    hrvs = [build_hrv(c, scn.calibration, per_hrv[k][0]) for k, c in enumerate(configs)]
    platform = _platform(scn, hrvs, rng_att, rng_gyro)
    out = []
    for k in chosen:  # one HRV each: two at most
        _, rng_noise_k, rng_gcp_k = per_hrv[k]
        out.append(_acquisition(scn, platform, hrvs[k], k, render, rng_noise_k, rng_gcp_k))
    return tuple(out)


@dataclass(frozen=True, eq=False)
class _Platform:
    """What every HRV of a pass shares: the day's epoch, the orbit and the strip's centre
    instant, the truth attitude and its gyro record, the bulletins, the world, the Sun at
    the centre and the station's passes over the day."""

    epoch: Epoch
    orbit: TruthOrbit
    t_c: float
    attitude: TruthAttitude
    gyros: GyroRecord
    bulletins: Ephemeris
    world: World
    sun: NDArray[np.float64]
    passes: tuple[Pass, ...]


def _platform(
    scn: Scenario, hrvs: list[Hrv], rng_att: np.random.Generator, rng_gyro: np.random.Generator
) -> _Platform:
    """The platform of a pass (:class:`_Platform`), spanning every HRV's lines."""
    first = hrvs[0]
    tle = _tle(scn) if scn.orbit.kind == "tle" else None
    if tle is not None:  # the TLE's day: its orbit is where it is
        epoch = Epoch(tle.epoch_utc.astype("datetime64[D]"), name="00:00 UTC of the TLE's day")
    else:
        epoch = Epoch(np.datetime64(scn.pass_.date_utc, "ns"), name="00:00 UTC of the pass day")
    # every HRV's strip is centred on the same instant: the longest one spans them all
    strip_s = max(h.n_lines * h.line_period_s for h in hrvs)
    margin = max(scn.bulletins.margin_s, 8 * scn.bulletins.period_s) + strip_s / 2
    mirror = float(mirror_angle_rad(first.mirror_step))
    if first.twin:
        mirror += (-0.5 if first.number == 1 else 0.5) * TWIN_SEPARATION_RAD
    day = (0.0, max(scn.pass_.ground_pass_days, 1.0) * 86400.0)
    span = (min(day[0], -margin), day[1] + margin)
    orbit, t_c = _orbit(scn, epoch, span, margin, mirror, tle)
    orbit = orbit.with_reference_velocity(scn.attitude.reference_velocity)
    half_s = max((h.n_lines - 1) * h.line_period_s for h in hrvs) / 2  # first to last line
    strip = (t_c - half_s, t_c + half_s)
    ac = scn.attitude
    attitude = TruthAttitude.generate(
        strip[0] - _ATTITUDE_MARGIN_S,
        strip[1] + _ATTITUDE_MARGIN_S,
        rng_att,
        offsets_rad=(ac.roll0_rad, ac.pitch0_rad, ac.yaw0_rad),
        drift_scale=ac.drift_scale,
        jitter_amplitude_rad=ac.jitter_amplitude_rad,
        jitter_frequency_hz=ac.jitter_frequency_hz,
    )
    g0 = np.ceil((strip[0] - 2.0) / ac.gyro_period_s) * ac.gyro_period_s
    n_gyro = int((strip[1] + 2.0 - g0) / ac.gyro_period_s) + 1
    gyros = sample_gyros(
        attitude,
        g0,
        n_gyro,
        ac.gyro_period_s,
        ac.gyro_noise_rad_per_s,
        ac.gyro_lsb_rad_per_s,
        rng_gyro,
    )
    bc = scn.bulletins
    bulletins = make_bulletins(
        orbit,
        strip[0] - bc.margin_s,
        strip[1] + bc.margin_s,
        bc.period_s,
        np.asarray(bc.bias_m),
        np.asarray(bc.drift_m_per_s),
        t_c,
    )
    gs = scn.ground_station
    passes = (
        tuple(
            find_passes(
                orbit, gs.lat_rad, gs.lon_rad, gs.height_m, gs.elevation_mask_rad, day[0], day[1]
            )
        )
        if scn.pass_.ground_pass_days > 0
        else ()
    )
    sun = sun_direction_ecef(epoch, [t_c])[0]
    return _Platform(epoch, orbit, t_c, attitude, gyros, bulletins, _world(scn), sun, passes)


def _acquisition(
    scn: Scenario,
    p: _Platform,
    hrv: Hrv,
    k: int,
    render: bool,
    rng_noise: np.random.Generator,
    rng_gcp: np.random.Generator,
) -> Acquisition:
    """HRV ``k``'s acquisition on the platform: its line times, rendered bands (``render``)
    and control points."""
    line_times = np.asarray(
        p.t_c + (np.arange(hrv.n_lines) - (hrv.n_lines - 1) / 2) * hrv.line_period_s,
        dtype=np.float64,
    )
    bands: tuple[RenderedBand, ...] = ()
    if render:
        bands = tuple(
            render_band(p.orbit, p.attitude, hrv, b, p.world, line_times, p.sun, rng_noise)
            for b in hrv.bands
        )
    gcps = _control_points(scn.gcps, hrv, line_times, p.orbit, p.attitude, p.world, rng_gcp)
    return Acquisition(
        scenario=scn,
        epoch=p.epoch,
        orbit=p.orbit,
        attitude=p.attitude,
        hrv=hrv,
        world=p.world,
        t_centre_s=p.t_c,
        line_times_s=line_times,
        bands=bands,
        gyros=p.gyros,
        bulletins=p.bulletins,
        gcps=gcps,
        passes=p.passes,
        sun_ecef=p.sun,
        index=k,
    )
