"""ERS-1's SAR in the emulator: its orbit, the range–Doppler geometry of the truth, and the
detected slant-range image of a frame rendered from the world (issue 38, ADRIN ``001_…`` §5).

* **Orbit.** ERS-1's: 785 km, sun-synchronous, phased on 501 revolutions in 35 days, its
  descending node at 10:30 (mean local time), placed by :func:`station.spacecraft.placement.
  place_orbit` so that the centre of the swath (zero Doppler, the look angle of the mid
  incidence, to the right of the track) crosses the frame's target on its day.
* **Geometry of the truth.** A ground point ``p`` (ECEF, fixed on the Earth) is imaged on the
  line whose time ``t`` solves the Doppler equation of ADRIN's paper, ``Fdc − 2 (p − s)·(ṗ −
  ṡ) / (λ |p − s|) = 0`` with ``ṗ = 0`` in the Earth-fixed frame (``s``, ``ṡ``: the
  satellite's position and Earth-fixed velocity, ``Fdc`` the Doppler centroid the image was
  focused to), and on the column of its slant range ``r0 + mr·j = |p − s(t)|``. The truth
  solves it on the integrated orbit itself (:class:`~station.spacecraft.orbit.TruthOrbit`'s
  dense output), by Newton's method with the acceleration from the velocity's own
  difference: what the processing centre's ephemeris knows only through state vectors.
* **The image.** The world's terrain, sampled on a map grid finer than the image, each facet
  carrying the backscatter of its local incidence angle ``θ`` (``σ⁰ = ρ·cos²θ``, ``ρ`` the
  world's texture; or ``ρ·cos θ``, whose γ⁰ is ``ρ``) times its area on the terrain, is
  summed into the slant-range cell where the truth images it (bilinear weights,
  :func:`splat_bilinear`): two slopes at one range add up (layover), a facet
  the terrain hides from the antenna gives nothing (shadow: of the facets on one line at
  one look angle, only the nearest is seen). The sum over the cell's nominal area on the
  ellipsoid is σ⁰ where the ground is flat; multiplicative speckle of ``looks`` looks
  (Gamma of mean 1) follows.

The frame's annotation (:class:`levels.sar.SarAnnotation`) is what ADRIN had with the image:
state vectors of the post-facto orbit (sampled from the truth, with their stated errors), the
first line's time, the line interval, the near range, the range spacing, the Doppler
centroid and the wavelength.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import pyproj
from numpy.typing import NDArray

from levels.geometry.ellipsoid import WGS84
from levels.geometry.times import Epoch
from levels.sar.annotation import (
    MASK_TOLERANCE_PX,
    SPEED_OF_LIGHT_M_PER_S,
    SarAnnotation,
    SarImage,
    frame_grid,
    line_spacing_m,
    nominal_cell_m2,
)
from station.spacecraft.orbit import TruthOrbit, node_state, phased_targets
from station.spacecraft.placement import place_orbit
from station.spacecraft.sar_masks import layover_and_shadow
from station.spacecraft.world import World

__all__ = ["ERS1", "ErsFrame", "SarInstrument", "SarTruth", "emulate_frame", "sar_view"]


@dataclass(frozen=True)
class SarInstrument:
    """A side-looking SAR and its orbit (defaults: ERS-1's AMI in image mode)."""

    wavelength_m: float = 0.0565646  # C band, 5.3 GHz
    range_sampling_hz: float = 18.96e6
    prf_hz: float = 1679.9
    #: Incidence at the near and far edges of the 100 km swath (degrees, on the ellipsoid).
    incidence_deg: tuple[float, float] = (19.5, 26.5)
    altitude_m: float = 785_000.0
    repeat: tuple[int, int] = (501, 35)  # revolutions, days
    ltdn_h: float = 10.5
    right_looking: bool = True

    @property
    def range_spacing_m(self) -> float:
        """Slant-range sample spacing ``c / (2 f_s)`` (7.9 m)."""
        return SPEED_OF_LIGHT_M_PER_S / (2.0 * self.range_sampling_hz)


ERS1 = SarInstrument()


@dataclass(frozen=True)
class ErsFrame:
    """One frame of a pass: where, when, its size and how it was processed.

    ``range_looks`` and ``azimuth_looks`` set the detected image's sampling (the range
    spacing times ``range_looks``, the line interval ``azimuth_looks / PRF``): the reduced
    frames of the tests keep the swath's geometry with fewer, larger samples.
    """

    date_utc: str = "1995-08-15"
    target_lat_deg: float = -15.6  # Cuiabá
    target_lon_deg: float = -56.1
    n_lines: int = 400
    n_samples: int = 400
    azimuth_looks: int = 5
    range_looks: int = 2
    speckle_looks: float = 3.0
    doppler_hz: tuple[float, ...] = (0.0,)  # Fdc polynomial in (R − r0) / km
    #: State vectors of the annotation: spacing (s), and their 1σ errors (m, m/s) per axis
    #: (ERS's post-facto orbits: decimetres; 0 gives the truth's own).
    state_spacing_s: float = 10.0
    state_error_m: float = 0.0
    state_error_m_per_s: float = 0.0
    #: The post-facto orbit's smooth error: an offset (m) and its drift (m/s) along the
    #: track, across it (to the left) and radially, at the frame's centre time.
    state_bias_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    state_drift_m_per_s: tuple[float, float, float] = (0.0, 0.0, 0.0)
    #: Map sampling of the terrain under the frame, per image sample (finer = more facets).
    oversample: float = 2.0
    seed: int = 38
    #: The terrain's backscatter law on the local incidence θ: ``"cos2"``, σ⁰ = ρ·cos²θ;
    #: ``"gamma"``, σ⁰ = ρ·cos θ (γ⁰ = σ⁰ / cos θ = ρ whatever the slope: what terrain
    #: flattening recovers).
    backscatter: str = "cos2"

    def __post_init__(self) -> None:
        if self.backscatter not in ("cos2", "gamma"):
            raise ValueError(f"backscatter {self.backscatter!r}: 'cos2' or 'gamma'")


def sar_view(look_rad: float, height_m: float, right: bool = True):
    """The ground point the antenna sees at zero Doppler at ``look_rad`` off nadir, on the
    ellipsoid raised by ``height_m`` (the view :func:`place_orbit` aims)."""

    def view(orbit: TruthOrbit, t_s: NDArray[np.float64]) -> tuple[NDArray, NDArray]:
        r, v = orbit.state_ecef(t_s)
        los = _look_vector(r, v, look_rad, right)
        point, _ok = WGS84.intersect(r, los, height_m)
        lat, lon, _h = WGS84.to_geodetic(point)
        return lat, lon

    return view


def _look_vector(r: NDArray, v: NDArray, look_rad: float, right: bool) -> NDArray:
    """The unit vector at ``look_rad`` from nadir in the zero-Doppler plane (⟂ ``v``),
    right of the track (or left)."""
    vh = v / np.linalg.norm(v, axis=-1, keepdims=True)
    down = -r / np.linalg.norm(r, axis=-1, keepdims=True)
    down = down - np.sum(down * vh, axis=-1, keepdims=True) * vh
    down /= np.linalg.norm(down, axis=-1, keepdims=True)
    side = np.cross(vh, -down) * (1.0 if right else -1.0)  # forward × up = right
    return np.cos(look_rad) * down + np.sin(look_rad) * side


def _look_of_incidence(incidence_rad: float, altitude_m: float) -> float:
    """Look angle off nadir for an incidence on a sphere of the Earth's radius."""
    re = WGS84.a_m
    return float(np.arcsin(re / (re + altitude_m) * np.sin(incidence_rad)))


@dataclass(frozen=True, eq=False)
class SarTruth:
    """The truth behind a frame: the orbit, the world and the annotation's grid."""

    orbit: TruthOrbit
    world: World
    annotation: SarAnnotation

    def zero_doppler(
        self, p_ecef: NDArray[np.float64], iterations: int = 8
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Time (s since the epoch) and slant range (m) at which ground points ``p`` (N, 3)
        are imaged: the Doppler equation solved on the integrated orbit (module
        docstring)."""
        ann = self.annotation
        p = np.atleast_2d(np.asarray(p_ecef, dtype=np.float64))
        t = np.full(p.shape[0], ann.first_line_s + 0.5 * ann.shape[0] * ann.line_interval_s)
        lam = ann.wavelength_m
        for _ in range(iterations):
            s, sd = self.orbit.state_ecef(t)
            _, sd2 = self.orbit.state_ecef(t + 1e-3)
            acc = (sd2 - sd) / 1e-3
            d = p - s
            r = np.linalg.norm(d, axis=1)
            fdc = ann.doppler_at(r)
            # f(t) = Fdc − 2 (p − s)·(−ṡ) / (λ r); ṗ = 0 on the Earth
            f = fdc + 2.0 * np.sum(d * sd, axis=1) / (lam * r)
            dfdt = 2.0 * (np.sum(d * acc, axis=1) - np.sum(sd * sd, axis=1)) / (lam * r)
            step = f / dfdt
            t = t - step
            if np.max(np.abs(step)) < 1e-10:
                break
        s, _ = self.orbit.state_ecef(t)
        return t, np.linalg.norm(p - s, axis=1)

    def masks(self, grid: Any, oversample: int = 4) -> tuple[NDArray, NDArray]:
        """The true layover and shadow at the centre of every pixel of a map grid: the
        definitions of :func:`~station.spacecraft.sar_masks.layover_and_shadow` on the
        world's own terrain,
        sampled ``oversample`` times finer than the grid (a profile every fine node along
        the track), each node's line, range, look angle and ground range (its column at
        the map across the track) by the truth's own solution on the integrated orbit."""
        ann = self.annotation
        n_r = (grid.n_rows - 1) * oversample + 1
        n_c = (grid.n_cols - 1) * oversample + 1
        i, j = np.meshgrid(np.arange(n_r) / oversample, np.arange(n_c) / oversample, indexing="ij")
        x, y = grid.map_of(i.ravel(), j.ravel())
        to_geo = pyproj.Transformer.from_crs(grid.crs_wkt, "EPSG:4326", always_xy=True)
        lon, lat = (np.radians(a) for a in to_geo.transform(x, y))
        h, _, _ = self.world.height(lat, lon)
        p = WGS84.to_ecef(lat, lon, h)
        t, r = self.zero_doppler(p)
        s, _ = self.orbit.state_ecef(t)
        look = _look_angle(s, p, r)
        line = ann.line_of(t).reshape(n_r, n_c)
        col = ann.column_of(r).reshape(n_r, n_c)
        look = look.reshape(n_r, n_c)
        per_node = max(
            float(np.median(np.abs(np.diff(line, axis=0)))),
            float(np.median(np.abs(np.diff(line, axis=1)))),
        )
        # the ground range: the map across the lines' mean direction, away from the track
        gl = np.array([np.mean(np.diff(line, axis=0)), np.mean(np.diff(line, axis=1))])
        across = np.array([-gl[1], gl[0]]) / np.hypot(*gl)
        if across @ [np.mean(np.diff(col, axis=0)), np.mean(np.diff(col, axis=1))] < 0:
            across = -across
        u = (i * across[0] + j * across[1]) * grid.pixel_size_m
        du = grid.pixel_size_m / oversample
        centre = (slice(None, None, oversample), slice(None, None, oversample))
        layover, shadow = layover_and_shadow(
            line,
            u,
            col,
            look,
            0.5 * float(du),
            MASK_TOLERANCE_PX,
            MASK_TOLERANCE_PX * ann.range_spacing_m / ann.near_range_m,
            queries=(line[centre], u[centre], col[centre], look[centre]),
            lines_per_profile=per_node,
        )
        return layover.reshape(grid.shape), shadow.reshape(grid.shape)

    def image_of(
        self, lat_rad: NDArray, lon_rad: NDArray, h_m: NDArray
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The (line, column) where the truth images geodetic points."""
        t, r = self.zero_doppler(WGS84.to_ecef(lat_rad, lon_rad, h_m))
        return self.annotation.line_of(t), self.annotation.column_of(r)


def _enu_normal(lat: NDArray, lon: NDArray, gx: NDArray, gy: NDArray) -> NDArray:
    """The terrain's unit normal in ECEF from its east and north slopes."""
    e = np.stack([-np.sin(lon), np.cos(lon), np.zeros_like(lon)], axis=-1)
    n = np.stack([-np.sin(lat) * np.cos(lon), -np.sin(lat) * np.sin(lon), np.cos(lat)], axis=-1)
    u = np.stack([np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)], axis=-1)
    nrm = -gx[:, None] * e - gy[:, None] * n + u
    return nrm / np.linalg.norm(nrm, axis=1, keepdims=True)


def emulate_frame(
    frame: ErsFrame, world: World, instrument: SarInstrument = ERS1, render: bool = True
) -> tuple[SarImage, SarTruth]:
    """A frame's detected slant-range image with its annotation, and the truth behind it
    (module docstring); ``render=False``: the geometry alone, the image zero."""
    epoch = Epoch(np.datetime64(f"{frame.date_utc}T00:00:00", "ns"), "frame day")
    inc_mid = np.radians(0.5 * sum(instrument.incidence_deg))
    look = _look_of_incidence(inc_mid, instrument.altitude_m)
    period, raan_rate = phased_targets(*instrument.repeat)
    a_m, i_rad = node_state(period, raan_rate, 0.0)
    orbit, t_c = place_orbit(
        epoch,
        a_m,
        i_rad,
        0.0,
        instrument.ltdn_h,
        np.radians(frame.target_lat_deg),
        np.radians(frame.target_lon_deg),
        (0.0, 86400.0),
        view=sar_view(look, world.base_height_m, instrument.right_looking),
    )
    dt_line = frame.azimuth_looks / instrument.prf_hz
    t0 = t_c - 0.5 * frame.n_lines * dt_line
    mr = instrument.range_spacing_m * frame.range_looks
    s_c, v_c = orbit.state_ecef(np.array([t_c]))
    los = _look_vector(s_c, v_c, look, instrument.right_looking)
    ground, _ = WGS84.intersect(s_c, los, world.base_height_m)
    r_c = float(np.linalg.norm(ground - s_c))
    r0 = r_c - 0.5 * frame.n_samples * mr
    rng = np.random.default_rng(frame.seed)
    span = (t0 - 60.0, t0 + frame.n_lines * dt_line + 60.0)
    t_sv = np.arange(span[0], span[1] + frame.state_spacing_s / 2, frame.state_spacing_s)
    r_sv, v_sv = orbit.state_ecef(t_sv)
    # the smooth error, in each state vector's local orbital frame (along, across, radial)
    radial = r_sv / np.linalg.norm(r_sv, axis=1, keepdims=True)
    along = v_sv - np.sum(v_sv * radial, axis=1, keepdims=True) * radial
    along /= np.linalg.norm(along, axis=1, keepdims=True)
    axes = np.stack([along, np.cross(radial, along), radial], axis=1)  # (N, 3 axes, xyz)
    bias, drift = np.asarray(frame.state_bias_m), np.asarray(frame.state_drift_m_per_s)
    offset = bias[None, :] + drift[None, :] * (t_sv - t_c)[:, None]
    r_sv = r_sv + np.einsum("na,nax->nx", offset, axes)
    v_sv = v_sv + np.einsum("a,nax->nx", drift, axes)
    r_sv = r_sv + frame.state_error_m * rng.standard_normal(r_sv.shape)
    v_sv = v_sv + frame.state_error_m_per_s * rng.standard_normal(v_sv.shape)
    ann = SarAnnotation(
        epoch=epoch,
        state_t_s=t_sv,
        state_r_m=r_sv,
        state_v_m_per_s=v_sv,
        first_line_s=t0,
        line_interval_s=dt_line,
        near_range_m=r0,
        range_spacing_m=mr,
        wavelength_m=instrument.wavelength_m,
        doppler_hz=tuple(frame.doppler_hz),
        shape=(frame.n_lines, frame.n_samples),
        looks=frame.speckle_looks,
        right_looking=instrument.right_looking,
    )
    r_true, v_true = orbit.state_ecef(t_sv)
    truth = SarTruth(orbit, world, replace(ann, state_r_m=r_true, state_v_m_per_s=v_true))
    if not render:
        return SarImage(ann, np.zeros(ann.shape, dtype=np.float32)), truth
    intensity = _render(truth, frame, instrument, rng)
    return SarImage(ann, intensity), truth


def _render(
    truth: SarTruth, frame: ErsFrame, instrument: SarInstrument, rng: np.random.Generator
) -> NDArray[np.float32]:
    """The detected intensity of the frame (module docstring)."""
    ann = truth.annotation
    n_l, n_s = ann.shape
    inc_near = np.radians(instrument.incidence_deg[0])
    ground_range_m = ann.range_spacing_m / np.sin(inc_near)
    spacing = min(ground_range_m, line_spacing_m(ann)) / frame.oversample
    # the terrain under the frame, on a map grid finer than its samples
    under = frame_grid(ann, spacing, truth.world.base_height_m, 2.0 * truth.world.relief_m + 500.0)
    xs, ys = under.x_m(), under.y_m()
    to_geo = pyproj.Transformer.from_crs(under.crs_wkt, "EPSG:4326", always_xy=True)
    out = np.zeros(n_l * n_s)
    for k0 in range(0, ys.size, 256):  # strips of map rows: bounded memory
        x, y = np.meshgrid(xs, ys[k0 : k0 + 256])
        lon, lat = (np.radians(a) for a in to_geo.transform(x.ravel(), y.ravel()))
        h, gx, gy = truth.world.height(lat, lon)
        p = WGS84.to_ecef(lat, lon, h)
        t, r = truth.zero_doppler(p)
        line, col = ann.line_of(t), ann.column_of(r)
        inside = (line > -1) & (line < n_l) & (col > -1) & (col < n_s) & np.isfinite(h)
        if not inside.any():
            continue
        k = np.flatnonzero(inside)
        s, _ = truth.orbit.state_ecef(t[k])
        to_sat = (s - p[k]) / r[k, None]
        cos_loc = np.sum(_enu_normal(lat[k], lon[k], gx[k], gy[k]) * to_sat, axis=1)
        rho = truth.world.reflectance(lat[k], lon[k], "P")
        area = spacing**2 * np.sqrt(1.0 + gx[k] ** 2 + gy[k] ** 2)
        power = rho * np.clip(cos_loc, 0.0, None) ** (2 if frame.backscatter == "cos2" else 1)
        power *= area
        seen = _visible(line[k], _look_angle(s, p[k], r[k]), r[k], ann.range_spacing_m, spacing)
        splat_bilinear(out, line[k][seen], col[k][seen], power[seen], n_l, n_s)
    cell = nominal_cell_m2(ann, truth.world.base_height_m)  # σ⁰ on flat ground
    intensity = out.reshape(n_l, n_s) / cell[None, :]
    if frame.speckle_looks > 0:
        lk = frame.speckle_looks
        intensity *= rng.gamma(lk, 1.0 / lk, intensity.shape)
    return intensity.astype(np.float32)


def _look_angle(s: NDArray, p: NDArray, r: NDArray) -> NDArray:
    """The look angle (rad) of ground points ``p`` from the antenna at ``s``, ``r`` apart:
    from its geocentric nadir."""
    down = -s / np.linalg.norm(s, axis=1, keepdims=True)
    return np.arccos(np.clip(np.sum(down * (p - s), axis=1) / r, -1.0, 1.0))


def _visible(
    line: NDArray, look: NDArray, r: NDArray, range_spacing_m: float, facet_m: float
) -> NDArray[np.bool_]:
    """Which facets (``facet_m`` apart on the map) the antenna sees: on one line, at one look
    angle, only the nearest (and those within a range sample of it)."""
    # bins a facet and a half wide as the antenna sees them: an occluding ridge has a facet
    # in the bin of every facet it hides, and neighbours on open ground share bins
    d_look = 1.5 * facet_m / float(np.median(r))
    key = np.rint(line).astype(np.int64) * (1 << 32) + np.rint(look / d_look).astype(np.int64)
    order = np.lexsort((r, key))
    ks, rs = key[order], r[order]
    first = np.r_[True, ks[1:] != ks[:-1]]
    nearest = np.maximum.accumulate(np.where(first, np.arange(ks.size), 0))
    seen = np.empty(r.size, dtype=bool)
    seen[order] = rs <= rs[nearest] + range_spacing_m
    return seen


def splat_bilinear(
    out: NDArray[np.float64], line: NDArray, col: NDArray, value: NDArray, n_l: int, n_s: int
) -> None:
    """Add each point's ``value`` to the four cells of an ``n_l`` × ``n_s`` image (``out``,
    flat) around its (line, column), bilinearly; what falls outside is dropped."""
    l0, c0 = np.floor(line).astype(np.int64), np.floor(col).astype(np.int64)
    fl, fc = line - l0, col - c0
    for dl, dc, w in (
        (0, 0, (1 - fl) * (1 - fc)),
        (1, 0, fl * (1 - fc)),
        (0, 1, (1 - fl) * fc),
        (1, 1, fl * fc),
    ):
        ll, cc = l0 + dl, c0 + dc
        ok = (ll >= 0) & (ll < n_l) & (cc >= 0) & (cc < n_s)
        idx = ll[ok] * n_s + cc[ok]
        out += np.bincount(idx, weights=(w * value)[ok], minlength=n_l * n_s)
