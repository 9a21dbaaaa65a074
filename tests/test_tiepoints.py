"""Tie points between two passes over one ground (issue 36 §2), against the truth: where
the first pass's pixel truly looks, projected by the second pass's true model, is where the
tie point must be found in the second image.

Reduced passes (600 detectors with a 10× IFOV: 100 m pixels, 600 lines) over the same
world on two dates 26 days apart, the mirror at 0° and +8.4°, each with its own errors
(scenario seeds), 400 m of relief.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from _passes import run_pass

from levels.errors import GeometryError
from levels.geometry.ellipsoid import WGS84
from levels.products import read_product
from levels.readers.gcp import read_gcps, write_gcps
from levels.readers.l0 import read_l0
from levels.tiepoints import MapView, TiePoints, match_views
from station.cli import main
from station.loader import load_scenario
from station.spacecraft.emulator import emulate_pass, truth_model
from station.truth.optical import Truth

#: The issue's bar: matched position against the true corresponding point, RMS.
TIE_RMS_PX = 0.2
#: A wrong match: a point found farther than this from where the truth puts it.
WRONG_MATCH_PX = 1.0
#: Tie points expected at least on the reduced pair (it finds 642 of 1000 candidates).
MIN_TIE_POINTS = 200


@pytest.fixture(scope="module")
def passes(tmp_path_factory) -> dict[str, tuple[Path, Path]]:
    """Two passes run end to end: their scenario and their run directory."""
    d = tmp_path_factory.mktemp("tie")
    return {
        "pa": run_pass(d, "pa", 11, "1998-02-20", 48),
        "pb": run_pass(d, "pb", 12, "1998-03-18", 62),
    }


@pytest.fixture(scope="module")
def views(passes) -> tuple[MapView, MapView]:
    return tuple(  # type: ignore[return-value]
        MapView.of_product(read_product(run / f"{name}_s000_2A.nc"))
        for name, (_, run) in passes.items()
    )


def _truth_miss_px(tp: TiePoints, passes) -> np.ndarray:
    """Each tie point's distance (px) in the second image from where the truth puts the
    ground the first image's pixel truly sees."""
    truths = []
    for name, (scenario, run) in passes.items():
        acq = emulate_pass(load_scenario(scenario), render=False)[0]
        truths.append((acq, Truth.of(acq, read_l0(run / f"{name}.l0.h5", lazy=True))))
    (_, ta), (acq_b, tb) = truths
    g = ta.ground(0, tp.line_a + ta.row_offset, tp.column_a)
    lat, lon, h = WGS84.to_geodetic(g)
    back = truth_model(acq_b).ground_to_image(lat, lon, h)
    return np.hypot(tp.line_b - (back.line - tb.row_offset), tp.column_b - back.column)


def test_tie_points_sit_on_the_truth(views, passes) -> None:
    tp = match_views(*views)
    assert len(tp) >= MIN_TIE_POINTS, tp.counts
    miss = _truth_miss_px(tp, passes)
    assert np.sqrt(np.mean(miss**2)) <= TIE_RMS_PX
    assert miss.max() < WRONG_MATCH_PX
    assert (
        sum(v for k, v in tp.counts.items() if k not in ("candidates", "kept")) + len(tp)
        == tp.counts["candidates"]
    )
    # the mid-points of the two lines of sight lie on the relief (the models' error moves
    # them by their ~220 m each, the heights by that over the B/H of 0.15)
    assert np.all(np.abs(tp.h_m) < 5000.0)


def _periodic(shape: tuple[int, int], period: int = 5) -> np.ndarray:
    r, c = np.mgrid[0 : shape[0], 0 : shape[1]]
    return 80.0 + 60.0 * np.sin(2 * np.pi * r / period) * np.sin(2 * np.pi * c / period)


def test_repetitive_texture_and_a_cloud_make_no_match(views, passes) -> None:
    """A periodic pattern laid on the same ground of both images, and a cloud (a flat bright
    patch with soft edges) in the first only: no tie point in the pattern, none wrong."""
    a, b = views
    ia, ib = a.image.copy(), b.image.copy()
    r0, c0, n = 150, 150, 120  # the pattern on a's grid, the same map area on b's
    ga, gb = a.geometry.map_grid.geotransform, b.geometry.map_grid.geotransform
    rb0 = r0 + round((gb[3] - ga[3]) / ga[5])
    cb0 = c0 + round((ga[0] - gb[0]) / ga[1])
    ia[r0 : r0 + n, c0 : c0 + n] = _periodic((n, n))
    ib[rb0 : rb0 + n, cb0 : cb0 + n] = _periodic((n, n))
    rr, cc = np.mgrid[0 : ia.shape[0], 0 : ia.shape[1]]
    cloud = np.clip(1.5 - np.hypot(rr - 420, cc - 300) / 60.0, 0.0, 1.0)
    ia = (ia * (1 - cloud) + 250.0 * cloud).astype(np.float32)
    tp = match_views(dataclasses.replace(a, image=ia), dataclasses.replace(b, image=ib))
    assert len(tp) >= MIN_TIE_POINTS // 2
    row, col = _grid_positions(a, tp)
    inside = (row > r0 - 5) & (row < r0 + n + 5) & (col > c0 - 5) & (col < c0 + n + 5)
    assert not inside.any(), tp.counts
    under_cloud = np.hypot(row - 420, col - 300) < 60.0
    assert not under_cloud.any()
    assert _truth_miss_px(tp, passes).max() < WRONG_MATCH_PX
    assert tp.counts["ambiguous"] + tp.counts["flat"] > 0


def _grid_positions(view: MapView, tp: TiePoints) -> tuple[np.ndarray, np.ndarray]:
    """Where the tie points lie on the view's map grid (through its model, at their
    heights)."""
    from pyproj import CRS, Transformer

    g = view.model.image_to_ground(tp.line_a - view.first_line, tp.column_a, tp.h_m)
    crs = CRS.from_wkt(view.geometry.map_grid.crs_wkt)
    x, y = Transformer.from_crs(CRS.from_epsg(4326), crs, always_xy=True).transform(
        np.degrees(g.lon_rad), np.degrees(g.lat_rad)
    )
    gt = view.geometry.map_grid.geotransform
    return (y - gt[3]) / gt[5] - 0.5, (x - gt[0]) / gt[1] - 0.5


def test_tie_points_are_written_as_control_points_of_their_own_kind(views, tmp_path) -> None:
    tp = match_views(*views)
    a = write_gcps(tmp_path / "pa.tie.csv", tp.control_points("a"), "tie points pa–pb")
    b = write_gcps(tmp_path / "pb.tie.csv", tp.control_points("b"))
    ra, rb = read_gcps(a), read_gcps(b)
    assert ra.id == rb.id == tp.ids and ra.tie.all() and rb.tie.all()
    np.testing.assert_allclose(rb.line, tp.line_b, atol=5e-4)  # written to 0.001 px
    assert "kind" in a.read_text().splitlines()[1]
    assert len(ra.controls()) == 0  # a single pass's level 2 has no use for them
    with pytest.raises(ValueError):
        tp.control_points("c")


def test_views_that_do_not_overlap_are_one_clear_error(views) -> None:
    a, b = views
    far = dataclasses.replace(b, valid=np.zeros_like(b.valid))
    with pytest.raises(GeometryError, match="do not overlap"):
        match_views(a, far)


def test_station_tie_writes_each_passs_tie_file(passes, tmp_path, capsys) -> None:
    (_, run_a), (_, run_b) = passes.values()
    a, b = run_a / "pa_s000_2A.nc", run_b / "pb_s000_2A.nc"
    assert main(["tie", str(a), str(b), "--out", str(tmp_path)]) == 0
    assert "tie points (of 1000 candidates" in capsys.readouterr().out
    ta, tb = read_gcps(tmp_path / "pa.tie.csv"), read_gcps(tmp_path / "pb.tie.csv")
    assert ta.id == tb.id and len(ta) >= MIN_TIE_POINTS and ta.tie.all()
    assert main(["tie", str(a), str(a), "--out", str(tmp_path)]) == 2
    assert "the same pass" in capsys.readouterr().err
