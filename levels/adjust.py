"""Level 2: control points refine the sensor model, from one scene to a whole pass.

Westin's pass adjustment (paper ``000_…``), on this project's rigorous model
(:class:`~levels.geometry.model.PushbroomModel`) instead of his plane circular orbit:

Parameters (eqs. 1–3)
    For the **pass**: a bias of the ephemeris along track, across track and radial, and its
    growth per second (six; Westin's ΔΩ, Δi, Δr0 are the same freedoms of a plane orbit).
    For **each scene** ``j``: offsets of roll, pitch, yaw (Westin's Δω0, Δρ0, Δκ0) and their
    rates over the scene. The corrections are applied to the pass's attitude integrated from
    the gyros (:func:`~levels.geometry.attitude.integrate_rates`: Westin's "start values
    calculated from the preceding scene"), so that with attitude records all the way every
    scene needs the same correction. Westin's per-scene time Δt0 is not needed: every row of
    a pass comes from one fitted line clock (:class:`~levels.geo.scenes.PassGeometry`), so
    the scenes' relative timing is known; the clock's absolute error is an along-track bias.

Observations
    Each control point gives the collinearity condition (eqs. 7–9) as two angles: the
    direction to the point seen from the projection centre of its measured line, in the
    sensor frame, minus the look-angle table's at its measured column, expressed in pixels
    (the table's pitch). Its weight is ``(A Q Aᵀ)⁻¹`` (eq. 20): ``A`` the partials of the
    condition with respect to the point's line, column, east, north and height (numerical),
    ``Q`` their a priori variances from the control-point file. The pass parameters are
    observed as zero with the error budget's σ (eq. 4, 10), the first scene's attitude as
    zero (eq. 5, 11), and each following scene's attitude *difference* with the previous
    one (eqs. 6, 12) with the variance of its increment: the gyros' random walk,
    ``σ_g² T Δt``, where records are continuous, and Westin's variogram (eqs. 24–26,
    ``levels.geometry.attitude.westin_variogram_rad2``) over the records lost in a gap.
    Rates are observed as zero with the gyro noise averaged over a scene.

Solution
    Weighted nonlinear least squares in parameters scaled by their a priori σ:
    Gauss–Newton on the sparse normal equations (``scipy``), the first fit with a robust
    loss by iteratively reweighted least squares; then Baarda's data
    snooping: normalised residuals ``v / σ_v`` (``σ_v² = 1 − h``, ``h`` the leverage),
    points beyond the threshold rejected and reported, and a plain least-squares fit on the
    rest. Its covariance (a priori: the error budget is trusted, the unit-weight σ0 is
    reported beside it) propagates to a **predicted accuracy** of every scene, with or
    without control points: the ground displacement (east, north on the reference surface)
    that the parameters' covariance makes at a lattice of the scene's pixels.

Modes: ``pass`` (all scenes together, Westin) and ``scene`` (each alone: its six pass
parameters its own). One control point, or none, is handled by the same equations: what the
points cannot determine is held by the priors, and the predicted σ says so.
"""

from __future__ import annotations

import dataclasses
import functools
import logging
import time
from dataclasses import dataclass, fields
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy import sparse
from scipy.linalg import cho_factor, cho_solve

from levels.errors import AdjustmentError, GeometryError
from levels.geo.scenes import PassGeometry, SceneGeometry
from levels.geometry import collinearity
from levels.geometry.attitude import SampledAttitude, attitude_gaps, westin_variogram_rad2
from levels.geometry.ellipsoid import WGS84
from levels.geometry.ephemeris import Ephemeris
from levels.geometry.frames import (
    apply,
    apply_inverse,
    ecef_from_orbital,
    enu_from_ecef,
    orbital_from_body,
)
from levels.options import ProcessingOptions
from levels.readers.gcp import ControlPointSet

_log = logging.getLogger(__name__)

__all__ = [
    "PASS_PARAMETERS",
    "SCENE_PARAMETERS",
    "Adjustment",
    "Strip",
    "adjust",
    "adjust_block",
    "adjust_strips",
]

#: The pass's parameters, in order (SI units).
PASS_PARAMETERS = (
    "ephemeris_along_m",
    "ephemeris_across_m",
    "ephemeris_radial_m",
    "drift_along_m_per_s",
    "drift_across_m_per_s",
    "drift_radial_m_per_s",
)
#: Each scene's parameters, in order (SI units).
SCENE_PARAMETERS = (
    "roll_rad",
    "pitch_rad",
    "yaw_rad",
    "roll_rate_rad_per_s",
    "pitch_rate_rad_per_s",
    "yaw_rate_rad_per_s",
)
_NP, _NS = len(PASS_PARAMETERS), len(SCENE_PARAMETERS)
#: Lattice of pixels per scene side where the predicted accuracy is evaluated.
PREDICTION_LATTICE = 5
#: Finite-difference steps: parameters (in a priori σ), image (px), ground (m).
_STEP_X, _STEP_PX, _STEP_M = 1e-3, 0.05, 1.0
#: Soft-L1 scale of the robust first fit, in normalised residuals (inliers stay quadratic).
ROBUST_SCALE = 3.0
#: At most this many snooping rounds (each rejects every point beyond the threshold).
MAX_SNOOPING_ROUNDS = 10
#: A point whose residual before the fit is beyond this many σ of what the a priori
#: covariance allows there (parameters' and point's together) is out of the model's
#: reach: no error the budget admits brings it in (another scene's point, a wrong datum).
#: 10σ of a Gaussian budget happens once in 10²³; a budget wrong by a factor 3 still
#: keeps every honest point.
REACH_SIGMAS = 10.0
#: Data snooping finds a few blunders among good points (Baarda); when it rejects more
#: than this share of the points, the points' σ or the model are wrong, not the points.
MAX_REJECTED_SHARE = 0.5


def _orbital(along_across_radial: NDArray[np.float64]) -> NDArray[np.float64]:
    """(along, across, radial) → components on the orbital frame's (X across, Y along, Z)."""
    a = along_across_radial
    return np.stack([a[..., 1], a[..., 0], a[..., 2]], axis=-1)


@dataclass(frozen=True, eq=False)
class _Points:
    """Image points and their ground, with everything that does not depend on the
    parameters evaluated once: the ephemeris and the pass attitude at each point's time."""

    t_s: NDArray[np.float64]
    scene: NDArray[np.int64]  # position in the adjustment's scene list
    g_ecef_m: NDArray[np.float64]
    r: NDArray[np.float64]
    v: NDArray[np.float64]
    axes: NDArray[np.float64]
    attitude: NDArray[np.float64]
    table: NDArray[np.float64]  # (N, 2) the look table's psi_x, psi_y at the column
    pitch_rad: NDArray[np.float64]  # (N,) the look table's pitch (one per HRV and band)

    @functools.cached_property
    def kernel_args(self) -> tuple[NDArray[np.float64], ...]:
        """The points as :mod:`levels.geometry.collinearity`'s kernels take them."""
        arrays = (self.r, self.v, self.axes, self.attitude, self.table, self.pitch_rad)
        return tuple(np.ascontiguousarray(a, dtype=np.float64) for a in (*arrays, self.g_ecef_m))

    @staticmethod
    def concatenate(parts: list[_Points]) -> _Points:
        return _Points(
            *(np.concatenate([getattr(p, f.name) for p in parts]) for f in fields(_Points))
        )


def _points(
    pg: PassGeometry,
    band: str,
    line: NDArray[np.float64],
    column: NDArray[np.float64],
    g_ecef_m: NDArray[np.float64],
    scene: NDArray[np.int64],
) -> _Points:
    t = pg.clock(0).time_s(line)
    r, v = pg.ephemeris.interpolate(t)
    look = pg.look_angles[band]
    px, py = look.angles_rad(column)
    pitch = float(np.median(np.abs(np.diff(look.psi_y_rad))))
    return _Points(
        t,
        scene,
        g_ecef_m,
        r,
        v,
        ecef_from_orbital(r, v),
        pg.attitude.angles_rad(t),
        np.stack([px, py], axis=-1),
        np.full(t.size, pitch),
    )


def _condition(
    p: _Points, bias_m: NDArray[np.float64], drift: NDArray[np.float64], d_att: NDArray[np.float64]
) -> NDArray[np.float64]:
    """The collinearity condition (module docstring) in pixels, ``(N, 2)``, for orbital-frame
    position corrections ``bias_m`` with velocity corrections ``drift`` and attitude
    corrections ``d_att`` per point (:func:`levels.geometry.collinearity.condition`)."""
    c = np.ascontiguousarray(np.concatenate(np.broadcast_arrays(bias_m, drift, d_att), axis=1))
    r, v, axes, att, table, pitch, g = p.kernel_args
    return collinearity.condition(r, v, axes, att, table, pitch, g, c)


def _condition_numpy(
    p: _Points, bias_m: NDArray[np.float64], drift: NDArray[np.float64], d_att: NDArray[np.float64]
) -> NDArray[np.float64]:
    """The collinearity condition (module docstring) in pixels, in numpy (the reference
    :mod:`levels.geometry.collinearity`'s kernels are tested against), ``(N, 2)``, for orbital-frame
    position corrections ``bias_m`` with velocity corrections ``drift`` and attitude
    corrections ``d_att`` per point. The orbital frame is rebuilt on the corrected state, as
    the refined model (:meth:`Adjustment.refine`) does."""
    r = p.r + apply(p.axes, bias_m)
    v = p.v + apply(p.axes, drift)
    axes = ecef_from_orbital(r, v)
    a = p.attitude + d_att
    body = orbital_from_body(a[:, 0], a[:, 1], a[:, 2])
    w = apply_inverse(body, apply_inverse(axes, p.g_ecef_m - r))
    depth = -w[:, 2]
    with np.errstate(invalid="ignore", divide="ignore"):
        psi = np.stack([np.arctan(w[:, 1] / depth), np.arctan(-w[:, 0] / depth)], axis=-1)
    return (psi - p.table) / p.pitch_rad[:, None]


def _local_axes(g_ecef_m: NDArray[np.float64]) -> NDArray[np.float64]:
    """East, north, up unit vectors at ECEF points, ``(N, 3, 3)`` (rows)."""
    lat, lon, _h = WGS84.to_geodetic(g_ecef_m)
    return enu_from_ecef(lat, lon)


@dataclass(frozen=True, eq=False)
class _Problem:
    """One least-squares problem: the points, the scenes' times and the priors."""

    points: _Points
    whitening: NDArray[np.float64]  # (N, 2, 2): L⁻¹ with L Lᵀ = A Q Aᵀ
    t_ref_s: float
    t_centre_s: NDArray[np.float64]  # (S,)
    sigma_pass: NDArray[np.float64]  # (6,) a priori σ, SI
    sigma_scene: NDArray[np.float64]  # (6,)
    increment_sigma: NDArray[np.float64]  # (S, 3): σ of attitude jumps from the previous

    @property
    def n_scenes(self) -> int:
        return int(self.t_centre_s.size)

    @property
    def n_params(self) -> int:
        return _NP + _NS * self.n_scenes

    def split(self, x: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Pass (6,) and scene (S, 6) parameters in SI from the scaled vector."""
        return x[:_NP] * self.sigma_pass, x[_NP:].reshape(-1, _NS) * self.sigma_scene

    def corrections(
        self, x: NDArray[np.float64], p: _Points
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        pas, sce = self.split(x)
        dt = p.t_s - self.t_ref_s
        bias = _orbital(pas[:3] + pas[3:] * dt[:, None])
        drift = np.broadcast_to(_orbital(pas[3:]), bias.shape)
        s = sce[p.scene]
        att = s[:, :3] + s[:, 3:] * (p.t_s - self.t_centre_s[p.scene])[:, None]
        return bias, drift, att

    def condition(self, x: NDArray[np.float64], p: _Points | None = None) -> NDArray:
        p = self.points if p is None else p
        return _condition(p, *self.corrections(x, p))

    def parameter_jacobian(self, x: NDArray[np.float64], p: _Points) -> NDArray[np.float64]:
        """∂condition/∂x, ``(N, 2, 12)``: the 6 pass and the point's own scene's 6 columns
        (central differences of ± ``_STEP_X``, in one kernel call: the corrections
        are linear in the parameters, so each parameter moves a point's nine corrections
        along a fixed direction)."""
        c = np.concatenate(self.corrections(x, p), axis=1)
        dt = p.t_s - self.t_ref_s
        dc = np.zeros((p.t_s.size, _NP + _NS, 9))
        for k in range(3):  # along, across, radial: orbital X across, Y along, Z
            o = (1, 0, 2)[k]
            dc[:, k, o] = self.sigma_pass[k]
            dc[:, 3 + k, o] = self.sigma_pass[3 + k] * dt
            dc[:, 3 + k, 3 + o] = self.sigma_pass[3 + k]
            dc[:, _NP + k, 6 + k] = self.sigma_scene[k]
            dc[:, _NP + 3 + k, 6 + k] = self.sigma_scene[3 + k] * (p.t_s - self.t_centre_s[p.scene])
        r, v, axes, att, table, pitch, g = p.kernel_args
        c = np.ascontiguousarray(c)
        return collinearity.jacobian(r, v, axes, att, table, pitch, g, c, dc, _STEP_X)

    def ground_jacobian(
        self, x: NDArray[np.float64], p: _Points, directions: NDArray[np.float64]
    ) -> NDArray[np.float64]:
        """∂condition/∂(ground moved along ``directions``, ``(N, K, 3)`` unit vectors), in
        pixels per metre, ``(N, 2, K)`` (forward differences of ``_STEP_M``)."""
        c = np.ascontiguousarray(np.concatenate(self.corrections(x, p), axis=1))
        r, v, axes, att, table, pitch, g = p.kernel_args
        d = np.ascontiguousarray(directions)
        return collinearity.ground_jacobian(r, v, axes, att, table, pitch, g, c, d, _STEP_M)

    @functools.cached_property
    def prior_rows(self) -> NDArray[np.float64]:
        """The linear pseudo-observations on the scaled parameters (eqs. 4–6, 10–12): the
        pass parameters and every rate observed as zero, the first scene's attitude as
        zero, each following scene's attitude minus the previous one's as zero with the
        weight of its jump."""
        n = self.n_params
        rows = np.eye(n)
        att = _NP + _NS * np.arange(1, self.n_scenes)[:, None] + np.arange(3)  # (S-1, 3)
        w = self.sigma_scene[:3] / self.increment_sigma[1:]
        rows[att, att] = w
        rows[att, att - _NS] = -w
        rows.setflags(write=False)
        return rows

    def residuals(self, x: NDArray[np.float64], use: NDArray[np.bool_]) -> NDArray[np.float64]:
        f = self.condition(x)[use]
        wf = np.einsum("nij,nj->ni", self.whitening[use], f).ravel()
        return np.concatenate([wf, self.prior_rows @ x])

    def jacobian(self, x: NDArray[np.float64], use: NDArray[np.bool_]) -> sparse.csr_matrix:
        """The Jacobian of :meth:`residuals`, sparse: a point's two rows touch the 6 pass
        and its scene's 6 parameters, a prior row one or two."""
        p = self.points
        local = self.parameter_jacobian(x, p)[use]  # (n, 2, 12)
        local = np.einsum("nij,njk->nik", self.whitening[use], local)
        n = local.shape[0]
        cols = np.concatenate(
            [
                np.broadcast_to(np.arange(_NP), (n, _NP)),
                _NP + _NS * p.scene[use][:, None] + np.arange(_NS),
            ],
            axis=1,
        )  # (n, 12)
        obs = sparse.csr_matrix(
            (
                local.reshape(-1),
                np.repeat(cols[:, None, :], 2, axis=1).reshape(-1),
                np.arange(0, 2 * n * 12 + 1, 12),
            ),
            shape=(2 * n, self.n_params),
        )
        return sparse.vstack([obs, self._prior_sparse], format="csr")

    @functools.cached_property
    def _prior_sparse(self) -> sparse.csr_matrix:
        return sparse.csr_matrix(self.prior_rows)


@dataclass(frozen=True, eq=False)
class Adjustment:
    """A solved adjustment: the corrections of every scene, their covariance and predicted
    accuracy, and what became of every control point.

    Per-scene arrays are in the order of ``scene_index`` (the scenes' cut indices). In
    ``pass`` mode every scene shares the pass parameters; in ``scene`` mode each has its own.
    Covariances are ``(S, 12, 12)`` over the 6 pass and the scene's 6 parameters, SI units.
    """

    mode: str
    t_ref_s: float
    scene_index: NDArray[np.int64]
    t_centre_s: NDArray[np.float64]
    pass_parameters: NDArray[np.float64]  # (S, 6)
    scene_parameters: NDArray[np.float64]  # (S, 6)
    covariance: NDArray[np.float64]  # (S, 12, 12)
    predicted_sigma_m: NDArray[np.float64]  # (S, 3): east, north, horizontal (RMS)
    prior_sigma_m: NDArray[np.float64]  # (S, 3): the same from the priors alone
    increment_sigma_rad: NDArray[np.float64]  # (S, 3): σ of each scene's jump, inf first
    gap_s: NDArray[np.float64]  # (S,): attitude records lost since the previous scene
    point_id: tuple[str, ...]
    point_scene: NDArray[np.int64]  # cut index, -1 outside every scene
    point_status: tuple[str, ...]  # used, rejected, outside
    residual_before_px: NDArray[np.float64]  # (N, 2): along (line), across (column)
    residual_after_px: NDArray[np.float64]
    normalised_residual: NDArray[np.float64]  # (N,) at the last test, NaN if not tested
    sigma0: float
    timings_s: dict[str, float]
    #: A block's tie points found to be blunders and left out (their ids).
    ties_rejected: tuple[str, ...] = ()

    def of_scene(self, index: int) -> int:
        hit = np.flatnonzero(self.scene_index == index)
        if hit.size == 0:
            raise GeometryError(f"scene {index} was not in the adjustment")
        return int(hit[0])

    def refine(self, pg: PassGeometry, scene: SceneGeometry) -> SceneGeometry:
        """The scene again, on the refined ephemeris and attitude (module docstring)."""
        k = self.of_scene(scene.cut.index)
        pas, sce = self.pass_parameters[k], self.scene_parameters[k]
        e = pg.ephemeris
        dt = e.t_s - self.t_ref_s
        axes = ecef_from_orbital(e.r_ecef_m, e.v_ecef_m_per_s)
        r = e.r_ecef_m + apply(axes, _orbital(pas[:3] + pas[3:] * dt[:, None]))
        v = e.v_ecef_m_per_s + apply(axes, np.broadcast_to(_orbital(pas[3:]), r.shape))
        eph = Ephemeris(e.t_s, r, v, e.n_points, e.reference_velocity)
        a = pg.attitude
        da = sce[:3] + sce[3:] * (a.t_s - self.t_centre_s[k])[:, None]
        att = SampledAttitude(a.t_s, a.angles_rad_samples + da, a.hold_s)
        return pg.scene(scene.cut, scene.reference_height_m, ephemeris=eph, attitude=att)

    def summary(self) -> dict[str, Any]:
        """Headline figures of the whole adjustment (the run report's)."""
        status = np.array(self.point_status)
        after = np.hypot(*self.residual_after_px[status == "used"].T)
        return {
            "mode": self.mode,
            "points_used": int(np.sum(status == "used")),
            "points_rejected": int(np.sum(status == "rejected")),
            "points_outside": int(np.sum(status == "outside")),
            "rejected": [i for i, s in zip(self.point_id, status, strict=True) if s == "rejected"],
            "residual_rms_px": float(np.sqrt(np.mean(after**2))) if after.size else None,
            "sigma0": self.sigma0,
        }

    def product_tree(self, index: int) -> dict[str, Any]:
        """``geometry/adjustment`` of the scene's level 2 product (``docs/products.md``)."""
        k = self.of_scene(index)
        return {
            "mode": self.mode,
            "note": "pass ephemeris bias and drift (along, across, radial) and the scene's "
            "attitude offsets and rates, added to the gyro-integrated attitude (Westin); "
            "covariance over the 6 pass and 6 scene parameters, a priori",
            "t_ref_s": self.t_ref_s,
            "t_centre_s": float(self.t_centre_s[k]),
            "pass_parameter_names": list(PASS_PARAMETERS),
            "pass_parameters": self.pass_parameters[k],
            "scene_parameter_names": list(SCENE_PARAMETERS),
            "scene_parameters": self.scene_parameters[k],
            "covariance": self.covariance[k],
            "predicted_sigma_m": {
                "east": float(self.predicted_sigma_m[k, 0]),
                "north": float(self.predicted_sigma_m[k, 1]),
                "horizontal": float(self.predicted_sigma_m[k, 2]),
                "prior_horizontal": float(self.prior_sigma_m[k, 2]),
            },
            "attitude_jump_sigma_rad": self.increment_sigma_rad[k],
            "attitude_gap_s": float(self.gap_s[k]),
            "sigma0": self.sigma0,
            "points": {
                "id": list(self.point_id),
                "scene": self.point_scene,
                "status": list(self.point_status),
                "residual_before_px": self.residual_before_px,
                "residual_after_px": self.residual_after_px,
                "normalised_residual": self.normalised_residual,
            },
            **({"ties_rejected": list(self.ties_rejected)} if self.mode == "block" else {}),
        }


def _increment_sigma(
    gaps: NDArray[np.float64],
    t_centre_s: NDArray[np.float64],
    record_period_s: float,
    options: ProcessingOptions,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """σ of each scene's attitude jump from the previous scene (``(S, 3)``, inf for the
    first) and the attitude records lost between them (s): the gyros' random walk over the
    recorded time, Westin's variogram over the lost time."""
    a, b = t_centre_s[:-1, None], t_centre_s[1:, None]  # each interval against each gap
    overlap = np.clip(np.minimum(gaps[:, 1], b) - np.maximum(gaps[:, 0], a), 0.0, None)
    lost = np.r_[0.0, overlap.sum(axis=1)]
    recorded = np.clip(np.diff(t_centre_s) - lost[1:], 0.0, None)
    walk = options.gyro_noise_rad_per_s**2 * record_period_s * recorded
    var = walk[:, None] + options.variogram_scale * np.stack(
        [westin_variogram_rad2(k, lost[1:]) for k in range(3)], axis=-1
    )
    sig = np.vstack([np.full((1, 3), np.inf), np.sqrt(np.maximum(var, 1e-24))])
    return sig, lost


def _image_partials(
    pg: PassGeometry, band: str, line: NDArray, col: NDArray, p: _Points
) -> NDArray[np.float64]:
    """The condition's partials by the measured line and column, ``(N, 2, 2)``."""
    zero = np.zeros((p.t_s.size, 3))
    f0 = _condition(p, zero, zero, zero)
    return np.stack(
        [
            (
                _condition(
                    _points(pg, band, line + dl, col + dc, p.g_ecef_m, p.scene), zero, zero, zero
                )
                - f0
            )
            / _STEP_PX
            for dl, dc in ((_STEP_PX, 0.0), (0.0, _STEP_PX))
        ],
        axis=-1,
    )


def _whitening(
    pg: PassGeometry,
    band: str,
    gcps: ControlPointSet,
    use: NDArray[np.bool_],
    p: _Points,
) -> NDArray[np.float64]:
    """``L⁻¹`` of every point's condition covariance ``A Q Aᵀ`` (eq. 20), ``(N, 2, 2)``."""
    zero = np.zeros((p.t_s.size, 3))
    f0 = _condition(p, zero, zero, zero)
    line, col = gcps.line[use], gcps.column[use]
    cols = list(np.moveaxis(_image_partials(pg, band, line, col, p), -1, 0))
    enu = _local_axes(p.g_ecef_m)
    for k in range(3):
        q = _points(pg, band, line, col, p.g_ecef_m + _STEP_M * enu[:, k], p.scene)
        cols.append((_condition(q, zero, zero, zero) - f0) / _STEP_M)
    a = np.stack(cols, axis=-1)  # (N, 2, 5): line, column, east, north, up
    sg, sh, sp = gcps.sigma_ground_m[use], gcps.sigma_h_m[use], gcps.sigma_px[use]
    q_diag = np.stack([sp**2, sp**2, sg**2, sg**2, sh**2], axis=-1)
    cov = np.einsum("nik,nk,njk->nij", a, q_diag, a)
    return np.linalg.inv(np.linalg.cholesky(cov))


def _problem(
    strips: list[Strip],
    uses: list[NDArray[np.bool_]],
    nodes: list[NDArray[np.int64]],
    t_node_s: NDArray[np.float64],
    t_ref_s: float,
    options: ProcessingOptions,
) -> tuple[_Problem, NDArray[np.float64]]:
    """The least-squares problem of the attitude nodes at ``t_node_s`` with each strip's
    points ``uses[k]`` (``nodes[k]``: each point's node, positions in ``t_node_s``), and the
    attitude records lost before each node (s)."""
    parts, white = [], []
    for s, use, node in zip(strips, uses, nodes, strict=True):
        g = WGS84.to_ecef(s.gcps.lat_rad[use], s.gcps.lon_rad[use], s.gcps.h_m[use])
        p = _points(s.pg, s.band, s.gcps.line[use], s.gcps.column[use], g, node[use])
        parts.append(p)
        white.append(_whitening(s.pg, s.band, s.gcps, use, p))
    att = strips[0].pg.attitude  # every strip's: checked by adjust_strips
    period = float(np.median(np.diff(att.t_s)))
    inc, lost = _increment_sigma(attitude_gaps(att.t_s), t_node_s, period, options)
    prob = _Problem(
        _Points.concatenate(parts),
        np.concatenate(white),
        t_ref_s,
        t_node_s,
        np.r_[options.prior_ephemeris_m, options.prior_ephemeris_drift_m_per_s],
        np.r_[options.prior_attitude_rad, [options.prior_attitude_rate_rad_per_s] * 3],
        inc,
    )
    return prob, lost


#: Robust losses: the weight ``ρ'(z)`` of a residual with ``z = (r / ROBUST_SCALE)²``, as
#: ``scipy.optimize.least_squares`` defines them.
_LOSS_WEIGHT = {
    "linear": lambda z: np.ones_like(z),
    "soft_l1": lambda z: 1.0 / np.sqrt(1.0 + z),
    "huber": lambda z: np.where(z <= 1.0, 1.0, 1.0 / np.sqrt(np.maximum(z, 1.0))),
    "cauchy": lambda z: 1.0 / (1.0 + z),
}
_LOSS_RHO = {
    "linear": lambda z: z,
    "soft_l1": lambda z: 2.0 * (np.sqrt(1.0 + z) - 1.0),
    "huber": lambda z: np.where(z <= 1.0, z, 2.0 * np.sqrt(np.maximum(z, 1.0)) - 1.0),
    "cauchy": lambda z: np.log1p(z),
}
#: Gauss–Newton stops when no scaled parameter moves more than ``STEP_TOL`` (a priori σ),
#: when a step lowers the cost by less than ``COST_TOL`` of it (rounding: the minimum is
#: reached), or after ``MAX_ITERATIONS``; a step that raises the cost is halved at most
#: ``MAX_HALVINGS`` times.
STEP_TOL, COST_TOL, MAX_ITERATIONS, MAX_HALVINGS = 1e-7, 1e-10, 30, 8


def _cost(
    prob: _Problem, x: NDArray[np.float64], use: NDArray[np.bool_], loss: str
) -> tuple[float, NDArray[np.float64]]:
    """The robust cost: ``Σ ρ(z)`` over the observations (in ``ROBUST_SCALE²`` units), plus
    the squared prior rows (never down-weighted: a prior is not a blunder); and the
    residuals it was computed from."""
    r = prob.residuals(x, use)
    n = 2 * int(use.sum())
    z = (r[:n] / ROBUST_SCALE) ** 2
    return float(ROBUST_SCALE**2 * np.sum(_LOSS_RHO[loss](z)) + np.sum(r[n:] ** 2)), r


def _solve(
    prob: _Problem, use: NDArray[np.bool_], x0: NDArray[np.float64], loss: str
) -> NDArray[np.float64]:
    """Weighted nonlinear least squares on the scaled parameters: Gauss–Newton on the
    normal equations (sparse ``JᵀWJ``, a Cholesky factor from ``scipy.linalg``), the robust
    loss by iteratively reweighted least squares (Holland & Welsch's IRLS: each
    observation weighted by ``ρ'(z)`` at the current residuals; its fixed point is the
    robust minimum ``scipy.optimize.least_squares`` seeks), steps halved while the cost
    rises. ``least_squares`` itself (``trf``, dense) spent 70 % of its time in the SVD of a
    1000 × 450 Jacobian; the normal equations of this weakly nonlinear problem converge in
    3–5 steps."""
    x = x0.copy()
    n = 2 * int(use.sum())
    cost, r = _cost(prob, x, use, loss)
    for _ in range(MAX_ITERATIONS):
        jac = prob.jacobian(x, use)
        w = np.ones(r.size)
        w[:n] = _LOSS_WEIGHT[loss]((r[:n] / ROBUST_SCALE) ** 2)
        wj = sparse.diags(w) @ jac
        normal = (jac.T @ wj).toarray()
        dx = -cho_solve(cho_factor(normal), wj.T @ r)
        for _ in range(MAX_HALVINGS):
            trial, r_trial = _cost(prob, x + dx, use, loss)
            if trial <= cost * (1 + 1e-12) + 1e-12:
                break
            dx = 0.5 * dx
        else:
            break  # no descent along the Gauss–Newton direction: at the minimum
        x, decrease, cost, r = x + dx, cost - trial, trial, r_trial
        if np.max(np.abs(dx)) < STEP_TOL or decrease <= COST_TOL * cost:
            break
    return x


def _normalised(
    prob: _Problem, x: NDArray[np.float64], use: NDArray[np.bool_]
) -> tuple[NDArray[np.float64], NDArray[np.float64], float]:
    """Baarda's normalised residual of each used point (the larger of its two), the scaled
    covariance ``(JᵀJ)⁻¹`` at ``x`` and the sum of squared normalised residuals (χ²)."""
    jac = prob.jacobian(x, use)
    cov = np.linalg.inv((jac.T @ jac).toarray())
    n = int(use.sum())
    jo = jac[: 2 * n].toarray()
    leverage = np.sum((jo @ cov) * jo, axis=1)
    r = prob.residuals(x, use)
    w = np.abs(r[: 2 * n]) / np.sqrt(np.clip(1.0 - leverage, 1e-12, None))
    return w.reshape(n, 2).max(axis=1), cov, float(np.sum(r**2))


def _within_reach(
    prob: _Problem, prior_cov: NDArray[np.float64], n_points: int
) -> NDArray[np.bool_]:
    """The points whose residual before the fit is within ``REACH_SIGMAS`` of its a priori
    σ: the whitened condition ``f`` has unit variance from the point, and ``J P Jᵀ`` from
    the parameters' a priori covariance ``P`` (scaled), so ``f / √(1 + diag J P Jᵀ)``."""
    use = np.ones(n_points, dtype=bool)
    x = np.zeros(prob.n_params)
    jo = prob.jacobian(x, use)[: 2 * n_points].toarray()
    r = prob.residuals(x, use)[: 2 * n_points]
    z = np.abs(r) / np.sqrt(1.0 + np.sum((jo @ prior_cov) * jo, axis=1))
    return np.all(z.reshape(n_points, 2) <= REACH_SIGMAS, axis=1)


def _fit(
    prob: _Problem, n_points: int, prior_cov: NDArray[np.float64], options: ProcessingOptions
) -> tuple[NDArray[np.float64], NDArray[np.bool_], NDArray[np.float64], NDArray, float]:
    """The robust fit, then Baarda's data snooping with plain fits until no point is beyond
    the threshold: the solution, the points kept, each point's last normalised residual,
    the scaled covariance and χ². Without points, the priors alone."""
    x = np.zeros(prob.n_params)
    wr = np.full(n_points, np.nan)
    if not n_points:
        return x, np.ones(0, dtype=bool), wr, prior_cov, 0.0
    active = _within_reach(prob, prior_cov, n_points)
    if not active.any():
        return x, active, wr, prior_cov, 0.0
    # the robust fit is tested first; every later test is of a plain fit
    x, robust = _solve(prob, active, x, options.robust_loss), True
    for _ in range(MAX_SNOOPING_ROUNDS):
        w, cov, chi2 = _normalised(prob, x, active)
        wr[active] = w
        bad = np.flatnonzero(active)[w > options.blunder_threshold]
        if bad.size == 0 or bad.size >= active.sum():
            break
        active[bad] = False
        x, robust = _solve(prob, active, x, "linear"), False
    else:  # out of rounds: the last fit is not tested yet
        w, cov, chi2 = _normalised(prob, x, active)
        wr[active] = w
    if robust:
        x = _solve(prob, active, x, "linear")
        w, cov, chi2 = _normalised(prob, x, active)
        wr[active] = w
    return x, active, wr, cov, chi2


def _predicted(
    prob: _Problem,
    strip: Strip,
    scene_node: NDArray[np.int64],
    x: NDArray[np.float64],
    covariances: list[NDArray[np.float64]],
) -> list[NDArray[np.float64]]:
    """Predicted ground σ (east, north, horizontal RMS) of each of the strip's scenes
    (``scene_node``: their nodes in ``prob``), ``(S, 3)`` for each scaled covariance given:
    the ground displacement ``J_g⁻¹ J_x`` at a lattice of every scene's pixels on its
    reference surface, through the covariance (all scenes at once)."""
    m, pg, band = PREDICTION_LATTICE, strip.pg, strip.band
    lines, cols, ground = [], [], []
    for scene in strip.scenes:
        line, col = (
            a.ravel()
            for a in np.meshgrid(
                np.linspace(0, scene.cut.n_lines - 1, m),
                np.linspace(0, scene.model.n_columns - 1, m),
                indexing="ij",
            )
        )
        gp = scene.model.image_to_ground(line, col, scene.reference_height_m)
        lines.append(line + scene.cut.first_line)
        cols.append(col)
        ground.append(WGS84.to_ecef(gp.lat_rad, gp.lon_rad, gp.h_m))
    line, col, g = (np.concatenate(v) for v in (lines, cols, ground))
    which = np.repeat(np.arange(len(strip.scenes)), m * m)  # each lattice point's scene
    at = scene_node[which]
    p = _points(pg, band, line, col, g, at)
    jx = prob.parameter_jacobian(x, p)  # (n, 2, 12)
    f0 = prob.condition(x, p)
    enu = _local_axes(g)
    jg = np.stack(
        [
            (prob.condition(x, _points(pg, band, line, col, g + _STEP_M * enu[:, k], at)) - f0)
            / _STEP_M
            for k in range(2)
        ],
        axis=-1,
    )  # (n, 2, 2): the condition per metre east, north
    move = np.linalg.solve(jg, jx)  # ground metres per scaled parameter, (n, 2, 12)
    sel = np.concatenate(
        [np.broadcast_to(np.arange(_NP), (at.size, _NP)), _NP + _NS * at[:, None] + np.arange(_NS)],
        axis=1,
    )  # (n, 12): each point's parameters
    out = []
    for cov in covariances:
        c = cov[sel[:, :, None], sel[:, None, :]]  # (n, 12, 12)
        cg = np.einsum("nik,nkl,njl->nij", move, c, move)
        var = np.stack([cg[:, 0, 0], cg[:, 1, 1]], axis=-1)
        per = np.zeros((len(strip.scenes), 3))
        for k in range(2):
            per[:, k] = np.bincount(which, var[:, k], len(strip.scenes)) / m**2
        per[:, 2] = per[:, 0] + per[:, 1]
        out.append(np.sqrt(per))
    return out


def _scene_of_points(
    scenes: list[SceneGeometry], line: NDArray[np.float64]
) -> tuple[NDArray[np.int64], NDArray[np.bool_]]:
    """Position in ``scenes`` of each point's scene (the nearest centre among the scenes
    holding its line; 0 where none does), and whether any does."""
    if not scenes:
        return np.zeros(line.size, dtype=np.int64), np.zeros(line.size, dtype=bool)
    first = np.array([s.cut.first_line for s in scenes], dtype=np.float64)
    n = np.array([s.cut.n_lines for s in scenes], dtype=np.float64)
    inside = (line[:, None] >= first - 0.5) & (line[:, None] <= first + n - 0.5)
    dist = np.where(inside, np.abs(line[:, None] - (first + 0.5 * (n - 1))), np.inf)
    return np.argmin(dist, axis=1), np.asarray(inside.any(axis=1))


@dataclass(frozen=True)
class Strip:
    """One HRV's share of a pass: GEO's set-up, the scenes made of it (in time order), its
    control points (``line`` in the pass's rows) and the band they were measured in
    (default: the first)."""

    pg: PassGeometry
    scenes: list[SceneGeometry]
    gcps: ControlPointSet
    band: str = ""

    def __post_init__(self) -> None:
        if not self.band:
            object.__setattr__(self, "band", next(iter(self.pg.look_angles)))
        # tie points (kind "tie") tie passes together: one pass's adjustment has no use
        # for a point whose ground it does not know (docs/gcp.md)
        object.__setattr__(self, "gcps", self.gcps.controls())


def adjust(
    pg: PassGeometry,
    scenes: list[SceneGeometry],
    gcps: ControlPointSet,
    options: ProcessingOptions,
    band: str | None = None,
) -> Adjustment:
    """Refine the pass's model with its control points (module docstring).

    Parameters
    ----------
    pg
        GEO's pass set-up (the gyro-integrated attitude, ephemeris, clock, look angles).
    scenes
        The scenes made of the pass, in time order; every one gets its corrections and its
        predicted accuracy, with or without control points.
    gcps
        The pass's control points of this HRV (``line`` in the pass's rows); points in no
        scene are reported ``outside`` and not used.
    options
        ``adjustment`` (mode), the priors, the robust loss and the blunder threshold.
    band
        The band whose look angles the points were measured in (default: the first).
    """
    return adjust_strips([Strip(pg, scenes, gcps, band or "")], options)[0]


#: Scenes of different HRVs whose centres are closer than this share one attitude node.
NODE_TOLERANCE_S = 1e-3


def adjust_strips(strips: list[Strip], options: ProcessingOptions) -> tuple[Adjustment, ...]:
    """Refine several HRVs of one pass together: a twin pass (ADRIN, ``001_…``: "the two
    HRVs share the platform"). One ephemeris correction, and one attitude correction per
    *node*, the scenes' centre instants over every strip (scenes of both HRVs at the same
    instant share a node), so that control points in one HRV refine the other. The strips
    must share one platform attitude (GEO from the same gyro records); each HRV's look
    angles are its own, their relative error not modelled (an HRV's calibration, 1 µrad,
    is well below what the points measure). ``options.adjustment`` ``scene`` adjusts each
    node alone, any other mode all nodes together.

    Returns one :class:`Adjustment` per strip, in order.
    """
    t0 = time.perf_counter()
    nodes, t_ref = _pass_nodes(strips, "no scene to adjust")
    n_nodes = nodes.t_node.size
    groups = (
        [[j] for j in range(n_nodes)] if options.adjustment == "scene" else [list(range(n_nodes))]
    )
    sol = _Solution.empty(strips, n_nodes, nodes.has)
    for group in groups:
        _solve_group(strips, nodes, group, t_ref, options, sol)
    sigma0 = float(np.sqrt(sol.chi2 / sol.dof)) if sol.dof else float("nan")
    _judge(strips, sol, options.fit_confidence)
    if options.adjustment == "scene":
        mode = "scene"
    else:
        mode = "twin" if len(strips) > 1 else "pass"
    elapsed = {"adjust": time.perf_counter() - t0}
    out = []
    for k, s in enumerate(strips):
        sn = nodes.scene_node[k]
        out.append(
            Adjustment(
                mode,
                t_ref,
                nodes.index[k],
                nodes.t_node[sn],
                sol.node_pass[sn],
                sol.node_scene[sn],
                sol.node_cov[sn],
                sol.predicted[k],
                sol.prior[k],
                sol.node_inc[sn],
                sol.node_lost[sn],
                tuple(s.gcps.id),
                nodes.point_scene[k],
                tuple(str(v) for v in sol.status[k]),
                sol.before[k],
                sol.after[k],
                sol.wres[k],
                sigma0,
                elapsed,
            )
        )
    return tuple(out)


def _judge(strips: list[Strip], sol: _Solution, confidence: float) -> None:
    """The fit judged before anything is made of it: :class:`AdjustmentError` naming the
    points when every point is out of the model's reach (``REACH_SIGMAS``), when more than
    ``MAX_REJECTED_SHARE`` of them are rejected, or when its χ²
    fails the global test, ``χ² > χ²_dof(confidence)`` (the unit-weight σ0 beyond what the
    a priori σ of the points and of the budget allow: the points, or the model, wrong)."""
    from scipy.stats import chi2 as chi2_law

    ids = [i for s in strips for i in s.gcps.id]
    status = np.concatenate([np.asarray(st, dtype=object) for st in sol.status])
    inside = status != "outside"
    if inside.any() and not sol.dof:
        before = np.concatenate(sol.before)
        miss = np.hypot(before[:, 0], before[:, 1])
        worst = np.flatnonzero(inside)[np.argsort(-miss[inside])][:3]
        raise AdjustmentError(
            f"level 2: none of the {int(inside.sum())} control points is within reach of the "
            f"model ({REACH_SIGMAS:g}σ of its a priori accuracy): "
            + ", ".join(f"{ids[k]} misses by {miss[k]:.0f} px" for k in worst)
            + "; are they this pass's points, in its lines and columns?"
        )
    rejected = np.flatnonzero(status == "rejected")
    if rejected.size > MAX_REJECTED_SHARE * inside.sum():
        raise AdjustmentError(
            f"level 2: {rejected.size} of the {int(inside.sum())} control points rejected "
            f"(more than {MAX_REJECTED_SHARE:.0%}): "
            + ", ".join(ids[k] for k in rejected[:5])
            + ("…" if rejected.size > 5 else "")
            + "; the points' σ or the model are wrong, not a few points: check them"
        )
    _say_refused(ids, status, np.concatenate(sol.before) if sol.before else None)
    if not sol.dof:
        return
    limit = float(chi2_law.ppf(confidence, sol.dof))
    if sol.chi2 <= limit:
        return
    wres = np.concatenate(sol.wres)
    used = np.flatnonzero(status == "used")
    worst = used[np.argsort(-np.nan_to_num(wres[used]))][:3]
    raise AdjustmentError(
        f"level 2: the fit fails its χ² test: σ0 {np.sqrt(sol.chi2 / sol.dof):.2f} beyond "
        f"{np.sqrt(limit / sol.dof):.2f} ({confidence:.1%} for {sol.dof} degrees of "
        "freedom); the points do not fit the model within their σ: worst "
        + ", ".join(f"{ids[k]} ({wres[k]:.1f}σ)" for k in worst)
        + "; check the points and their σ (or [processing] fit_confidence)"
    )


def _say_refused(ids: list[str], status: NDArray[Any], before: NDArray[Any] | None) -> None:
    """One console line (a warning) per control point the fit did not use: rejected as a
    blunder, or out of the model's reach; with how far the model before the fit missed it."""
    for k in np.flatnonzero((status == "rejected") | (status == "outside")):
        miss = (
            f"; the model before the fit misses it by {np.hypot(*before[k, :2]):.0f} px"
            if before is not None and np.all(np.isfinite(before[k, :2]))
            else ""
        )
        what = "rejected as a blunder" if status[k] == "rejected" else "out of the model's reach"
        _log.warning("level 2: control point %s %s, not used%s", ids[k], what, miss)


def _pass_nodes(strips: list[Strip], no_scene: str) -> tuple[_Nodes, float]:
    """The attitude nodes of one pass's strips and its reference time (the middle of the
    first strip's lines), after checking it has a scene (else ``GeometryError(no_scene)``)
    and one platform."""
    if not strips or not any(s.scenes for s in strips):
        raise GeometryError(no_scene)
    _check_one_platform(strips)
    pg0 = strips[0].pg
    return _nodes(strips), float(0.5 * (pg0.line_t_s[0] + pg0.line_t_s[-1]))


def _check_one_platform(strips: list[Strip]) -> None:
    """The strips' GEO share one platform attitude, or :class:`GeometryError`."""
    att = strips[0].pg.attitude
    for s in strips[1:]:
        if not (
            np.array_equal(s.pg.attitude.t_s, att.t_s)
            and np.array_equal(s.pg.attitude.angles_rad_samples, att.angles_rad_samples)
        ):
            raise GeometryError(
                "the HRVs of a joint adjustment must share one platform attitude: "
                "make their GEO from the same gyro records"
            )


@dataclass(frozen=True, eq=False)
class _Nodes:
    """The nodes of a joint adjustment (:func:`adjust_strips`): their instants, each
    strip's scenes' node and index, and each strip's points' node, whether a scene holds
    them, and that scene's index (−1: none)."""

    t_node: NDArray[np.float64]
    scene_node: list[NDArray[np.int64]]
    index: list[NDArray[np.int64]]
    point_node: list[NDArray[np.int64]]
    has: list[NDArray[np.bool_]]
    point_scene: list[NDArray[np.int64]]


def _nodes(strips: list[Strip]) -> _Nodes:
    """Every scene's centre a node, those of several HRVs at one instant merged."""
    t_scene = [np.array([sc.t_centre_s for sc in s.scenes]) for s in strips]
    t_all = np.concatenate(t_scene)
    order = np.argsort(t_all, kind="stable")
    first = np.r_[True, np.diff(t_all[order]) > NODE_TOLERANCE_S]
    t_node = t_all[order][first]
    node_of = np.empty(t_all.size, dtype=np.int64)
    node_of[order] = np.cumsum(first) - 1
    scene_node = np.split(node_of, np.cumsum([t.size for t in t_scene])[:-1])
    index = [np.array([sc.cut.index for sc in s.scenes], dtype=np.int64) for s in strips]
    point_node, has, point_scene = [], [], []
    for s, sn, idx in zip(strips, scene_node, index, strict=True):
        pos, inside = _scene_of_points(s.scenes, s.gcps.line)
        point_node.append(sn[pos] if sn.size else pos)
        has.append(inside)
        point_scene.append(np.where(inside, idx[pos] if idx.size else -1, -1))
    return _Nodes(t_node, scene_node, index, point_node, has, point_scene)


@dataclass(eq=False)
class _Solution:
    """What the groups of a joint adjustment solve, filled group after group: per node its
    parameters, covariance, increments' σ and lost time; per strip its scenes' predicted
    and prior σ, its points' residuals before and after, normalised residuals and status;
    the χ² and degrees of freedom summed over the groups."""

    node_pass: NDArray[np.float64]
    node_scene: NDArray[np.float64]
    node_cov: NDArray[np.float64]
    node_inc: NDArray[np.float64]
    node_lost: NDArray[np.float64]
    predicted: list[NDArray[np.float64]]
    prior: list[NDArray[np.float64]]
    before: list[NDArray[np.float64]]
    after: list[NDArray[np.float64]]
    wres: list[NDArray[np.float64]]
    status: list[NDArray[np.object_]]
    chi2: float = 0.0
    dof: int = 0

    @classmethod
    def empty(cls, strips: list[Strip], n_nodes: int, has: list[NDArray[np.bool_]]) -> _Solution:
        return cls(
            np.zeros((n_nodes, _NP)),
            np.zeros((n_nodes, _NS)),
            np.zeros((n_nodes, _NP + _NS, _NP + _NS)),
            np.full((n_nodes, 3), np.inf),
            np.zeros(n_nodes),
            [np.zeros((len(s.scenes), 3)) for s in strips],
            [np.zeros((len(s.scenes), 3)) for s in strips],
            [np.full((len(s.gcps), 2), np.nan) for s in strips],
            [np.full((len(s.gcps), 2), np.nan) for s in strips],
            [np.full(len(s.gcps), np.nan) for s in strips],
            [np.where(h, "used", "outside").astype(object) for h in has],
        )


def _solve_group(
    strips: list[Strip],
    nodes: _Nodes,
    group: list[int],
    t_ref: float,
    options: ProcessingOptions,
    sol: _Solution,
) -> None:
    """Adjust the nodes of ``group`` together, their results into ``sol``."""
    uses = [h & np.isin(pn, group) for h, pn in zip(nodes.has, nodes.point_node, strict=True)]
    local = [np.searchsorted(group, pn) for pn in nodes.point_node]  # node within the group
    prob, lost = _problem(strips, uses, local, nodes.t_node[group], t_ref, options)
    ids = [np.flatnonzero(u) for u in uses]
    # the problem's points, strip after strip: where each strip's begin
    cut = np.cumsum([0] + [i.size for i in ids])
    f = prob.condition(np.zeros(prob.n_params))
    for k in range(len(strips)):
        sol.before[k][ids[k]] = f[cut[k] : cut[k + 1]]
    rows = prob.prior_rows
    prior_cov = np.linalg.inv(rows.T @ rows).astype(np.float64, copy=False)
    x, active, wr, cov, chi2_group = _fit(prob, cut[-1], prior_cov, options)
    sol.chi2, sol.dof = sol.chi2 + chi2_group, sol.dof + 2 * int(active.sum())
    f = prob.condition(x)
    for k in range(len(strips)):
        span = slice(cut[k], cut[k + 1])
        sol.after[k][ids[k]] = f[span]
        sol.wres[k][ids[k]] = wr[span]
        sol.status[k][ids[k][~active[span]]] = "rejected"
    pas, sce = prob.split(x)
    scale = np.r_[prob.sigma_pass, prob.sigma_scene]
    for jl, j in enumerate(group):
        sol.node_pass[j], sol.node_scene[j] = pas, sce[jl]
        sel = np.r_[np.arange(_NP), _NP + _NS * jl + np.arange(_NS)]
        sol.node_cov[j] = cov[np.ix_(sel, sel)] * np.outer(scale, scale)
    for k, s in enumerate(strips):
        mine = np.isin(nodes.scene_node[k], group)
        if mine.any():
            sub = Strip(
                s.pg, [sc for sc, m in zip(s.scenes, mine, strict=True) if m], s.gcps, s.band
            )
            sol.predicted[k][mine], sol.prior[k][mine] = _predicted(
                prob, sub, np.searchsorted(group, nodes.scene_node[k][mine]), x, [cov, prior_cov]
            )
    sol.node_inc[group], sol.node_lost[group] = prob.increment_sigma, lost


#: A block's iterations stop when the χ² drops by less than this, one unit: a step that
#: lowers it by less than one moves no combination of the unknowns by more than its σ. A
#: block tied by points has nearly flat directions (each pass's along-track bias against
#: its pitch, the tie points' heights at a small base-to-height ratio) along which the
#: iterations creep while nothing the data tell changes: stopped at 0.1 instead, the scenes'
#: errors against the truth move by less than 0.02 px (``benchmarks/bench_block.py``), for
#: a third more iterations.
BLOCK_CHI2_TOL = 1.0
#: Scale of a tie point's ground unknowns in the solution vector (m per unit): its
#: east, north and up corrections to the approximate position, on the scale of the
#: parameters' (scaled by their a priori σ).
TIE_SCALE_M = 100.0


@dataclass(frozen=True)
class _TieObservations:
    """One pass's measurements of tie points: their points (ground at the current
    estimate), tie index, whitening (image σ only: the ground is an unknown)."""

    points: _Points
    tie: NDArray[np.int64]
    whitening: NDArray[np.float64]


def _image_whitening(
    pg: PassGeometry, band: str, line: NDArray, col: NDArray, p: _Points, sigma_px: NDArray
) -> NDArray[np.float64]:
    """``L⁻¹`` of a tie measurement's condition covariance from its image σ alone."""
    a = _image_partials(pg, band, line, col, p)
    cov = np.einsum("nik,n,njk->nij", a, sigma_px**2, a)
    return np.linalg.inv(np.linalg.cholesky(cov))


def adjust_block(
    passes: list[list[Strip]],
    ties: list[list[ControlPointSet]],
    options: ProcessingOptions,
    dem: Any = None,
    dem_sigma_m: float = 10.0,
) -> list[tuple[Adjustment, ...]]:
    """Refine several passes over one ground together (ADRIN's blocks, paper ``001_…``,
    solved at once rather than strip after strip): each pass its own ephemeris and
    attitude corrections with their priors, as :func:`adjust_strips` (Westin); its control
    points; and the **tie points** (``kind = tie``, ``ties[p][s]`` the measurements in pass
    ``p``'s strip ``s``, the same id in every pass that saw the point), whose ground
    positions are unknowns: three per point (east, north, up of its approximate position),
    eliminated from the normal equations (the Schur complement, as a bundle adjustment
    does: their 3 × 3 blocks inverted one by one), so that a block of many scenes stays a
    problem in the passes' parameters alone.

    Solved by Levenberg–Marquardt on the reduced normal equations (its damping added to
    both blocks), until the χ² drops by less than ``BLOCK_CHI2_TOL``; the iterations are in
    ``timings_s``. The covariance of the passes' parameters is that of the reduced system,
    a priori (the budget trusted); each scene's predicted accuracy follows from it as in
    one pass. Tie points arrive from :mod:`levels.tiepoints`, blunders already refused there
    (left–right, y-parallax); Baarda's data snooping then rejects the tie points and the
    control points the block does not fit (:meth:`_Block.snoop`).

    The weakest direction of two passes tied by points alone is across the baseline:
    shifting one pass that way is nearly the same as raising every tie point by the shift
    over the base-to-height ratio (only the view angles' spread across the swaths tells
    them apart). Control points seen in both passes, with their heights, strengthen it; so
    does a ``dem`` (:class:`levels.geometry.dem.Dem`): each tie point's height observed as
    the DEM's under it, with ``dem_sigma_m`` (ADRIN's "secondary controls" were map points,
    heights and all). The tie points' own σ (``sigma_ground_m``, ``sigma_h_m`` of their
    files: loose) are priors on their ground.

    Returns each pass's :class:`Adjustment` per strip, mode ``block``.
    """
    t0 = time.perf_counter()
    if len(passes) != len(ties) or any(len(p) != len(t) for p, t in zip(passes, ties, strict=True)):
        raise GeometryError("adjust_block: one tie-point set per strip of every pass")
    block = _Block(passes, ties, options, dem, dem_sigma_m)
    z, r, j, cost, iterations = block.snoop()
    return block.adjustments(z, r, j, cost, iterations, t0)


@dataclass(frozen=True, eq=False)
class _PassSetup:
    """One pass of a block: its strips, their attitude nodes, its problem of control
    points and priors (as :func:`adjust_strips` builds it), the records lost, ``t_ref``."""

    strips: list[Strip]
    nodes: _Nodes
    prob: _Problem
    lost: NDArray[np.float64]
    t_ref: float

    @classmethod
    def of(cls, strips: list[Strip], options: ProcessingOptions) -> _PassSetup:
        nodes, t_ref = _pass_nodes(strips, "adjust_block: a pass without a scene")
        prob, lost = _problem(strips, nodes.has, nodes.point_node, nodes.t_node, t_ref, options)
        return cls(strips, nodes, prob, lost, t_ref)


@dataclass(frozen=True, eq=False)
class _TieUnknowns:
    """The block's tie points as unknowns: their ids, approximate ground (ECEF), its local
    east–north–up axes, and the rows of their priors (the files' ``sigma_ground_m``,
    ``sigma_h_m``: a tie point's are loose, 10 and 5 km from the matcher; they keep a point
    the images barely determine, at a small base-to-height ratio, well-posed)."""

    ids: list[str]
    where: dict[str, int]
    g0: NDArray[np.float64]
    enu0: NDArray[np.float64]  # (T, 3, 3) rows east, north, up
    prior: NDArray[np.float64]  # (3T,) TIE_SCALE_M / σ

    @classmethod
    def of(cls, ties: list[list[ControlPointSet]]) -> _TieUnknowns:
        sets = [t for pass_ties in ties for t in pass_ties]
        ids = sorted({i for t in sets for i in t.id})
        where = {i: k for k, i in enumerate(ids)}
        g_sum, g_n = np.zeros((len(ids), 3)), np.zeros(len(ids))
        sigma = np.full((len(ids), 3), np.inf)
        for t in sets:  # each id's ground the mean of its files', its σ the smallest
            k = np.array([where[i] for i in t.id], dtype=np.int64)
            np.add.at(g_sum, k, WGS84.to_ecef(t.lat_rad, t.lon_rad, t.h_m))
            np.add.at(g_n, k, 1.0)
            sig = np.stack([t.sigma_ground_m, t.sigma_ground_m, t.sigma_h_m], axis=1)
            sigma[k] = np.minimum(sigma[k], sig)
        g0 = g_sum / np.maximum(g_n, 1.0)[:, None]
        return cls(ids, where, g0, _local_axes(g0), (TIE_SCALE_M / sigma).ravel())

    def observations(
        self, setup: _PassSetup, pass_ties: list[ControlPointSet]
    ) -> _TieObservations | None:
        """One pass's measurements of the tie points inside its scenes (None: none)."""
        parts, whites, tie_of = [], [], []
        for strip, sn, t in zip(setup.strips, setup.nodes.scene_node, pass_ties, strict=True):
            pos, inside = _scene_of_points(strip.scenes, t.line)
            if not inside.any():
                continue
            k = np.array([self.where[i] for i in t.id], dtype=np.int64)[inside]
            line, col = t.line[inside], t.column[inside]
            p = _points(strip.pg, strip.band, line, col, self.g0[k], sn[pos[inside]])
            parts.append(p)
            whites.append(_image_whitening(strip.pg, strip.band, line, col, p, t.sigma_px[inside]))
            tie_of.append(k)
        if not parts:
            return None
        return _TieObservations(
            _Points.concatenate(parts), np.concatenate(tie_of), np.concatenate(whites)
        )


class _Block:
    """A block's least squares (:func:`adjust_block`): the unknowns (every pass's scaled
    parameters, then every tie point's east, north, up in ``TIE_SCALE_M``), the weighted
    residuals and their sparse Jacobian, the normal equations reduced to the parameters,
    Levenberg–Marquardt, and Baarda's data snooping; the tie and control points rejected
    so far weigh nothing."""

    def __init__(
        self,
        passes: list[list[Strip]],
        ties: list[list[ControlPointSet]],
        options: ProcessingOptions,
        dem: Any,
        dem_sigma_m: float,
    ) -> None:
        self.options, self.dem, self.dem_sigma_m = options, dem, dem_sigma_m
        self.setups = [_PassSetup.of(strips, options) for strips in passes]
        self.tu = _TieUnknowns.of(ties)
        self.observations = [
            self.tu.observations(s, t) for s, t in zip(self.setups, ties, strict=True)
        ]
        self.n_ties = n_ties = len(self.tu.ids)
        seen = np.zeros(n_ties, dtype=int)
        for obs in self.observations:
            if obs is not None:
                np.add.at(seen, obs.tie, 1)
        if n_ties and seen.min() < 2:
            raise GeometryError(
                f"adjust_block: {int(np.sum(seen < 2))} tie point(s) measured in fewer than "
                "two scenes of the block: a tie point ties at least two"
            )
        self.heights_known = np.zeros(n_ties, dtype=bool)
        if dem is not None and n_ties:
            lat0, lon0, _h0 = WGS84.to_geodetic(self.tu.g0)
            self.heights_known = np.isfinite(dem.heights(lat0, lon0))
        self.offsets = np.cumsum([0] + [s.prob.n_params for s in self.setups])
        self.nx = int(self.offsets[-1])
        self.n = self.nx + 3 * n_ties
        self.active = np.ones(n_ties, dtype=bool)  # tie points not rejected as blunders
        # each pass's control points not rejected (its problem holds only those inside)
        self.use_gcp = [np.ones(s.prob.points.t_s.size, dtype=bool) for s in self.setups]
        # where the rows of each pass's control points and tie points start
        self.gcp_rows: list[int] = []
        self.tie_rows: list[tuple[int, _TieObservations]] = []
        self._last: tuple[Any, Any] = (None, None)  # a Jacobian and its normal equations
        self._undamped: tuple[Any, Any] = (None, None)  # those equations and their reduction

    def ground(self, d: NDArray) -> NDArray:
        """The tie points' ECEF ground for their scaled unknowns ``d``."""
        return self.tu.g0 + TIE_SCALE_M * np.einsum("tij,ti->tj", self.tu.enu0, d.reshape(-1, 3))

    def _x(self, z: NDArray, p_idx: int) -> NDArray:
        return z[self.offsets[p_idx] : self.offsets[p_idx + 1]]

    def residuals_and_jacobian(
        self, z: NDArray, jac: bool
    ) -> tuple[NDArray, sparse.csr_matrix | None]:
        """The weighted residuals at ``z`` (each pass's control points and priors, then its
        tie points; the tie points' priors; their DEM heights) and, with ``jac``, their
        Jacobian; the rows' starts recorded for the tests."""
        nx, n = self.nx, self.n
        g = self.ground(z[nx:])
        res, blocks = [], []
        self.tie_rows.clear()
        self.gcp_rows.clear()
        row = 0
        for p_idx, (setup, obs) in enumerate(zip(self.setups, self.observations, strict=True)):
            x, use = self._x(z, p_idx), self.use_gcp[p_idx]
            self.gcp_rows.append(row)
            res.append(setup.prob.residuals(x, use))
            row += res[-1].size
            if jac:
                j = setup.prob.jacobian(x, use)
                left, right = self.offsets[p_idx], n - self.offsets[p_idx + 1]
                blocks.append(
                    sparse.hstack(
                        [
                            sparse.csr_matrix((j.shape[0], left)),
                            j,
                            sparse.csr_matrix((j.shape[0], right)),
                        ]
                    )
                )
            if obs is None:
                continue
            pts = dataclasses.replace(obs.points, g_ecef_m=g[obs.tie])
            on = self.active[obs.tie].astype(float)[:, None]  # a rejected point weighs nothing
            f0 = setup.prob.condition(x, pts)
            res.append((on * np.einsum("nij,nj->ni", obs.whitening, f0)).ravel())
            self.tie_rows.append((row, obs))
            row += res[-1].size
            if jac:
                blocks.append(self._tie_jacobian(p_idx, x, pts, obs, on))
        if self.n_ties:
            res.append(self.tu.prior * z[nx:])
            if jac:
                diag = nx + np.arange(3 * self.n_ties)
                blocks.append(
                    sparse.csr_matrix(
                        (self.tu.prior, (diag - nx, diag)), shape=(3 * self.n_ties, n)
                    )
                )
        if self.dem is not None and self.heights_known.any():
            hr, hj = self._dem_rows(g, jac)
            res.append(hr)
            if jac:
                blocks.append(hj)
        r = np.concatenate(res)
        return r, (sparse.vstack(blocks, format="csr") if jac else None)

    def _tie_jacobian(
        self, p_idx: int, x: NDArray, pts: _Points, obs: _TieObservations, on: NDArray
    ) -> sparse.csr_matrix:
        """A pass's tie rows' Jacobian: each measurement's two rows touch its pass's 6, its
        scene's 6 parameters and its point's 3 ground unknowns."""
        prob, m, start = self.setups[p_idx].prob, obs.tie.size, self.offsets[p_idx]
        jx = np.einsum("nij,njk->nik", obs.whitening, prob.parameter_jacobian(x, pts))
        jd = prob.ground_jacobian(x, pts, self.tu.enu0[obs.tie]) * TIE_SCALE_M
        jd = np.einsum("nij,njk->nik", obs.whitening, jd)
        cols = np.concatenate(
            [
                start + np.broadcast_to(np.arange(_NP), (m, _NP)),
                start + _NP + _NS * pts.scene[:, None] + np.arange(_NS),
                self.nx + 3 * obs.tie[:, None] + np.arange(3),
            ],
            axis=1,
        )  # (m, 15)
        vals = np.concatenate([jx, jd], axis=2) * on[:, :, None]  # (m, 2, 15)
        return sparse.csr_matrix(
            (
                vals.reshape(-1),
                np.repeat(cols[:, None, :], 2, axis=1).reshape(-1),
                np.arange(0, 2 * m * 15 + 1, 15),
            ),
            shape=(2 * m, self.n),
        )

    def _dem_rows(self, g: NDArray, jac: bool) -> tuple[NDArray, Any]:
        """Each tie point's height minus the DEM's under it, over ``dem_sigma_m``; the
        Jacobian by the point's up offset and the DEM's slope east and north."""
        dem, t = self.dem, np.flatnonzero(self.heights_known)
        lat, lon, h = WGS84.to_geodetic(g[t])
        h_dem = dem.heights(lat, lon)
        rows = np.nan_to_num((h - h_dem) / self.dem_sigma_m)
        if not jac:
            return rows, None
        slope = []
        for k in range(2):
            la, lo, _ = WGS84.to_geodetic(g[t] + _STEP_M * self.tu.enu0[t, k])
            slope.append((dem.heights(la, lo) - h_dem) / _STEP_M)
        vals = np.stack([-slope[0], -slope[1], np.ones(t.size)], axis=1)
        vals = np.nan_to_num(vals) * TIE_SCALE_M / self.dem_sigma_m
        cols = (self.nx + 3 * t[:, None] + np.arange(3)).ravel()
        m = sparse.csr_matrix(
            (vals.ravel(), (np.repeat(np.arange(t.size), 3), cols)), shape=(t.size, self.n)
        )
        return rows, m

    def normal_equations(
        self, j: sparse.csr_matrix, r: NDArray
    ) -> tuple[NDArray, Any, NDArray, NDArray]:
        """``JᵀJ`` in its parts: the parameters' block ``U`` (dense), their coupling with the
        ground unknowns ``W``, the ground unknowns' 3 × 3 diagonal blocks of ``V`` (it is
        block diagonal: every row's ground columns are one tie point's, so its blocks are
        sums of the rows' outer products, point by point), and the gradient ``−Jᵀr``; built
        once per Jacobian (the snooping's tests and the covariance reuse the last)."""
        if self._last[0] is j:
            return self._last[1]
        nx, n_ties = self.nx, self.n_ties
        jc = j.tocsc()
        jx, jd = jc[:, :nx], jc[:, nx:].tocoo()
        vb = np.zeros((n_ties, 3, 3))
        if n_ties:
            rows_d = np.zeros((j.shape[0], 3))
            rows_d[jd.row, jd.col % 3] = jd.data
            tie_of_row = np.full(j.shape[0], -1)
            tie_of_row[jd.row] = jd.col // 3
            on = tie_of_row >= 0
            outer = np.einsum("ri,rj->rij", rows_d[on], rows_d[on]).reshape(-1, 9)
            sums = [np.bincount(tie_of_row[on], outer[:, k], n_ties) for k in range(9)]
            vb = np.stack(sums, axis=1).astype(np.float64).reshape(n_ties, 3, 3)
        jxt = jx.T.tocsr()
        parts = ((jxt @ jx).toarray(), (jxt @ jd.tocsc()), vb, -(j.T @ r))
        self._last = (j, parts)
        return parts

    def reduced(
        self, parts: tuple[NDArray, Any, NDArray, NDArray], damping: float = 0.0
    ) -> tuple[NDArray, NDArray, NDArray, NDArray, Any]:
        """The normal equations with the ground unknowns eliminated (the Schur complement
        ``S = U − W V⁻¹ Wᵀ`` and its right-hand side), ``damping`` on the diagonal, and what
        recovers the ground steps: ``V``'s 3 × 3 blocks inverted, the ground part of the
        gradient, ``W``."""
        nx, n_ties = self.nx, self.n_ties
        u, w, vb, grad = parts
        vinv = np.linalg.inv(vb + damping * np.eye(3)) if n_ties else vb
        t3 = 3 * np.arange(n_ties)[:, None, None]
        i3, j3 = np.meshgrid(np.arange(3), np.arange(3), indexing="ij")
        vinv_sp = sparse.csr_matrix(
            (vinv.ravel(), ((t3 + i3).ravel(), (t3 + j3).ravel())), shape=(3 * n_ties,) * 2
        )
        wv = w @ vinv_sp
        schur = u + damping * np.eye(nx) - (wv @ w.T).toarray()
        b = grad[:nx] - wv @ grad[nx:]
        return schur, b, vinv, np.asarray(grad[nx:]), w

    def solve(self, z: NDArray) -> tuple[NDArray, NDArray, Any, float, int]:
        """Levenberg–Marquardt from ``z``: the solution, its residuals, Jacobian, cost and
        iterations."""
        r, j = self.residuals_and_jacobian(z, True)
        cost = float(r @ r)
        iterations = 0
        damping = 1e-3  # in the scaled unknowns' units
        for iterations in range(1, MAX_ITERATIONS + 1):  # noqa: B007 (reported)
            assert j is not None
            parts = self.normal_equations(j, r)
            for _ in range(MAX_HALVINGS):
                schur, b, vinv, gd, w = self.reduced(parts, damping)
                dx = cho_solve(cho_factor(schur), b)
                dd = np.einsum("tij,tj->ti", vinv, (gd - w.T @ dx).reshape(-1, 3)).ravel()
                step = np.r_[dx, dd]
                r_try, _ = self.residuals_and_jacobian(z + step, False)
                trial = float(r_try @ r_try)
                if trial <= cost * (1 + 1e-12) + 1e-12:
                    damping = max(damping / 4.0, 1e-9)
                    break
                damping *= 8.0
            else:
                break
            z, decrease, cost = z + step, cost - trial, trial
            r, j = self.residuals_and_jacobian(z, True)
            if np.max(np.abs(step)) < STEP_TOL or decrease <= max(COST_TOL * cost, BLOCK_CHI2_TOL):
                break
        return z, r, j, cost, iterations

    def reduced_at(self, j: Any, r: NDArray) -> tuple[NDArray, NDArray, NDArray, NDArray, Any]:
        """The undamped reduction of ``j``'s normal equations, once (the tests of a round
        and the covariance share it)."""
        parts = self.normal_equations(j, r)
        if self._undamped[0] is not parts:
            self._undamped = (parts, self.reduced(parts))
        return self._undamped[1]

    def tie_tests(self, r: NDArray, j: Any) -> NDArray[np.float64]:
        """Each tie point's largest normalised residual over its measurements (Baarda's
        ``|v| / σ_v``, the leverage of the point's own ground unknowns: ``J_d V⁻¹ J_dᵀ``);
        NaN for the rejected."""
        _s, _b, vinv, _g, _w = self.reduced_at(j, r)
        worst = np.full(self.n_ties, np.nan)
        for start, obs in self.tie_rows:
            m = obs.tie.size
            rows = start + np.arange(2 * m)
            sub = j[rows].tocoo()
            own = sub.col >= self.nx  # a tie row's three ground columns: its own point's
            jd = np.zeros((2 * m, 3))
            jd[sub.row[own], (sub.col[own] - self.nx) % 3] = sub.data[own]
            h = np.einsum("ri,rij,rj->r", jd, vinv[np.repeat(obs.tie, 2)], jd)
            w = np.abs(r[rows]) / np.sqrt(np.clip(1.0 - h, 1e-6, None))
            np.fmax.at(worst, obs.tie, w.reshape(m, 2).max(axis=1))
        worst[~self.active] = np.nan
        return worst

    def gcp_tests(self, r: NDArray, j: Any) -> list[NDArray[np.float64]]:
        """Each pass's control points' largest normalised residual (Baarda's, the leverage
        ``h = j S⁻¹ jᵀ`` of a row on the parameters alone: a control point has no ground
        unknown), NaN for the rejected and those outside."""
        schur, *_ = self.reduced_at(j, r)
        cov = None
        out = []
        for start, use in zip(self.gcp_rows, self.use_gcp, strict=True):
            worst = np.full(use.size, np.nan)
            m = int(use.sum())
            if m:
                if cov is None:
                    cov = np.linalg.inv(schur)
                rows = start + np.arange(2 * m)
                jr = j[rows][:, : self.nx].toarray()
                h = np.einsum("ri,ij,rj->r", jr, cov, jr)
                w = np.abs(r[rows]) / np.sqrt(np.clip(1.0 - h, 1e-6, None))
                worst[use] = w.reshape(m, 2).max(axis=1)
            out.append(worst)
        return out

    def snoop(self) -> tuple[NDArray, NDArray, Any, float, int]:
        """The solution with Baarda's data snooping: every tie point beyond
        ``blunder_threshold`` and the worst control point beyond it rejected each round,
        and the block solved again, until none is (more than ``MAX_REJECTED_SHARE`` of the
        tie points, or of a pass's control points, is refused)."""
        threshold = self.options.blunder_threshold
        z, r, j, cost, iterations = self.solve(np.zeros(self.n))
        for _ in range(MAX_SNOOPING_ROUNDS):
            bad = np.flatnonzero(np.nan_to_num(self.tie_tests(r, j)) > threshold)
            gcp_test = self.gcp_tests(r, j)
            worst_gcp = max(
                ((float(np.nanmax(t)), p) for p, t in enumerate(gcp_test) if np.isfinite(t).any()),
                default=(0.0, -1),
            )
            if worst_gcp[0] > threshold:  # the worst control point, one a round
                p_idx = worst_gcp[1]
                self.use_gcp[p_idx][int(np.nanargmax(gcp_test[p_idx]))] = False
            elif bad.size == 0:
                break
            self.active[bad] = False
            self._check_rejected()
            z, r, j, cost, more = self.solve(z)
            iterations += more
        return z, r, j, cost, iterations

    def _check_rejected(self) -> None:
        out, n_ties = int((~self.active).sum()), self.n_ties
        if out > MAX_REJECTED_SHARE * n_ties:
            raise AdjustmentError(
                f"level 2 of a block: {out} of {n_ties} tie points rejected "
                f"(more than {MAX_REJECTED_SHARE:.0%}): the tie points or their σ are wrong"
            )
        for use in self.use_gcp:
            if (~use).sum() > MAX_REJECTED_SHARE * use.size:
                raise AdjustmentError(
                    f"level 2 of a block: {int((~use).sum())} of a pass's {use.size} control "
                    f"points rejected (more than {MAX_REJECTED_SHARE:.0%}): the points' σ or "
                    "the model are wrong, not a few points: check them"
                )

    def adjustments(
        self, z: NDArray, r: NDArray, j: Any, cost: float, iterations: int, t0: float
    ) -> list[tuple[Adjustment, ...]]:
        """Each pass's :class:`Adjustment` per strip from the solution: the covariance of
        the reduced system, σ0 over the degrees of freedom left by the tie points' ground."""
        schur, *_ = self.reduced_at(j, r)
        cov_all = np.linalg.inv(schur)
        n_obs = sum(2 * int(use.sum()) for use in self.use_gcp)
        n_obs += sum(2 * int(self.active[o.tie].sum()) for o in self.observations if o is not None)
        n_obs += int(self.heights_known.sum()) if self.dem is not None else 0
        dof = n_obs - 3 * int(self.active.sum())
        sigma0 = float(np.sqrt(cost / dof)) if dof > 0 else float("nan")
        # the iterations are reported: where the tie points' lines of sight are nearly
        # parallel and no DEM holds their heights, they creep (docs/blocks.md)
        elapsed = {"adjust": time.perf_counter() - t0, "iterations": float(iterations)}
        ties_rejected = tuple(self.tu.ids[k] for k in np.flatnonzero(~self.active))
        out = []
        for p_idx, setup in enumerate(self.setups):
            span = slice(self.offsets[p_idx], self.offsets[p_idx + 1])
            out.append(
                _pass_adjustments(
                    setup,
                    self._x(z, p_idx),
                    cov_all[span, span],
                    self.use_gcp[p_idx],
                    sigma0,
                    elapsed,
                    ties_rejected,
                )
            )
        return out


def _pass_adjustments(
    setup: _PassSetup,
    x: NDArray,
    cov: NDArray,
    use: NDArray[np.bool_],
    sigma0: float,
    elapsed: dict[str, float],
    ties_rejected: tuple[str, ...],
) -> tuple[Adjustment, ...]:
    """One pass's :class:`Adjustment` per strip, mode ``block``: its parameters ``x``,
    their covariance ``cov``, its control points' residuals and status (``use``: those
    the snooping kept)."""
    strips, nodes, prob = setup.strips, setup.nodes, setup.prob
    rows = prob.prior_rows
    prior_cov = np.linalg.inv(rows.T @ rows).astype(np.float64, copy=False)
    pas, sce = prob.split(x)
    scale = np.r_[prob.sigma_pass, prob.sigma_scene]
    n_nodes = nodes.t_node.size
    node_cov = np.empty((n_nodes, _NP + _NS, _NP + _NS))
    for jn in range(n_nodes):
        sel = np.r_[np.arange(_NP), _NP + _NS * jn + np.arange(_NS)]
        node_cov[jn] = cov[np.ix_(sel, sel)] * np.outer(scale, scale)
    f_before = prob.condition(np.zeros(prob.n_params))
    f_after = prob.condition(x)
    cut = np.cumsum([0] + [int(h.sum()) for h in nodes.has])
    adjs: list[Adjustment] = []
    for si, st in enumerate(strips):
        has, mine = nodes.has[si], slice(cut[si], cut[si + 1])
        before = np.full((len(st.gcps), 2), np.nan)
        after = np.full((len(st.gcps), 2), np.nan)
        before[has], after[has] = f_before[mine], f_after[mine]
        status = np.where(has, "used", "outside").astype(object)
        status[np.flatnonzero(has)[~use[mine]]] = "rejected"
        sn = nodes.scene_node[si]
        predicted, prior = (
            _predicted(prob, st, sn, x, [cov, prior_cov])
            if st.scenes
            else (np.zeros((0, 3)), np.zeros((0, 3)))
        )
        adjs.append(
            Adjustment(
                "block",
                setup.t_ref,
                nodes.index[si],
                nodes.t_node[sn],
                np.broadcast_to(pas, (sn.size, _NP)).copy(),
                sce[sn],
                node_cov[sn],
                predicted,
                prior,
                prob.increment_sigma[sn],
                setup.lost[sn],
                tuple(st.gcps.id),
                nodes.point_scene[si],
                tuple(str(v) for v in status),
                before,
                after,
                np.full(len(st.gcps), np.nan),
                sigma0,
                elapsed,
                ties_rejected,
            )
        )
    return tuple(adjs)
