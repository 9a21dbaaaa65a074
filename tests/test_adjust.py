"""Level 2: the adjustment against the emulated truth, at full P geometry (no image)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from levels.adjust import adjust
from levels.errors import GcpError
from levels.geometry.attitude import attitude_gaps, integrate_rates, westin_variogram_rad2
from levels.options import ProcessingOptions
from levels.process import process_l0
from levels.products import read_product
from levels.readers.l0 import read_l0
from levels.spot import MODES
from station.scenario import scenario_from_dict
from station.sipc.process import control_points, emulated_pass
from station.sipc.truth import Truth
from station.spacecraft.emulator import emulate

SCENE = 6000  # a full P scene: the figures below are in 10 m pixels
PIXEL_M = 10.0
#: Seeds drawn for the statistical checks: 8 passes keep the suite fast; the issue's 20
#: are in ``tools/level2.py``.
SEEDS = range(8)


def _case(seed: int, n_scenes: int, gcps: dict, lost: tuple[int, ...] = ()) -> dict:
    scn = scenario_from_dict(
        {"name": "t", "seed": seed, "instrument": {"n_lines": SCENE * n_scenes}, "gcps": gcps}
    )
    acq = emulate(scn, render=False)
    pg, scenes = emulated_pass(acq, SCENE, lost=lost)
    adj = adjust(pg, scenes, control_points(acq), ProcessingOptions())
    truth = Truth(acq, 0)
    return {
        "adj": adj,
        "acq": acq,
        "before": [np.hypot(*truth.model_error_en(s)) for s in scenes],
        "after": [np.hypot(*truth.model_error_en(adj.refine(pg, s))) for s in scenes],
    }


def _rms(x: list[np.ndarray]) -> float:
    return float(np.sqrt(np.mean(np.concatenate(x) ** 2)))


def test_twelve_points_a_scene_reach_a_pixel_as_predicted() -> None:
    after, predicted = [], []
    for seed in SEEDS:
        c = _case(seed, 1, {"count": 12})
        assert _rms(c["before"]) > 150.0  # the system model's 200 m, as real 2A
        after += c["after"]
        predicted.append(c["adj"].predicted_sigma_m[0, 2])
    measured, pred = _rms(after), float(np.sqrt(np.mean(np.square(predicted))))
    assert measured <= 1.0 * PIXEL_M  # the figure: ≤ 1 px
    # the predicted σ is honest: 8 passes put the ratio within the issue's [0.7, 1.5]
    # widened by the sampling error of 8 draws (≈ 0.1 on the RMS ratio)
    assert 0.6 <= measured / pred <= 1.6


def test_one_point_holds_the_rest_by_the_priors() -> None:
    after = [_case(seed, 1, {"count": 1})["after"][0] for seed in SEEDS]
    assert _rms(after) <= 2.0 * PIXEL_M  # the figure: ≤ 2 px


def test_blunders_are_rejected_and_reported() -> None:
    planted = caught = false = 0
    ratios = []
    for seed in SEEDS[:4]:
        clean = _case(seed, 1, {"count": 20})
        dirty = _case(seed, 1, {"count": 20, "blunder_fraction": 0.1, "blunder_m": 100.0})
        rejected = np.array(dirty["adj"].point_status) == "rejected"
        blunder = dirty["acq"].gcps.blunder
        planted += int(blunder.sum())
        caught += int(np.sum(blunder & rejected))
        false += int(np.sum(~blunder & rejected))
        ratios.append(_rms(dirty["after"]) / _rms(clean["after"]))
        assert dirty["adj"].summary()["rejected"] == [
            i for i, b in zip(dirty["adj"].point_id, blunder, strict=True) if b
        ]
    assert planted == 8 and caught == planted and false == 0
    # the same points less the two blunders: within the 10 % of the clean result,
    # give or take what two fewer points change (checked on the RMS over 4 passes)
    assert np.mean(ratios) == pytest.approx(1.0, abs=0.1)


def test_points_at_both_ends_bridge_the_pass() -> None:
    c = _case(3, 6, {"count": 16, "line_ranges": [0.0, 0.12, 0.88, 1.0]})
    for k, err in enumerate(c["after"]):
        assert _rms([err]) <= 1.5 * PIXEL_M, k  # the figure for the gap
    assert c["adj"].summary()["points_used"] == 16


def test_a_gap_is_weighted_by_westin_and_costs_accuracy() -> None:
    gcps = {"count": 2, "line_ranges": [0.0, 0.15]}
    gap = _case(1, 4, gcps, lost=(1, 2))
    adj = gap["adj"]
    assert list(adj.scene_index) == [0, 3]
    lost = adj.gap_s[1]
    assert lost == pytest.approx(2 * SCENE * MODES["P"].line_period_s, rel=0.01)
    # the jump across the gap is weighted by Westin's variogram (eq. 24) over the lost time,
    # plus the gyros' random walk over the recorded part: (0.5 µrad/s)² × 0.125 s × 9 s
    # against 2γ_ω(18 s) ≈ 9e-11 rad², a 0.15 % larger σ
    assert adj.increment_sigma_rad[1, 0] == pytest.approx(
        np.sqrt(westin_variogram_rad2(0, lost)), rel=0.005
    )
    through = _case(1, 4, gcps)
    assert through["adj"].increment_sigma_rad[3, 0] < 0.1 * adj.increment_sigma_rad[1, 0]
    # the scene beyond is predicted worse than with records throughout
    assert adj.predicted_sigma_m[1, 2] > through["adj"].predicted_sigma_m[3, 2]


def test_geo_holds_the_attitude_across_lost_records() -> None:
    t = np.r_[np.arange(0.0, 1.0, 0.125), np.arange(5.0, 6.0, 0.125)]
    rates = np.full((t.size, 3), 1e-4)
    held = integrate_rates(t, rates, max_gap_s=0.2)
    across = integrate_rates(t, rates)
    jump = held.angles_rad(np.array([5.0]))[0] - held.angles_rad(np.array([0.875]))[0]
    assert np.all(jump == 0.0)
    assert np.allclose(across.angles_rad(np.array([5.0]))[0], 5.0 * 1e-4)
    assert attitude_gaps(t).tolist() == [[0.875, 5.0]]


def test_level_2_products_need_points_and_carry_their_adjustment(tmp_path) -> None:
    from station.sipc.process import process_scenario

    scn = scenario_from_dict(
        {
            "name": "l2",
            "seed": 2,
            "instrument": {"n_detectors": 300, "n_lines": 300},
            "gcps": {"count": 6, "blunder_fraction": 0.2, "blunder_m": 2000.0},
            "downlink": {"bit_rate_mbps": 0.2, "preamble_s": 0.1, "postamble_s": 0.1},
            "processing": {"levels": ["2"]},
        }
    )
    made, l0 = process_scenario(scn, tmp_path)
    p = read_product(made.scenes[0].paths["2"])
    assert p.level == "2" and p.map_grid is not None
    adj = p.geometry["adjustment"]
    assert adj["covariance"].shape == (12, 12)
    assert np.all(np.linalg.eigvalsh(adj["covariance"]) > 0)
    assert sorted(json.loads(adj["points"]["status"])) == ["rejected"] + ["used"] * 5
    q = made.scenes[0].quality["2"]
    after = q["checkpoints/P/line_of_sight/rms_m"]
    assert after < 0.2 * q["checkpoints_2a/P/line_of_sight/rms_m"]
    assert q["predicted_sigma_m/horizontal"] < 0.2 * q["predicted_sigma_m/prior_horizontal"]
    with pytest.raises(GcpError, match="level 2 needs control points"):
        process_l0(read_l0(l0), ProcessingOptions(levels=("2",)), tmp_path / "again")
