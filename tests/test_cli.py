"""The ``station`` command: one line on stderr and exit 2 on bad input, never a traceback."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from station.cli import main


def test_locate_prints_the_frame_check(refdata: Path, capsys) -> None:
    code = main(
        ["locate", str(refdata / "dimap" / "spot5_hrg1_A_20050313_altai_METADATA.DIM"), "--json"]
    )
    assert code == 0
    report = json.loads(capsys.readouterr().out)
    assert report["scene"] == "SPOT 5 HRG1 A" and len(report["points"]) == 5
    assert report["max_error_m"] < 0.1


def test_bad_inputs_exit_2_with_one_line(tmp_path: Path) -> None:
    bad = tmp_path / "bad.DIM"
    bad.write_text("<?xml version='1.0'?><Landsat/>")
    for target in (bad, tmp_path / "missing.DIM"):
        run = subprocess.run(
            [sys.executable, "-m", "station.cli", "locate", str(target)],
            capture_output=True,
            text=True,
            check=False,
        )
        assert run.returncode == 2
        assert run.stderr.startswith("station: error:") and run.stderr.count("\n") == 1
        assert "Traceback" not in run.stderr


ROOT = Path(__file__).resolve().parents[1]


def test_emulate_summarises_a_scenario(capsys) -> None:
    code = main(["emulate", str(ROOT / "scenarios" / "small_test.toml"), "--json"])
    assert code == 0
    report = json.loads(capsys.readouterr().out)
    assert report["strip"]["lines"] == 300 and report["strip"]["detectors"] == 300
    assert report["bands"][0]["failed_rays"] == 0
    assert 59.0 < report["footprint"]["width_first_line_km"] < 61.0
    code = main(["emulate", str(ROOT / "scenarios" / "small_test.toml"), "--no-render"])
    assert code == 0
    text = capsys.readouterr().out
    assert "footprint" in text and "passes over Cuiabá" in text


def test_emulate_bad_scenario_exits_2(tmp_path: Path, capsys) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_text("[instrument]\nmirror_step = 120\n")
    assert main(["emulate", str(bad)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["station: error: [instrument] mirror_step = 120: expected an integer in [3, 93]"]


def test_downlink_writes_l0_and_reports(tmp_path: Path, capsys) -> None:
    out = tmp_path / "pass.l0.h5"
    code = main(
        ["downlink", str(ROOT / "scenarios" / "small_test.toml"), "--out", str(out), "--json"]
    )
    assert code == 0
    rep = json.loads(capsys.readouterr().out)
    assert out.is_file() and rep["l0"]["path"] == str(out)
    for ch in rep["channels"].values():
        assert ch["sent"] == ch["truth_sent"] == ch["delivered"] + ch["lost"]
    band = rep["bands"][0]
    assert band["valid_pixels_as_sent"]
    assert all(
        rep["truth_check"][k]
        for k in ("masks_match_lost_frames", "accounts_balance", "sent_as_counted")
    )
    assert sum(rep["cadus"].values()) >= rep["link"]["cadus_sent"] - 5
    code = main(["downlink", str(ROOT / "scenarios" / "small_test.toml"), "--out", str(out)])
    assert code == 0
    assert "vc01" in capsys.readouterr().out


def test_downlink_bad_scenario_exits_2(tmp_path: Path, capsys) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_text("[channel]\nber = 2.0\n")
    assert main(["downlink", str(bad)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("station: error: [channel] ber = 2.0") and err.count("\n") == 1


def test_process_writes_products_and_reports(tmp_path: Path, capsys) -> None:
    code = main(
        ["process", str(ROOT / "scenarios" / "small_test.toml"), "--out", str(tmp_path), "--json"]
    )
    assert code == 0
    rep = json.loads(capsys.readouterr().out)
    levels = {r["level"]: r for r in rep["products"]}
    assert set(levels) == {"1A", "1B", "2A"}
    assert all(Path(r["path"]).is_file() for r in rep["products"])
    assert levels["2A"]["checkpoints/P/line_of_sight/rms_m"] > 0
    assert main(["process", str(tmp_path / "missing.toml")]) == 2


def test_verbose_says_each_stage_and_quiet_says_nothing(
    run_dir: Path, tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    """``-v`` (before or after the command) logs GEO and each scene on stderr; ``-q`` says
    nothing at all (no table either: the exit code says how it went), unless ``--json``
    asks for the report; by default neither is said."""
    l0 = str(run_dir / "small_test.l0.h5")
    args = ["process", l0, "--levels", "1A", "--out"]
    assert main(["-v", *args, str(tmp_path / "a")]) == 0
    err = capfd.readouterr().err
    assert "station: GEO of small_test: 1 scene(s) to make (1A)" in err
    assert "station: small_test-s000: 1 product(s)" in err
    assert main([*args, str(tmp_path / "b"), "-vv"]) == 0
    assert "small_test-s000 timings: " in capfd.readouterr().err
    assert main([*args, str(tmp_path / "c")]) == 0
    assert "GEO of" not in capfd.readouterr().err
    assert main(["-q", *args, str(tmp_path / "d")]) == 0
    assert capfd.readouterr() == ("", "")
    assert main(["-q", *args, str(tmp_path / "e"), "--json"]) == 0
    out, err = capfd.readouterr()
    assert err == "" and json.loads(out)["products"]
