"""SPOT 6/7 DIMAP v2 scenes (issue 35 §4): ``station locate DIM_*.XML`` builds the scene's
model from its RPC and reproduces the producer's frame; ``--gcps`` and ``--rpc`` work on it
as on DIMAP v1.

No real SPOT 6/7 product is in ../shared/refdata, so the "producer" is the emulated
station: a 1A's rigorous model locates the frame (the producer's own model), its RPC fitted
to that model is the ``RPC_*.XML`` (``tests/_dimap2.py`` writes both files as Airbus lays
them out, pixels from 1).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from _cli import one_line
from _dimap2 import write_dim_xml, write_rpc_xml

from levels.errors import DimapError
from levels.geo.rpc import Rpc
from levels.geo.scenes import models_of_tree
from levels.locate import check_frame
from levels.products import read_product
from levels.readers.dimap import read_dimap
from levels.readers.dimap2 import read_dimap2
from levels.readers.rpc import read_rpc_txt
from station.cli import main

#: The frame's height (m): where the producer located it (the file's ``H``).
FRAME_H_M = 500.0
#: Round-off of two evaluations of the same coefficients (pixels).
SAME_PX = 1e-6


@pytest.fixture(scope="module")
def scene(run_dir: Path, tmp_path_factory) -> tuple[Path, Rpc]:
    product = read_product(run_dir / "small_test_s000_1A.h5", images=False)
    rpc = Rpc.from_tree(product.geometry["rpc"]["P"])
    _, models = models_of_tree(product.geometry)
    model = models["P"]
    n_rows, n_cols = model.n_lines, model.n_columns
    rows = np.array([1, 1, n_rows, n_rows, (n_rows + 1) // 2], dtype=float)
    cols = np.array([1, n_cols, n_cols, 1, (n_cols + 1) // 2], dtype=float)
    g = model.image_to_ground(rows - 1.0, cols - 1.0, FRAME_H_M)  # the producer's model
    frame = np.column_stack([rows, cols, np.degrees(g.lat_rad), np.degrees(g.lon_rad)])
    frame = np.column_stack([frame, np.full(5, FRAME_H_M)])
    d = tmp_path_factory.mktemp("spot6")
    write_rpc_xml(rpc, d / "RPC_SPOT6_P_TEST.XML")
    return write_dim_xml(
        d / "DIM_SPOT6_P_TEST.XML", "RPC_SPOT6_P_TEST.XML", n_rows, n_cols, frame
    ), rpc


def test_locate_reproduces_the_producers_frame(scene) -> None:
    dim, rpc = scene
    check = check_frame(dim)
    # the RPC's fit to the producer's model, at most, on the ground (m)
    bar_m = rpc.fit_error_px["max_px"] * rpc.ground_sample_m()
    assert check.error_m.max() <= bar_m, (check.error_m, bar_m)
    assert check.roundtrip_px.max() < 1e-3
    assert check.attitude == "the producer's RPC"
    assert read_dimap2(dim).name == "SPOT 6 NAOMI"


def test_the_frames_heights_matter(scene, tmp_path) -> None:
    """The frame is located at the heights the file gives: 2500 m wrong moves the swath's
    edge corners by tan(2°) of it (~90 m; the check can tell); without ``H`` the frame is
    taken at the RPC's height offset."""
    dim, rpc = scene
    right = check_frame(dim).error_m.max()
    (tmp_path / "RPC_SPOT6_P_TEST.XML").write_text(
        (dim.parent / "RPC_SPOT6_P_TEST.XML").read_text()
    )
    wrong = tmp_path / dim.name
    wrong.write_text(dim.read_text().replace(f"<H>{FRAME_H_M!r}</H>", "<H>3000.0</H>"))
    assert check_frame(wrong).error_m.max() > 10 * right
    no_h = tmp_path / "DIM_NO_H.XML"
    no_h.write_text(dim.read_text().replace(f"<H>{FRAME_H_M!r}</H>", ""))
    assert np.all(read_dimap2(no_h).frame_h_m == rpc.height_off)


def test_locate_gcps_and_rpc_on_a_dimap2_scene(scene, run_dir, tmp_path, capsys) -> None:
    dim, rpc = scene
    gcps = run_dir / "small_test.gcp.csv"
    assert main(["locate", str(dim), "--gcps", str(gcps), "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["points_within_reach"] == len(report["points"]) > 0
    # the same points through the emulated 1A's rigorous model would miss by the same
    # bulletin error: ~216 m for small_test
    assert 150 < report["rms_ground_m"] < 300
    out = tmp_path / "IMG_RPC.TXT"
    assert main(["locate", str(dim), "--rpc", str(out), "--heights", "0,1000"]) == 0
    assert "as it is" in capsys.readouterr().out
    back = read_rpc_txt(out)
    rng = np.random.default_rng(6)
    lat = rng.uniform(-15.8, -15.4, 200)
    lon = rng.uniform(-56.3, -55.9, 200)
    h = rng.uniform(0, 1000, 200)
    a, b = np.array(rpc.image_of(lat, lon, h)), np.array(back.image_of(lat, lon, h))
    assert np.abs(a - b).max() < SAME_PX


def test_a_dimap2_scene_without_its_rpc_is_one_clear_error(scene, tmp_path, capsys) -> None:
    dim, _ = scene
    lone = tmp_path / dim.name
    lone.write_text(dim.read_text())
    with pytest.raises(DimapError, match=r"RPC file .* is not there"):
        read_dimap2(lone)
    one_line(capsys, main(["locate", str(lone)]), 2, "is not there")
    # the v1 reader points at the v2 one
    with pytest.raises(DimapError, match="read_dimap2"):
        read_dimap(dim)
