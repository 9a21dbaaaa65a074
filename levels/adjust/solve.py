"""Solving the adjustment: Gauss–Newton on the sparse normal equations, the robust first fit,
Baarda's data snooping, and the accuracy the covariance predicts at each scene.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy import sparse
from scipy.linalg import cho_factor, cho_solve

from levels.adjust.model import (
    _NP,
    _NS,
    _STEP_M,
    MAX_SNOOPING_ROUNDS,
    PREDICTION_LATTICE,
    REACH_SIGMAS,
    ROBUST_SCALE,
    Strip,
    _local_axes,
    _points,
    _Problem,
    shared_sigma_m,
)
from levels.geometry.ellipsoid import WGS84
from levels.options import ProcessingOptions

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
    reference surface, through the covariance (all scenes at once). The first covariance
    is the solution's: to it are added the attitude's error between gyro records (as an
    error of the scene's attitude offsets: every line has its own, which no parameter takes
    off; :func:`~levels.geometry.attitude.interpolation_sigma_rad`) and, on each axis, the
    ground error its control points share (:func:`~levels.adjust.model.shared_sigma_m`: a
    reference ortho-image's bias moves the refined model with it, whatever the number of
    points)."""
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
    out: list[NDArray[np.float64]] = []
    floor = np.zeros(_NP + _NS)  # the attitude between gyro records, on the solution's
    floor[_NP : _NP + 3] = (prob.attitude_floor_rad / prob.sigma_scene[:3]) ** 2  # scaled
    for k_cov, cov in enumerate(covariances):
        solution = k_cov == 0  # the solution's; the priors' after it
        c = cov[sel[:, :, None], sel[:, None, :]]  # (n, 12, 12)
        if solution:
            c = c + np.diag(floor)
        cg = np.einsum("nik,nkl,njl->nij", move, c, move)
        var = np.stack([cg[:, 0, 0], cg[:, 1, 1]], axis=-1)
        per = np.zeros((len(strip.scenes), 3))
        for k in range(2):
            per[:, k] = np.bincount(which, var[:, k], len(strip.scenes)) / m**2
        if solution:
            per[:, :2] += shared_sigma_m(strip.gcps) ** 2
        per[:, 2] = per[:, 0] + per[:, 1]
        out.append(np.sqrt(per))
    return out
