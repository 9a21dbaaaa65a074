"""The adjustments' collinearity kernels against the numpy reference they replace."""

from __future__ import annotations

import dataclasses

import numpy as np
from _orbits import synthetic_gcps, synthetic_pass

import levels.adjust.model as la
from levels.adjust.passes import _nodes
from levels.options import ProcessingOptions

#: Kernel against numpy, same formulas in another order of operations: the condition in
#: pixels agrees to round-off (1e-16 of angles of 0.1 rad over a 1.2e-5 rad pitch, ~1e-12,
#: times the 830 km lever of the frame's rebuilding: 1e-10 px).
CONDITION_TOL_PX = 1e-9
#: The Jacobian is a central difference of ±1e-3 σ: round-off of 1e-10 px over a step of
#: 2e-3 gives 5e-8 of a partial.
JACOBIAN_TOL = 1e-6


def _problem():
    pg, scene, _res = synthetic_pass(n_lines=6000, n_detectors=6000)
    scenes = [scene]
    strips = [la.Strip(pg, scenes, synthetic_gcps(scene, 40))]
    nodes = _nodes(strips)
    t_ref = float(np.mean(pg.line_t_s[[0, -1]]))
    prob, _lost = la._problem(
        strips, nodes.has, nodes.point_node, nodes.t_node, t_ref, ProcessingOptions()
    )
    return prob


def test_kernels_reproduce_the_numpy_condition_and_its_partials() -> None:
    prob = _problem()
    p = prob.points
    x = np.random.default_rng(0).standard_normal(prob.n_params) * 3.0  # 3σ corrections
    corr = prob.corrections(x, p)
    assert np.max(np.abs(la._condition(p, *corr) - la._condition_numpy(p, *corr))) < (
        CONDITION_TOL_PX
    )
    reference = np.empty((p.t_s.size, 2, 12))
    for k in range(12):  # the former Jacobian: each parameter stepped in numpy
        step = np.zeros_like(x)
        step[k if k < 6 else slice(k, None, 6)] = la._STEP_X
        f = [la._condition_numpy(p, *prob.corrections(x + s * step, p)) for s in (1, -1)]
        reference[:, :, k] = (f[0] - f[1]) / (2 * la._STEP_X)
    got = prob.parameter_jacobian(x, p)
    assert np.max(np.abs(got - reference)) < JACOBIAN_TOL * np.max(np.abs(reference))
    enu = la._local_axes(p.g_ecef_m)
    ground = prob.ground_jacobian(x, p, enu)
    f0 = la._condition_numpy(p, *corr)
    for k in range(3):
        moved = dataclasses.replace(p, g_ecef_m=p.g_ecef_m + la._STEP_M * enu[:, k])
        ref = (la._condition_numpy(moved, *corr) - f0) / la._STEP_M
        assert np.max(np.abs(ground[:, :, k] - ref)) < JACOBIAN_TOL * np.max(np.abs(ref))
