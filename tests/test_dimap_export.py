"""DIMAP v1 written out: the real SPOT files round-trip through the writer, an emulated 1A
becomes a scene whose model is the product's, GDAL's DIMAP driver opens it, and the
benchmark pack's truth files locate its checkpoints as the emulator does (issue 35 §5)."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest
from _cli import one_line
from _dimap import EXPORT_MODEL_PX, model_gap_px

from levels.geometry.attitude import SampledAttitude
from levels.geometry.ephemeris import Ephemeris
from levels.geometry.model import LineClock, PushbroomModel
from levels.geometry.sensor import LookAngleTable
from levels.geometry.times import parse_utc
from levels.products import read_product
from levels.readers.dimap import read_dimap
from station.cli import main

ROOT = Path(__file__).resolve().parents[1]
#: The truth tables (orbit every 1 s by Lagrange, attitude every 2 ms linearly, look angles
#: per detector, times to the nanosecond) against the emulator's continuous truth at the
#: checkpoints: measured 0.018 m at most, the attitude's linear interpolation being the
#: largest part (30 Hz jitter of 0.3 µrad sampled at 500 Hz: A·(ωh)²/8 ≈ 6e-10 rad, with the
#: drift's curvature); 0.05 m is 2.5e-4 of the reduced scene's 200 m pixel.
TRUTH_TABLES_M = 0.05


@pytest.fixture(scope="module")
def product_1a(run_dir: Path) -> Path:
    return run_dir / "small_test_s000_1A.h5"


def _columns(path: Path) -> dict[str, list[str]]:
    with path.open(encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    return {k: [r[k] for r in rows] for k in rows[0]}


@pytest.fixture(scope="module")
def pack(product_1a: Path, tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("pack") / "pack"
    scenario = ROOT / "scenarios" / "small_test.toml"
    assert main(["export", str(product_1a), "--dimap", str(out), "--scenario", str(scenario)]) == 0
    return out


def test_the_pack_holds_the_scene_and_its_truth(pack: Path) -> None:
    names = {p.relative_to(pack).as_posix() for p in pack.rglob("*") if p.is_file()}
    assert names == {
        "METADATA.DIM",
        "IMAGERY.TIF",
        "README.md",
        "pack.json",
        "control_points.csv",
        "truth/dem.tif",
        "truth/checkpoints.csv",
        "truth/control_points.csv",
        "truth/ephemeris.csv",
        "truth/attitude.csv",
        "truth/look_angles.csv",
        "truth/scenario.toml",
    }
    manifest = json.loads((pack / "pack.json").read_text())
    assert manifest["truth"] and manifest["seed"] == 4
    scores = manifest["scores_m"]["station model (INPE attitude)"]
    # small_test's bulletins are off by ~216 m (the run's own line-of-sight figure)
    assert 150 < scores["rms_m"] < 300 and scores["n"] == 21 * 21


def _truth_miss_m(pack: Path) -> float:
    """What a user of the pack does: build the true model of band 1 from the truth tables
    and find each checkpoint where the truth says it is; the largest miss (m)."""
    scene = read_dimap(pack / "METADATA.DIM")
    assert scene.epoch is not None and scene.line_period_s and scene.scene_center_line
    epoch = scene.epoch
    eph = _columns(pack / "truth" / "ephemeris.csv")
    att = _columns(pack / "truth" / "attitude.csv")
    look = _columns(pack / "truth" / "look_angles.csv")
    first = [k for k, b in enumerate(look["band"]) if b == look["band"][0]]  # band 1
    look = {k: [v[i] for i in first] for k, v in look.items()}
    cp = _columns(pack / "truth" / "checkpoints.csv")

    def num(table: dict, *keys: str) -> np.ndarray:
        return np.array([[float(x) for x in table[k]] for k in keys]).T

    # the lines' true times (the DIMAP's dating is the station's estimate)
    t_cp = epoch.seconds(parse_utc(cp["time_utc"]))
    row = np.array(cp["row"], dtype=float)
    period, t_row1 = np.polyfit(row - 1.0, t_cp, 1)
    assert np.abs(t_row1 + period * (row - 1.0) - t_cp).max() < 1e-8
    model = PushbroomModel(
        epoch,
        LineClock(t_row1, 0.0, period),
        Ephemeris(
            epoch.seconds(parse_utc(eph["time_utc"])),
            num(eph, "x_m", "y_m", "z_m"),
            num(eph, "vx_m_per_s", "vy_m_per_s", "vz_m_per_s"),
        ),
        SampledAttitude(
            epoch.seconds(parse_utc(att["time_utc"])), num(att, "roll_rad", "pitch_rad", "yaw_rad")
        ),
        LookAngleTable(
            num(look, "detector_id")[:, 0] - 1.0,
            num(look, "psi_x_rad")[:, 0],
            num(look, "psi_y_rad")[:, 0],
            scene.n_cols,
        ),
        scene.n_rows,
    )
    col, lon, lat, h = num(cp, "col", "lon_deg", "lat_deg", "h_m").T
    g = model.image_to_ground(row - 1.0, col - 1.0, h)
    from pyproj import Geod

    _, _, miss = Geod(ellps="WGS84").inv(lon, lat, np.degrees(g.lon_rad), np.degrees(g.lat_rad))
    return float(miss.max())


def test_the_truth_tables_locate_the_checkpoints(pack: Path) -> None:
    assert _truth_miss_m(pack) < TRUTH_TABLES_M
    # the measured control points are the truth plus the scenario's errors
    measured = _columns(pack / "control_points.csv")
    true = _columns(pack / "truth" / "control_points.csv")
    assert measured["id"] == true["id"] and len(true["id"]) > 0
    d_row = np.array(measured["row"], float) - np.array(true["row"], float)
    assert 0 < np.abs(d_row).max() < 5 * 0.3  # [gcps] pointing_error_px, 5σ


def test_station_locate_reads_the_pack(pack: Path, capsys) -> None:
    args = ["locate", str(pack / "METADATA.DIM"), "--attitude", "integrated_zeroed"]
    assert main(args) == 0
    out = capsys.readouterr().out
    assert float(out.strip().splitlines()[-1].split()[2]) < 0.05  # "max error X m"
    assert main([*args, "--gcps", str(pack / "control_points.csv")]) == 0


TWIN = """
name = "twin_xs"
seed = 7
[[instrument]]
hrv = 1
twin = true
mode = "XS"
n_detectors = 150
n_lines = 150
[[instrument]]
hrv = 2
twin = true
mode = "XS"
n_detectors = 150
n_lines = 150
[downlink]
bit_rate_mbps = 0.5
preamble_s = 0.1
postamble_s = 0.1
[processing]
levels = ["1A"]
"""


def test_a_twin_pass_in_xs_is_exported_the_same_way(tmp_path: Path) -> None:
    """Both HRVs of a twin pass, three bands each: two packs, each its HRV's scene and
    truth (reduced: 150 detectors, 150 lines)."""
    scenario = tmp_path / "twin_xs.toml"
    scenario.write_text(TWIN)
    run = tmp_path / "run"
    assert main(["run", str(scenario), "--out", str(run), "--quiet", "--no-quicklooks"]) == 0
    for hrv in (1, 2):
        product = run / f"twin_xs_hrv{hrv}_s000_1A.h5"
        pack = tmp_path / f"hrv{hrv}"
        assert (
            main(["export", str(product), "--dimap", str(pack), "--scenario", str(scenario)]) == 0
        )
        scene = read_dimap(pack / "METADATA.DIM")
        assert (scene.instrument_index, scene.sensor_code, sorted(scene.look_angles)) == (
            hrv,
            "X",
            [1, 2, 3],
        )
        assert model_gap_px(read_product(product), scene) < EXPORT_MODEL_PX
        assert _truth_miss_m(pack) < TRUTH_TABLES_M


def test_refusals(run_dir: Path, product_1a: Path, tmp_path: Path, capsys) -> None:
    twoa = run_dir / "small_test_s000_2A.nc"
    code = main(["export", str(twoa), "--dimap", str(tmp_path / "a")])
    one_line(capsys, code, 2, "made from a 1A")
    other = ROOT / "scenarios" / "quickstart.toml"
    args = ["export", str(product_1a), "--dimap", str(tmp_path / "b"), "--scenario", str(other)]
    one_line(capsys, main(args), 2, "is not the scenario that made")
    assert not (tmp_path / "b").exists()
    args = ["export", str(product_1a), "--dimap", str(tmp_path / "c"), "--out", "x.tif"]
    one_line(capsys, main(args), 2, "--out goes with --geotiff")
    # a directory holding something else is not replaced
    (tmp_path / "d").mkdir()
    (tmp_path / "d" / "keep.txt").write_text("mine")
    one_line(capsys, main(["export", str(product_1a), "--dimap", str(tmp_path / "d")]), 2, "keep")
    assert (tmp_path / "d" / "keep.txt").read_text() == "mine"


def test_the_scenario_is_found_through_the_runs_report(
    product_1a: Path, tmp_path: Path, monkeypatch
) -> None:
    monkeypatch.chdir(ROOT)  # report.json names scenarios/small_test.toml's file name
    assert main(["export", str(product_1a), "--dimap", str(tmp_path / "p")]) == 0
    assert json.loads((tmp_path / "p" / "pack.json").read_text())["truth"]
