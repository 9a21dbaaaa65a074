"""Level 2: the adjustment against the emulated truth, at full P geometry (no image); the
adjustment's own properties (one point, blunders, a pass bridged, a gap) are checked against
a synthetic truth without the emulator in ``tests/levels/test_adjust_truth.py``."""

from __future__ import annotations

import json

import numpy as np
import pytest

from levels.adjust import Strip, adjust, adjust_strips
from levels.errors import GeometryError
from levels.options import ProcessingOptions
from levels.products import read_product
from station.chain.gcps import control_points
from station.fixtures import emulated_pass
from station.scenario import scenario_from_dict
from station.spacecraft.emulator import emulate, emulate_pass
from station.truth.optical import Truth

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


def test_level_2_products_need_points_and_carry_their_adjustment(tmp_path) -> None:
    from station.reprocess import process_scenario

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
    made, _l0 = process_scenario(scn, tmp_path)
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
    # refused without points, the product's adjustment: tests/levels/test_level2_work.py


def _twin(seed: int, hrvs: list[int]) -> tuple[list, list, list]:
    """A twin pass of two full P scenes per HRV, control points in ``hrvs`` only; the
    geometry of each HRV, its points and its truth."""
    scn = scenario_from_dict(
        {
            "name": "t",
            "seed": seed,
            "instrument": [{"hrv": h, "twin": True, "n_lines": 2 * SCENE} for h in (1, 2)],
            "gcps": {"count": 24, "hrvs": hrvs},
        }
    )
    acqs = emulate_pass(scn, render=False)
    geo = [emulated_pass(a, SCENE) for a in acqs]
    return acqs, geo, [control_points(a) for a in acqs]


def test_a_twin_pass_adjusted_together_refines_the_hrv_without_points() -> None:
    together, alone, predicted = [], [], []
    for seed in SEEDS[:4]:
        acqs, geo, points = _twin(seed, [1])
        assert len(points[1]) == 0 and len(points[0]) == 24
        strips = [Strip(pg, scenes, p) for (pg, scenes), p in zip(geo, points, strict=True)]
        adj1, adj2 = adjust_strips(strips, ProcessingOptions())
        assert adj1.mode == adj2.mode == "twin"
        # one platform: both HRVs' scenes at the same instants share their corrections
        assert np.array_equal(adj1.scene_parameters, adj2.scene_parameters)
        pg2, scenes2 = geo[1]
        truth2 = Truth(acqs[1], 0)
        together += [np.hypot(*truth2.model_error_en(adj2.refine(pg2, s))) for s in scenes2]
        predicted += list(adj2.predicted_sigma_m[:, 2])
        solo = adjust(pg2, scenes2, points[1], ProcessingOptions())
        alone += [np.hypot(*truth2.model_error_en(solo.refine(pg2, s))) for s in scenes2]
    measured = _rms(together)
    assert measured <= 1.5 * PIXEL_M  # the figure for HRV2
    assert _rms(alone) > 10 * measured  # alone, HRV2 has only the a priori budget
    # predicted honestly (4 passes: the sampling error widens the [0.7, 1.5] band)
    assert 0.6 <= measured / float(np.sqrt(np.mean(np.square(predicted)))) <= 1.6


def test_a_joint_adjustment_needs_one_platform_attitude() -> None:
    acqs, geo, points = _twin(0, [1, 2])
    scenes2 = geo[1][1]
    other = emulated_pass(acqs[1], SCENE, lost=(0,))[0]  # fewer gyro records
    with pytest.raises(GeometryError, match="one platform attitude"):
        adjust_strips(
            [Strip(*geo[0], points[0]), Strip(other, scenes2[1:], points[1])],
            ProcessingOptions(),
        )


def test_station_process_adjusts_a_twin_pass_from_both_archives(tmp_path, capsys) -> None:
    """``station process HRV1.l0.h5 HRV2.l0.h5`` (adjustment = "twin") makes the run's level 2
    products again, and HRV2's, without points of its own, comes out refined."""
    from station.cli import main
    from station.run import run_scenario

    text = (
        'name = "tw"\nseed = 5\n'
        + "".join(
            f"[[instrument]]\nhrv = {h}\ntwin = true\nn_detectors = 300\nn_lines = 600\n"
            for h in (1, 2)
        )
        + "[gcps]\ncount = 12\nhrvs = [1]\n"
        + "[downlink]\nbit_rate_mbps = 0.6\npreamble_s = 0.1\npostamble_s = 0.1\n"
        + '[processing]\nlevels = ["2A", "2"]\nadjustment = "twin"\nscene_lines = 300\n'
    )
    scn_path = tmp_path / "tw.toml"
    scn_path.write_text(text)
    from station.loader import load_scenario

    report = run_scenario(load_scenario(scn_path), tmp_path / "run", quicklooks=False)
    assert [h["adjustment"]["mode"] for h in report["hrvs"]] == ["twin", "twin"]
    archives = [str(tmp_path / "run" / f"tw_hrv{h}.l0.h5") for h in (1, 2)]
    args = ["process", *archives, "--scenario", str(scn_path), "--json"]
    assert main([*args, "--out", str(tmp_path / "again")]) == 0
    again = json.loads(capsys.readouterr().out)["archives"]
    key = "checkpoints/P/line_of_sight/rms_m"
    for rows, hrv in zip(again, (1, 2), strict=True):
        ran = {
            (p["scene"], p["level"]): p["quality"][key]
            for p in report["products"]
            if p["hrv"] == hrv
        }
        redone = {(r["scene"], r["level"]): r[key] for r in rows["products"]}
        assert redone == pytest.approx(ran, rel=1e-9)
    hrv2 = {(r["scene"], r["level"]): r[key] for r in again[1]["products"]}
    for scene in (0, 1):
        # 200 m pixels: HRV1's points take HRV2 from the system model's 200 m to tens of m
        assert hrv2[scene, "2"] < 0.3 * hrv2[scene, "2A"]
    # processed alone, the HRV without points is refused, with the way out in the message
    assert (
        main([*args[:1], archives[1], "--scenario", str(scn_path), "--out", str(tmp_path / "x")])
        == 2
    )
    assert "adjustment = 'twin'" in capsys.readouterr().err
