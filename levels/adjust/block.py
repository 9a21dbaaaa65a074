"""A block of passes (:func:`adjust_block`): each pass's parameters, the tie points' ground as
unknowns, every pass's control points carried across by the tie points.
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray
from scipy import sparse
from scipy.linalg import cho_factor, cho_solve

from levels.adjust.model import (
    _NP,
    _NS,
    _STEP_M,
    MAX_REJECTED_SHARE,
    MAX_SNOOPING_ROUNDS,
    Adjustment,
    Strip,
    _image_partials,
    _local_axes,
    _Points,
    _points,
    _Problem,
    _problem,
    _scene_of_points,
)
from levels.adjust.passes import _Nodes, _pass_nodes
from levels.adjust.solve import COST_TOL, MAX_HALVINGS, MAX_ITERATIONS, STEP_TOL, _predicted
from levels.errors import AdjustmentError, GeometryError
from levels.geo.scenes import PassGeometry
from levels.geometry.ellipsoid import WGS84
from levels.options import ProcessingOptions
from levels.readers.gcp import ControlPointSet

if TYPE_CHECKING:
    from levels.geometry.dem import Dem

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
    dem: Dem | None = None,
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
        dem: Dem | None,
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
        assert dem is not None  # rows of the DEM only when one is given
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
