"""GEO's 2A geometry on full P scenes of a synthetic pass (``_orbits.synthetic_pass``:
6000 × 6000, nadir and 27°), without the emulator: the inverse grid from the four nearest
direct-grid points within a twentieth of a pixel of the model, and the grid's arithmetic
and COR's kernel's (raw → output → raw) the same to a micro-pixel."""

from __future__ import annotations

import numpy as np
import pytest
from _orbits import synthetic_pass

from levels.geo.level2a import level2a_geometry, map_crs

#: Issue 5's bound on the 2A inverse from the four nearest direct-grid points (px).
MAX_INVERSE_PX = 0.05
#: The grid's raw → output and the kernel's output → raw, one after the other (px).
ROUND_TRIP_PX = 1e-6
H_REF_M = 450.0


@pytest.fixture(scope="module", params=[48, 93], ids=["nadir", "27deg"])
def scene_2a(request) -> tuple:
    _pg, scene, res = synthetic_pass(6000, 6000, request.param, H_REF_M)
    crs = map_crs("utm", scene.centre_lat_rad, scene.centre_lon_rad)
    return scene, level2a_geometry(scene, res, crs)


def test_2a_four_nearest_inverse_within_a_twentieth_of_a_pixel(scene_2a) -> None:
    scene, g = scene_2a
    assert g.approximation_error(scene.model, H_REF_M, "nearest4")["max_px"] <= MAX_INVERSE_PX


def test_2a_grid_and_kernel_arithmetic_agree(scene_2a) -> None:
    _scene, g = scene_2a
    i, j = np.meshgrid(
        np.arange(0, g.map_grid.n_rows, 997.0), np.arange(0, g.map_grid.n_cols, 991.0)
    )
    line, col = g.raw_of(i.ravel(), j.ravel())
    ii, jj = g.output_of(line, col, (i.ravel() + 3.0, j.ravel() - 2.0))
    assert ii == pytest.approx(i.ravel(), abs=ROUND_TRIP_PX)
    assert jj == pytest.approx(j.ravel(), abs=ROUND_TRIP_PX)
