"""The steps a plan takes instead of making them, and the scenes it is asked for: level 2's
adjustment written into its scenes' products and read back (:meth:`levels.adjust.
Adjustment.from_trees`) is the adjustment solved, array for array; trees of two adjustments
are refused; a request of some scenes makes those alone (``levels.work.Request.scenes``,
what the live front end asks of each scene as its lines come in)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from _synthetic import true_pass

from levels.adjust import Adjustment, adjust
from levels.errors import GeometryError
from levels.options import ProcessingOptions
from levels.readers.l0 import read_l0
from levels.warmup import WARM_UP_ARCHIVE
from levels.work import Pass, Request, Step, plan, run

#: The figures the products do not carry (the priors' east and north σ; the solve's time).
NOT_WRITTEN = {"prior_sigma_m", "timings_s"}


@pytest.fixture(scope="module")
def solved() -> Adjustment:
    """Three full P scenes of a synthetic pass adjusted on 16 points, one a blunder."""
    tp = true_pass(n_lines=3 * 6000, seed=11)
    points, _ = tp.gcps(16, 11, blunder_fraction=0.07, blunder_m=300.0)
    return adjust(tp.geo, tp.scenes(6000), points, ProcessingOptions())


def test_an_adjustment_read_back_from_its_scenes_trees_is_the_one_solved(
    solved: Adjustment,
) -> None:
    trees = [(int(k), solved.product_tree(int(k))) for k in solved.scene_index]
    back = Adjustment.from_trees(trees[::-1])  # in any order: by scene
    for f in dataclasses.fields(Adjustment):
        if f.name in NOT_WRITTEN:
            continue
        a, b = getattr(solved, f.name), getattr(back, f.name)
        if isinstance(a, np.ndarray):
            assert np.array_equal(a, b, equal_nan=True), f.name
        else:
            assert tuple(a) == tuple(b) if isinstance(a, tuple) else a == b, f.name
    assert np.array_equal(back.prior_sigma_m[:, 2], solved.prior_sigma_m[:, 2])
    assert "rejected" in back.point_status  # the blunder, as solved


def test_trees_of_two_adjustments_are_refused(solved: Adjustment) -> None:
    one = solved.product_tree(int(solved.scene_index[0]))
    other = dict(solved.product_tree(int(solved.scene_index[1])))
    other["points"] = {**other["points"], "id": ["someone else"] * len(solved.point_id)}
    with pytest.raises(GeometryError, match="of another adjustment"):
        Adjustment.from_trees([(0, one), (1, other)])
    with pytest.raises(GeometryError, match="no level 2 product"):
        Adjustment.from_trees([])


def test_a_request_of_some_scenes_makes_those_alone(tmp_path: Path) -> None:
    """The shipped archive cut into three scenes of 80 lines: asked for scene 1, the plan
    makes its 1A and 2A and no other scene's."""
    options = ProcessingOptions(levels=("1A", "2A"), scene_lines=80)
    one = Pass((read_l0(WARM_UP_ARCHIVE),), ("w",))
    result = run(plan(Request(options, tmp_path, (one,), scenes=frozenset({1}))))
    made = sorted(p.name for p in tmp_path.glob("w_s*") if p.suffix in (".h5", ".nc"))
    assert made == ["w_s001_1A.h5", "w_s001_2A.nc"]  # (the 1A's RPC sidecar beside it)
    assert {m.scene[0] for m in result.of(Step.SCENES) if m.scene} == {1}
    # and all three when none is named
    every = run(plan(Request(options, tmp_path / "all", (one,))))
    assert {m.scene[0] for m in every.of(Step.SCENES) if m.scene} == {0, 1, 2}
