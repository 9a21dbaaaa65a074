"""The adjustment's model (the package docstring maps Westin's equations): the pass's and
each scene's parameters, the control points as observations of the collinearity condition
(eqs. 7–9), the problem's partials and weights (eq. 20), the result (:class:`Adjustment`)
and a strip of scenes (:class:`Strip`).
"""

from __future__ import annotations

import functools
import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, fields
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy import sparse

from levels.errors import GeometryError
from levels.geo.scenes import PassGeometry, SceneGeometry
from levels.geometry import collinearity
from levels.geometry.attitude import (
    SampledAttitude,
    attitude_gaps,
    interpolation_sigma_rad,
    westin_variogram_rad2,
)
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
#: Finite-difference steps: parameters (in a priori σ), image (px), ground (m), attitude
#: (rad).
_STEP_X, _STEP_PX, _STEP_M, _STEP_ATT_RAD = 1e-3, 0.05, 1.0, 1e-6
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
    #: The attitude's error between gyro records (rad; roll, pitch, yaw): its drift
    #: between them (:func:`~levels.geometry.attitude.interpolation_sigma_rad`) and its
    #: jitter (``attitude_jitter_rad``); no parameter takes it off.
    attitude_floor_rad: NDArray[np.float64] = field(default_factory=lambda: np.zeros(3))

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

    def summary(self) -> dict[str, object]:
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

    def product_tree(self, index: int) -> dict[str, object]:
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

    @classmethod
    def from_trees(cls, scenes: Sequence[tuple[int, Mapping[str, Any]]]) -> Adjustment:
        """The adjustment again from the ``geometry/adjustment`` trees of its scenes' level
        2 products (:meth:`product_tree`; ``(scene index, tree)`` each), as a step taken
        from a directory takes it: every figure but the priors' east and north σ (not
        written: NaN) and the time it took (none here). Trees of different adjustments
        are refused."""
        if not scenes:
            raise GeometryError("no level 2 product to take the adjustment from")
        order = sorted(scenes, key=lambda s: s[0])
        first = order[0][1]
        points = first["points"]
        for index, tree in order:
            if str(tree["mode"]) != str(first["mode"]) or _listed(tree["points"]["id"]) != (
                _listed(points["id"])
            ):
                raise GeometryError(
                    f"scene {index}'s level 2 is of another adjustment than scene {order[0][0]}'s"
                )

        def stacked(key: str) -> NDArray[np.float64]:
            return np.stack([np.asarray(t[key], dtype=np.float64) for _, t in order])

        sigma = [t["predicted_sigma_m"] for _, t in order]
        nan = np.full(len(order), np.nan)
        return cls(
            mode=str(first["mode"]),
            t_ref_s=float(first["t_ref_s"]),
            scene_index=np.array([i for i, _ in order], dtype=np.int64),
            t_centre_s=stacked("t_centre_s"),
            pass_parameters=stacked("pass_parameters"),
            scene_parameters=stacked("scene_parameters"),
            covariance=stacked("covariance"),
            predicted_sigma_m=np.array([[s["east"], s["north"], s["horizontal"]] for s in sigma]),
            prior_sigma_m=np.stack([nan, nan, [s["prior_horizontal"] for s in sigma]], axis=1),
            increment_sigma_rad=stacked("attitude_jump_sigma_rad"),
            gap_s=stacked("attitude_gap_s"),
            point_id=tuple(_listed(points["id"])),
            point_scene=np.asarray(points["scene"], dtype=np.int64),
            point_status=tuple(_listed(points["status"])),
            residual_before_px=np.asarray(points["residual_before_px"], dtype=np.float64),
            residual_after_px=np.asarray(points["residual_after_px"], dtype=np.float64),
            normalised_residual=np.asarray(points["normalised_residual"], dtype=np.float64),
            sigma0=float(first["sigma0"]),
            timings_s={"adjust": 0.0},  # taken, not solved
            ties_rejected=tuple(_listed(first.get("ties_rejected", []))),
        )


def _listed(value: object) -> list[str]:
    """A list of names as written (a JSON array in an attribute) or as made."""
    if isinstance(value, str | bytes):
        return [str(v) for v in json.loads(value)]
    return [str(v) for v in value]  # type: ignore[attr-defined]


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


#: A control point found on a reference ortho-image (kind ``reference``) shares its
#: ``sigma_ground_m`` with every other (the reference's own geolocation error: a bias of its
#: whole grid, GRI's 8 m CE95, which no number of points averages out): each is weighed
#: with at most this of its own on the ground (m; the reference's pixels among themselves),
#: and the shared part is added once to the predicted accuracy (:func:`shared_sigma_m`).
REFERENCE_OWN_SIGMA_M = 0.5


def shared_sigma_m(gcps: ControlPointSet) -> float:
    """The ground error (1σ per axis, m) every point of the set shares: the largest
    ``sigma_ground_m`` of its reference points (one reference's stated accuracy), beyond
    what each is weighed with alone (``REFERENCE_OWN_SIGMA_M``); 0 without any."""
    assert gcps.reference is not None
    if not gcps.reference.any():
        return 0.0
    s = float(np.max(gcps.sigma_ground_m[gcps.reference]))
    return float(np.sqrt(max(s * s - REFERENCE_OWN_SIGMA_M**2, 0.0)))


def _whitening(
    pg: PassGeometry,
    band: str,
    gcps: ControlPointSet,
    use: NDArray[np.bool_],
    p: _Points,
    attitude_floor_rad: NDArray[np.float64],
) -> NDArray[np.float64]:
    """``L⁻¹`` of every point's condition covariance ``A Q Aᵀ`` (eq. 20), ``(N, 2, 2)``:
    its image and ground σ, and the attitude's between gyro records (each point sees the
    attitude of its own line, which the model's offsets and rates cannot follow)."""
    zero = np.zeros((p.t_s.size, 3))
    f0 = _condition(p, zero, zero, zero)
    line, col = gcps.line[use], gcps.column[use]
    cols = list(np.moveaxis(_image_partials(pg, band, line, col, p), -1, 0))
    enu = _local_axes(p.g_ecef_m)
    for k in range(3):
        q = _points(pg, band, line, col, p.g_ecef_m + _STEP_M * enu[:, k], p.scene)
        cols.append((_condition(q, zero, zero, zero) - f0) / _STEP_M)
    for k in range(3):  # the condition per radian of roll, pitch, yaw
        d_att = np.zeros((p.t_s.size, 3))
        d_att[:, k] = _STEP_ATT_RAD
        cols.append((_condition(p, zero, zero, d_att) - f0) / _STEP_ATT_RAD)
    a = np.stack(cols, axis=-1)  # (N, 2, 8): line, column, east, north, up, roll, pitch, yaw
    sg, sh, sp = gcps.sigma_ground_m[use], gcps.sigma_h_m[use], gcps.sigma_px[use]
    assert gcps.reference is not None
    sg = np.where(gcps.reference[use], np.minimum(sg, REFERENCE_OWN_SIGMA_M), sg)
    att = np.broadcast_to(attitude_floor_rad**2, (sp.size, 3))
    q_diag = np.concatenate([np.stack([sp**2, sp**2, sg**2, sg**2, sh**2], axis=-1), att], axis=1)
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
    att = strips[0].pg.attitude  # every strip's: checked by adjust_strips
    period = float(np.median(np.diff(att.t_s)))
    floor = np.hypot(
        interpolation_sigma_rad(period, options.variogram_scale), options.attitude_jitter_rad
    )
    parts, white = [], []
    for s, use, node in zip(strips, uses, nodes, strict=True):
        g = WGS84.to_ecef(s.gcps.lat_rad[use], s.gcps.lon_rad[use], s.gcps.h_m[use])
        p = _points(s.pg, s.band, s.gcps.line[use], s.gcps.column[use], g, node[use])
        parts.append(p)
        white.append(_whitening(s.pg, s.band, s.gcps, use, p, floor))
    inc, lost = _increment_sigma(attitude_gaps(att.t_s), t_node_s, period, options)
    prob = _Problem(
        _Points.concatenate(parts),
        np.concatenate(white),
        t_ref_s,
        t_node_s,
        np.r_[options.prior_ephemeris_m, options.prior_ephemeris_drift_m_per_s],
        np.r_[options.prior_attitude_rad, [options.prior_attitude_rate_rad_per_s] * 3],
        inc,
        floor,
    )
    return prob, lost


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
