"""RPCs fitted to the rigorous model: their error measured against it, GDAL's evaluation of
them, real SPOT scenes' DIMAP turned into the sidecar GDAL reads."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
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


#: SPOT 1–4 DIMAP tabulate the first and last detector only (a straight line of look
#: angles) with the corrected attitude constant: the RPC is exact to rounding. SPOT 5
#: tabulates every detector and samples the attitude at 8 Hz (its own wiggles).
REAL_MAX_PX = {"spot2": 0.001, "spot4": 0.001, "spot5": 0.15}


@pytest.mark.filterwarnings("ignore::rasterio.errors.NotGeoreferencedWarning")  # the blank
@pytest.mark.parametrize(
    "name",
    [
        "spot2_hrv1_P_19980220_izmit_METADATA.DIM",
        "spot4_hrvir2_M_20120115_altai_METADATA.DIM",
        "spot5_hrg1_A_20050313_altai_METADATA.DIM",
    ],
)
def test_real_scenes_get_a_sidecar_gdal_reads(refdata, tmp_path, name, capsys) -> None:
    """``station locate FILE --rpc OUT``: the ``_RPC.TXT`` beside an image is what GDAL
    then finds for it, and the fit error is printed."""
    import rasterio

    from station.cli import main

    image = tmp_path / "scene.tif"
    with rasterio.open(image, "w", driver="GTiff", width=8, height=8, count=1, dtype="uint8") as ds:
        ds.write(np.zeros((1, 8, 8), dtype=np.uint8))
    sidecar = tmp_path / "scene_RPC.TXT"
    dim = refdata / "dimap" / name
    assert main(["locate", str(dim), "--rpc", str(sidecar), "--heights", "0,3000"]) == 0
    out = capsys.readouterr().out
    assert "RPC" in out and "max" in out
    with rasterio.open(image) as ds:
        rpcs = ds.rpcs
    assert rpcs is not None
    from levels.readers.dimap import read_dimap

    fitted = rpc_of_model(read_dimap(dim).model(), (0.0, 3000.0))
    assert rpcs.line_off == pytest.approx(fitted.line_off)
    assert np.allclose(rpcs.samp_num_coeff, fitted.samp_num, rtol=1e-12, atol=1e-15)
    assert fitted.fit_error_px["max_px"] <= REAL_MAX_PX[name.split("_")[0]]
    # DigitalGlobe's .RPB, which GDAL reads as well (once the _RPC.TXT is gone)
    sidecar.unlink()
    assert (
        main(["locate", str(dim), "--rpc", str(image.with_suffix(".RPB")), "--heights", "0,3000"])
        == 0
    )
    with rasterio.open(image) as ds:
        assert ds.rpcs is not None and ds.rpcs.lat_off == pytest.approx(fitted.lat_off)
        assert np.allclose(ds.rpcs.line_den_coeff, fitted.line_den, rtol=1e-12, atol=1e-15)


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


@pytest.mark.parametrize(
    "name", ["spot2_hrv1_P_19980220_izmit_METADATA.DIM", "spot5_hrg1_A_20050313_altai_METADATA.DIM"]
)
def test_control_points_through_the_algebraic_model(name, refdata, tmp_path, capsys) -> None:
    """``station locate --gcps G --model rpc``: the ground → image step through RPCs lands
    where the rigorous model does, within the RPC's own fit error (PHOTOMOD's comparison)."""
    from levels.locate import check_gcps
    from levels.readers.dimap import read_dimap
    from station.cli import main

    path = refdata / "dimap" / name
    scene = read_dimap(path)
    gcps = frame_gcps(scene, tmp_path / "frame.gcp.csv", height_step_m=100.0)
    rigorous = check_gcps(path, gcps)
    algebraic = check_gcps(path, gcps, model="rpc")
    assert algebraic.model == "rpc" and algebraic.rpc_fit_error_px is not None
    assert algebraic.rpc_vs_rigorous_px is not None
    assert algebraic.rpc_vs_rigorous_px <= max(1e-3, 2 * algebraic.rpc_fit_error_px["max_px"])
    assert algebraic.image_miss_px == pytest.approx(rigorous.image_miss_px, abs=0.3)
    assert main(["locate", str(path), "--gcps", str(gcps), "--model", "rpc"]) == 0
    assert "predicted through RPCs" in capsys.readouterr().out
