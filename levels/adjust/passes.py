"""A pass's adjustment (Westin): one HRV's scenes (:func:`adjust`), or a twin pass's HRVs on
their common platform (:func:`adjust_strips`), the fit judged before anything is made of it.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from levels.adjust.model import (
    _NP,
    _NS,
    MAX_REJECTED_SHARE,
    REACH_SIGMAS,
    Adjustment,
    Strip,
    _problem,
    _scene_of_points,
)
from levels.adjust.solve import _fit, _predicted
from levels.errors import AdjustmentError, FitRefused, GeometryError
from levels.geo.scenes import PassGeometry, SceneGeometry
from levels.options import ProcessingOptions
from levels.readers.gcp import ControlPointSet

_log = logging.getLogger(__name__)


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
    say_refused(ids, status, np.concatenate(sol.before) if sol.before else None)
    if not sol.dof:
        return
    limit = float(chi2_law.ppf(confidence, sol.dof))
    if sol.chi2 <= limit:
        return
    wres = np.concatenate(sol.wres)
    used = np.flatnonzero(status == "used")
    worst = used[np.argsort(-np.nan_to_num(wres[used]))][:3]
    sigma0 = float(np.sqrt(sol.chi2 / sol.dof))
    raise FitRefused(
        f"level 2: the fit fails its χ² test: σ0 {sigma0:.2f} beyond "
        f"{np.sqrt(limit / sol.dof):.2f} ({confidence:.1%} for {sol.dof} degrees of "
        "freedom); the points do not fit the model within their σ: worst "
        + ", ".join(f"{ids[k]} ({wres[k]:.1f}σ)" for k in worst)
        + "; check the points and their σ (or [processing] fit_confidence)",
        sigma0,
    )


def say_refused(ids: list[str], status: NDArray[Any], before: NDArray[Any] | None) -> None:
    """One console line (a warning) per control point the fit did not use: rejected as a
    blunder, or out of the model's reach; with how far the model before the fit missed it.
    A caller that adjusts the same points several times (``levels.reference``'s loop)
    silences this module's logger and says the last fit's once."""
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
