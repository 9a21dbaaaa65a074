"""GEO on a synthetic pass, ``levels`` alone (``_orbits.synthetic_pass``: a Keplerian orbit,
the HRV's pitch and CCD butting): INPE's polynomials, scene cutting, the 1B polynomials'
error, the direct grid at the buttings, INPE's exact 61 × 61 grid against the default.
GEO against the emulated truth, and the facts of a pass over Cuiabá, are
``tests/test_geo.py``'s."""

from __future__ import annotations

import numpy as np
import pytest
from _orbits import synthetic_pass

from levels.errors import GeometryError
from levels.geo.level1b import level1b_geometry
from levels.geo.level2a import butting_columns, level2a_geometry, map_crs
from levels.geo.polynomial import Poly1D, Poly2D
from levels.geo.scenes import cut_scenes

#: The issue's bound on the 2A inverse from the four nearest direct-grid points.
MAX_INVERSE_PX = 0.05
H_REF_M = 450.0
#: The normal equations against QR on a direct-grid-like design (condition number ~125):
#: cond² · ε ≈ 2e-12 relative, on lines of thousands of pixels.
NORMAL_EQUATIONS_TOL_PX = 1e-7
#: The largest butting step (7 µrad between the second and third CCDs) over the 10 m pixel
#: from 822 km: what a grid blind to the buttings misses at most.
BUTTING_STEP_PX = 7e-6 * 822e3 / 10.0


def _scene(mirror_step: int) -> tuple:
    _pg, scene, res = synthetic_pass(6000, 6000, mirror_step=mirror_step)
    return None, scene, res


@pytest.fixture(scope="module")
def nadir():
    return _scene(48)


@pytest.fixture(scope="module")
def tilted():
    return _scene(93)  # 27°


def test_polynomials_fit_and_invert() -> None:
    x = np.linspace(-50.0, 7000.0, 61)
    p = Poly1D.fit(x, 3.0 + 0.9 * x + 2e-6 * x**2 - 1e-10 * x**3, 3)
    y = p(x)
    assert p.solve(y, x + 5.0) == pytest.approx(x, abs=1e-9)
    assert Poly1D.from_array(p.as_array())(x) == pytest.approx(y, abs=1e-9)
    i, j = np.meshgrid(np.linspace(0, 7000, 30), np.linspace(0, 6000, 30))
    z = 1.0 + 0.5 * i - 0.2 * j + 1e-8 * i * j**2
    assert Poly2D.fit(i, j, z, 3)(i, j) == pytest.approx(z, abs=1e-6)


def test_poly2d_normal_equations_agree_with_qr() -> None:
    i, j = np.meshgrid(np.linspace(-30, 7200, 67), np.linspace(10, 6900, 74))
    z = 3000.0 + 0.9 * i - 0.3 * j + 2e-5 * i * j - 1e-9 * i**3 + 1e-16 * j**5
    fits = Poly2D.fit_orders(i, j, z, (3, 4, 5))
    for order, p in fits.items():
        design = p._design(i.ravel(), j.ravel())
        ref = np.linalg.lstsq(design, z.ravel(), rcond=None)[0]
        assert p(i, j).ravel() == pytest.approx(design @ ref, abs=NORMAL_EQUATIONS_TOL_PX), order


@pytest.mark.parametrize("spread", [0.1, 1e-3])
def test_poly2d_falls_back_to_qr_on_an_ill_conditioned_design(monkeypatch, spread) -> None:
    """Breakpoints bunched in a corner but one: the design's condition number is 2e8
    (Cholesky succeeds, R's diagonal says no) or 3e17 (Cholesky fails); QR answers."""
    from levels.geo import polynomial

    rng = np.random.default_rng(0)
    x = np.append(spread * rng.random(40), 1.0)
    y = np.append(spread * rng.random(40), 1.0)
    design = Poly2D(np.zeros(21), 5, (0.5, 0.5), (0.5, 0.5))._design(x, y)
    assert np.linalg.cond(design) > polynomial._NORMAL_EQUATIONS_MAX_COND
    calls = []
    qr = np.linalg.qr
    monkeypatch.setattr(np.linalg, "qr", lambda *a, **k: calls.append(1) or qr(*a, **k))
    p = Poly2D.fit(x, y, x + 2 * y, 5)
    assert calls
    assert p(x, y) == pytest.approx(x + 2 * y, abs=1e-6)


def test_scene_cutting() -> None:
    cuts = cut_scenes(20000, 6000, 500)
    assert [c.first_line for c in cuts] == [0, 5500, 11000]
    assert all(c.n_lines == 6000 for c in cuts)
    assert cut_scenes(300, 6000)[0].n_lines == 300  # a short pass is one scene
    with pytest.raises(GeometryError, match="overlap_lines"):
        cut_scenes(20000, 6000, 6000)


@pytest.mark.parametrize("case", ["nadir", "tilted"])
def test_1b_polynomial_errors_are_measured(case, request) -> None:
    _acq, scene, res = request.getfixturevalue(case)
    err = level1b_geometry(scene, res).approximation_error(scene.model)
    # INPE's one-dimensional cubics: under a pixel at nadir, a few pixels at 27°
    # (measured 0.88 and 2.19 px max); the bound only guards against a broken fit
    assert err["n_points"] > 1000
    assert 0.0 < err["max_px"] < (1.5 if case == "nadir" else 4.0)


def test_direct_grid_holds_both_sides_of_each_butting(nadir) -> None:
    _acq, scene, _res = nadir
    cols = butting_columns(scene.model.look_angles)
    assert cols.tolist() == [1499.0, 1500.0, 2999.0, 3000.0, 4499.0, 4500.0]


def test_inpe_exact_61_by_61_grid_is_measured(nadir) -> None:
    """INPE's exact configuration (61 × 61 regular breakpoints, one line field) beside the
    default (rows at the attitude samples, columns at the buttings): it misses the butting
    jumps by up to about half a step, the default stays within a twentieth of a pixel."""
    _acq, scene, res = nadir
    crs = map_crs("utm", scene.centre_lat_rad, scene.centre_lon_rad)
    inpe = level2a_geometry(scene, res, crs, grid_rows="regular", grid_columns="regular")
    assert inpe.grid_i.shape == (61, 61) and inpe.segment_first_column.tolist() == [0.0]
    default = level2a_geometry(scene, res, crs)
    e_inpe = inpe.approximation_error(scene.model, H_REF_M)["max_px"]
    e_default = default.approximation_error(scene.model, H_REF_M)["max_px"]
    assert e_default <= MAX_INVERSE_PX < e_inpe <= BUTTING_STEP_PX
