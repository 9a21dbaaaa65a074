"""RPCs fitted to the rigorous model of emulated scenes: their error measured against it;
``station locate --rpc`` refusing what has no model (real scenes' sidecars and control
points through RPCs: ``tests/levels/test_rpc_sidecars.py``)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest
from _frames import frame_gcps
from _orbits import smooth_table

from levels.geo.rpc import rpc_of_model
from station.fixtures import emulated_scene
from station.scenario import ERRORS_OFF, merge_tables, scenario_from_dict
from station.spacecraft.emulator import emulate

#: The issue's figures for the algebraic model against the rigorous one (pixels).
RPC_RMS_PX, RPC_MAX_PX = 0.01, 0.05
#: GDAL's evaluation of our coefficients against ours (pixels): the same rational
#: function, so only rounding separates them.
GDAL_AGREEMENT_PX = 0.01
HEIGHTS_M = (0.0, 1500.0)


def _scene(mirror_step: int, errors: dict) -> object:
    scn = scenario_from_dict(
        merge_tables(errors, {"name": "rpc", "instrument": {"mirror_step": mirror_step}})
    )
    _pg, scene, _res = emulated_scene(emulate(scn, render=False))
    return scene


@pytest.fixture(scope="module", params=[48, 93], ids=["nadir", "27deg"])
def scenes(request) -> tuple:
    """The P scene at the mirror step, errors off and with the default errors
    (gyro-integrated attitude with its drift and jitter)."""
    return _scene(request.param, ERRORS_OFF), _scene(request.param, {})


def test_what_keeps_spot_rpcs_above_a_hundredth_of_a_pixel(scenes) -> None:
    """The CCD buttings' along-track steps (ψx jumps of 0.6–0.8″, a third of a pixel) and
    the attitude's high frequencies are in the line direction: a rational function of the
    ground is smooth and follows neither; the 2A inverse grid, per segment and dense, does.
    The error is measured and stored, and it stays under the buttings' step."""
    quiet, noisy = scenes
    for scene in (quiet, noisy):
        e = rpc_of_model(scene.model, HEIGHTS_M).fit_error_px
        assert e["line_max_px"] > 3 * e["sample_max_px"]  # the steps are along track
        assert 0.1 < e["rms_px"] < 0.3 and e["max_px"] < 0.6
    smooth_noisy = dataclasses.replace(
        noisy.model, look_angles=smooth_table(noisy.model.look_angles)
    )
    e = rpc_of_model(smooth_noisy, HEIGHTS_M).fit_error_px
    assert e["rms_px"] > 5 * RPC_RMS_PX  # the attitude's jitter alone keeps it above


def test_locate_rpc_refuses_a_frame_only_file(refdata, tmp_path, capsys) -> None:
    from station.cli import EXIT_BAD_INPUT, main

    dim = refdata / "dimap" / "gdal_spot4_hrvir1_M_20011129_frameonly_METADATA.DIM"
    code = main(["locate", str(dim), "--rpc", str(tmp_path / "x_RPC.TXT")])
    assert code == EXIT_BAD_INPUT
    assert "no model" in capsys.readouterr().err
    assert not Path(tmp_path / "x_RPC.TXT").exists()


def test_locate_rpc_takes_an_ossim_keyword_list(refdata, tmp_path, capsys) -> None:
    from station.cli import EXIT_BAD_INPUT, main

    geom = refdata / "dimap" / "otb_spot5_hrg2_20030723_teheran_ossim.geom"
    out = tmp_path / "teheran_RPC.TXT"
    assert main(["locate", str(geom), "--rpc", str(out), "--heights", "0,3000"]) == 0
    assert "RPC00B written" in capsys.readouterr().out and out.read_text().count("\n") == 90
    assert main(["locate", str(geom)]) == EXIT_BAD_INPUT
    assert "use --rpc" in capsys.readouterr().err


def test_station_locate_checks_control_points_through_rpcs(refdata, tmp_path, capsys) -> None:
    """``station locate --gcps G --model rpc`` says the points were predicted through RPCs
    (what it finds: ``tests/levels/test_rpc_sidecars.py``)."""
    from levels.readers.dimap import read_dimap
    from station.cli import main

    path = refdata / "dimap" / "spot2_hrv1_P_19980220_izmit_METADATA.DIM"
    gcps = frame_gcps(read_dimap(path), tmp_path / "frame.gcp.csv", height_step_m=100.0)
    assert main(["locate", str(path), "--gcps", str(gcps), "--model", "rpc"]) == 0
    assert "predicted through RPCs" in capsys.readouterr().out
