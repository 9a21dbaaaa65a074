"""8-point Lagrange interpolation against exact orbits."""

from __future__ import annotations

import numpy as np
import pytest
from _orbits import ecef_states, j2_eci, kepler_eci

from levels.errors import GeometryError
from levels.geometry import Ephemeris, EphemerisSpacingWarning

#: The issue's bar: interpolation error below 1 mm at 60 s spacing.
LAGRANGE_TOL_M = 1e-3
#: Velocity error matching 1 mm over a few seconds.
LAGRANGE_TOL_M_PER_S = 1e-5


def _errors(states, step_s: float, n_samples: int = 11, eci: bool = False):
    t_nodes = np.arange(n_samples) * step_s
    t = np.linspace(0.0, t_nodes[-1], 2001)
    r_nodes, v_nodes = states(t_nodes)
    r_true, v_true = states(t)
    r, v = Ephemeris(t_nodes, r_nodes, v_nodes).interpolate(t)
    return np.linalg.norm(r - r_true, axis=1), np.linalg.norm(v - v_true, axis=1)


def test_keplerian_orbit_in_ecef_to_a_millimetre_at_60_s() -> None:
    dr, dv = _errors(ecef_states, 60.0)
    assert dr.max() < LAGRANGE_TOL_M
    assert dv.max() < LAGRANGE_TOL_M_PER_S


def test_j2_orbit_to_a_millimetre_at_60_s() -> None:
    r0, v0 = kepler_eci(0.0)

    def states(t):
        # Integrate once over the sorted instants (solve_ivp wants t_eval in order).
        order = np.argsort(t)
        r, v = j2_eci(np.asarray(t, dtype=float)[order], r0[0], v0[0])
        out_r, out_v = np.empty_like(r), np.empty_like(v)
        out_r[order], out_v[order] = r, v
        return out_r, out_v

    dr, _ = _errors(states, 60.0)
    assert dr.max() < LAGRANGE_TOL_M


def test_nodes_are_reproduced_and_ends_fall_back_one_sided() -> None:
    t_nodes = np.arange(11) * 60.0
    r, v = ecef_states(t_nodes)
    eph = Ephemeris(t_nodes, r, v)
    ri, vi = eph.interpolate(t_nodes)
    assert np.abs(ri - r).max() < 1e-6 and np.abs(vi - v).max() < 1e-9
    # Near the first node the window is shifted inwards: still far below a millimetre.
    t = np.array([1.0, 599.0])
    assert np.abs(eph.interpolate(t)[0] - ecef_states(t)[0]).max() < LAGRANGE_TOL_M


def test_coarse_spacing_degrades_as_expected() -> None:
    """An 8-point interpolant is 8th order: 4× the spacing costs about 4⁸ in error."""
    fine, _ = _errors(ecef_states, 30.0, n_samples=21)
    coarse, _ = _errors(ecef_states, 120.0, n_samples=11)
    assert coarse.max() > 1000 * fine.max()


def test_fewer_than_eight_samples_use_all_of_them() -> None:
    t_nodes = np.arange(5) * 30.0
    r, v = ecef_states(t_nodes)
    t = np.array([45.0])
    ri, _ = Ephemeris(t_nodes, r, v).interpolate(t)
    assert np.abs(ri - ecef_states(t)[0]).max() < 0.05  # 4th-degree over 2 min: centimetres


def test_outside_the_span_is_nan_not_extrapolated() -> None:
    t_nodes = np.arange(8) * 60.0
    eph = Ephemeris(t_nodes, *ecef_states(t_nodes))
    r, _ = eph.interpolate(np.array([-0.1, 200.0, 420.1]))
    assert np.isnan(r[[0, 2]]).all() and np.isfinite(r[1]).all()


def test_uneven_spacing_warns() -> None:
    t_nodes = np.array([0, 60, 120, 185, 240, 300, 360, 420.0])
    with pytest.warns(EphemerisSpacingWarning, match="uneven"):
        Ephemeris(t_nodes, *ecef_states(t_nodes))


@pytest.mark.parametrize(
    ("t", "r", "match"),
    [
        (np.array([0.0, 60.0, 60.0]), np.zeros((3, 3)), "increase strictly"),
        (np.array([0.0, 60.0, 120.0]), np.zeros((2, 3)), "sizes differ"),
        (np.array([0.0]), np.zeros((1, 3)), "at least 2"),
    ],
)
def test_bad_ephemeris_is_rejected(t, r, match) -> None:
    with pytest.raises(GeometryError, match=match):
        Ephemeris(t, r, np.zeros_like(r))
