"""A synthetic truth for the processing library's tests, without the emulator.

A pass is flown with an attitude and an orbit that GEO is not told: the gyros measure the
rates of the true attitude (with their white noise), never its constant part, and the
bulletins carry a bias. The truth is the pass as flown (:class:`TruePass`): its control
points are true image points seen on the ground through it (with the errors their σ
state), and a scene's error is its model against the true line of sight on the scene's
reference surface, as the station's truth measures it (``station.truth.optical``).

The sizes of the errors are the emulator's defaults (``station.scenario``): attitude
offsets 150, −200, 300 µrad in roll, pitch, yaw; a bulletin bias of −150, 100, −20 m along,
across track and radial growing by −0.05, −0.02, 0 m/s; gyro noise 0.5 µrad/s a record. The
bias is signed so that it adds to the attitude's displacement: the system model misses by
about 360 m, of the order of SPOT 1–4's specified 350 m.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
from _orbits import BUTTING_RAD, DESCENDING_M0_RAD, EPOCH, P_PITCH_RAD, ecef_states, kepler_eci
from numpy.typing import NDArray

from levels.geo.scenes import PassGeometry, SceneGeometry, cut_scenes, pass_geometry
from levels.geometry import Ephemeris, LookAngleTable, SampledAttitude, mirror_angle_rad
from levels.geometry.frames import apply, enu_from_ecef
from levels.readers.gcp import ControlPointSet
from levels.spot import MODES

#: The emulator's default attitude offsets (roll, pitch, yaw), rad.
ATTITUDE_OFFSET_RAD = np.array([150.0, -200.0, 300.0]) * 1e-6
#: Its default bulletin bias along, across track and radial (m), and its growth (m/s).
BULLETIN_BIAS_M = -np.array([150.0, -100.0, 20.0])
BULLETIN_DRIFT_M_PER_S = -np.array([0.05, 0.02, 0.0])
#: Its gyros' white noise per 0.125 s record (rad/s).
GYRO_NOISE_RAD_PER_S = 0.5e-6
GYRO_PERIOD_S = 0.125
#: A slow steady drift of the platform the gyros measure (roll, pitch, yaw rates, rad/s).
TRUE_RATES_RAD_PER_S = np.array([1e-6, 2e-6, -1e-6])
#: The control points' stated σ: the emulator's defaults (ground m, height m, image px).
GCP_SIGMAS = (8.0, 5.0, 0.3)


def _track_frame(r: NDArray[np.float64], v: NDArray[np.float64]) -> NDArray[np.float64]:
    """Unit vectors along track, across track and radial at each state, (n, 3, 3)."""
    up = r / np.linalg.norm(r, axis=-1, keepdims=True)
    across = np.cross(up, v)
    across /= np.linalg.norm(across, axis=-1, keepdims=True)
    along = np.cross(across, up)
    return np.stack([along, across, up], axis=1)


@dataclass(frozen=True)
class TruePass:
    """A pass as flown (``true``) and as GEO sets it up from its records (``geo``)."""

    geo: PassGeometry
    true: PassGeometry
    #: The true absolute attitude (roll, pitch, yaw from the orbital frame).
    true_attitude: SampledAttitude

    def scenes(
        self, scene_lines: int, lost: tuple[int, ...] = (), reference_height_m: float = 450.0
    ) -> list[SceneGeometry]:
        """GEO's scenes of ``scene_lines`` lines in time order, but those ``lost``."""
        cuts = [c for c in cut_scenes(self.geo.n_lines, scene_lines) if c.index not in lost]
        return [self.geo.scene(c, reference_height_m) for c in cuts]

    def true_scene(self, scene: SceneGeometry) -> SceneGeometry:
        """The same cut of the pass as flown."""
        return self.true.scene(scene.cut, scene.reference_height_m, attitude=self.true_attitude)

    def gcps(
        self,
        n: int,
        seed: int,
        line_ranges: tuple[float, ...] = (0.0, 1.0),
        blunder_fraction: float = 0.0,
        blunder_m: float = 100.0,
    ) -> tuple[ControlPointSet, NDArray[np.bool_]]:
        """``n`` control points drawn over the fractions ``line_ranges`` of the pass (pairs
        of start and end), seen on the ground through the truth at 200–800 m, measured with
        :data:`GCP_SIGMAS`; a ``blunder_fraction`` of them moved ``blunder_m`` on the
        ground. Returns the points and which are blunders."""
        rng = np.random.default_rng(seed)
        sigma_g, sigma_h, sigma_px = GCP_SIGMAS
        spans = np.reshape(line_ranges, (-1, 2)) * (self.geo.n_lines - 1)
        which = rng.integers(0, len(spans), n)
        line = rng.uniform(spans[which, 0], spans[which, 1])
        n_columns = next(iter(self.geo.look_angles.values())).n_columns
        column = rng.uniform(0.0, n_columns - 1.0, n)
        (cut,) = cut_scenes(self.geo.n_lines, self.geo.n_lines)
        model = next(iter(self.true.scene(cut, attitude=self.true_attitude).models.values()))
        g = model.image_to_ground(line, column, rng.uniform(200.0, 800.0, n))
        east, north, up = rng.normal(0.0, 1.0, (3, n)) * np.array([[sigma_g], [sigma_g], [sigma_h]])
        d_line, d_column = rng.normal(0.0, sigma_px, (2, n))
        # the blunders from a stream of their own: the other points are the clean draw's
        odd = np.random.default_rng([seed, 1])
        blunder = np.zeros(n, dtype=bool)
        blunder[odd.choice(n, round(blunder_fraction * n), replace=False)] = True
        azimuth = odd.uniform(0.0, 2 * np.pi, n)
        east += np.where(blunder, blunder_m * np.cos(azimuth), 0.0)
        north += np.where(blunder, blunder_m * np.sin(azimuth), 0.0)
        radius = model.ellipsoid.a_m
        points = ControlPointSet(
            tuple(f"g{k}" for k in range(n)),
            g.lon_rad + east / (radius * np.cos(g.lat_rad)),
            g.lat_rad + north / radius,
            g.h_m + up,
            line + d_line,
            column + d_column,
            np.full(n, sigma_g),
            np.full(n, sigma_h),
            np.full(n, sigma_px),
            np.ones(n, dtype=np.int64),
        )
        return points, blunder

    def model_error_en(
        self, scene: SceneGeometry, per_side: int = 11
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """East and north error (m) of a scene's model against the true line of sight on
        the scene's reference surface, at a lattice of whole pixels."""
        line, col = np.meshgrid(
            np.rint(np.linspace(0, scene.cut.n_lines - 1, per_side)),
            np.rint(np.linspace(0, scene.model.n_columns - 1, per_side)),
            indexing="ij",
        )
        line, col = line.ravel(), col.ravel()
        h = scene.reference_height_m
        p = scene.model.image_to_ground(line, col, h)
        q = self.true_scene(scene).model.image_to_ground(line, col, h)
        ell = scene.model.ellipsoid
        d = ell.to_ecef(p.lat_rad, p.lon_rad, p.h_m) - ell.to_ecef(q.lat_rad, q.lon_rad, q.h_m)
        enu = apply(enu_from_ecef(q.lat_rad, q.lon_rad), d)
        return enu[:, 0], enu[:, 1]


def true_pass(
    n_lines: int = 6000,
    n_detectors: int = 6000,
    mirror_step: int = 48,
    seed: int = 0,
    lost_lines: tuple[int, int] | None = None,
    attitude_offset_rad: NDArray[np.float64] = ATTITUDE_OFFSET_RAD,
) -> TruePass:
    """A P pass of ``n_lines`` over 15° S, descending, flown with the emulator's default
    errors (module docstring). ``lost_lines``: the first and last line of a span whose gyro
    records the downlink lost, as an outage of the station loses them;
    ``attitude_offset_rad``: the constant attitude GEO is not told (roll, pitch, yaw)."""
    rng = np.random.default_rng(seed)
    t_eph = np.arange(0.0, 8 * 60.0, 60.0)  # 8 bulletins a minute apart, as SPOT 1–4 files
    r, v = ecef_states(t_eph, lambda t: kepler_eci(t, m0_rad=DESCENDING_M0_RAD))
    period = MODES["P"].line_period_s * 6000 / n_detectors
    t_mid = 0.5 * (t_eph[0] + t_eph[-1])
    line_t = t_mid + period * (np.arange(n_lines) - 0.5 * (n_lines - 1))
    gyro_t = np.arange(line_t[0] - 1.0, line_t[-1] + 1.0, GYRO_PERIOD_S)
    true_angles = attitude_offset_rad + (gyro_t - gyro_t[0])[:, None] * TRUE_RATES_RAD_PER_S
    measured = TRUE_RATES_RAD_PER_S + rng.normal(0.0, GYRO_NOISE_RAD_PER_S, (gyro_t.size, 3))
    j = np.arange(n_detectors, dtype=np.float64)
    psi_y = (j - (n_detectors - 1) / 2) * P_PITCH_RAD * 6000 / n_detectors
    ccd = np.minimum((4 * (j + 0.5) / n_detectors).astype(int), 3)
    table = LookAngleTable(j, BUTTING_RAD[ccd], psi_y + mirror_angle_rad(mirror_step), n_detectors)
    frame = _track_frame(r, v)
    bias = BULLETIN_BIAS_M + (t_eph - t_mid)[:, None] * BULLETIN_DRIFT_M_PER_S
    told = Ephemeris(t_eph, r + np.einsum("nk,nkj->nj", bias, frame), v)
    keep = np.ones(gyro_t.size, dtype=bool)
    if lost_lines is not None:
        t0, t1 = line_t[list(lost_lines)]
        keep = (gyro_t < t0) | (gyro_t > t1)
    geo = pass_geometry(EPOCH, line_t, period, told, gyro_t[keep], measured[keep], {"P": table})
    attitude = SampledAttitude(gyro_t, true_angles)
    true = dataclasses.replace(geo, ephemeris=Ephemeris(t_eph, r, v), attitude=attitude)
    return TruePass(geo, true, attitude)
