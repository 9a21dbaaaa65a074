"""Level 2 made by the unit of work (:mod:`levels.work`) from the shipped L0 archive alone
(``levels/data/warmup.l0.h5``: 200 detectors, 300 m pixels): control points that put the
ground 600 m east and 400 m south of where GEO's model sees it move the product there; the
product carries its adjustment; a blunder is rejected by name; level 2 without points is
refused while planning."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from levels.errors import GcpError
from levels.geo.scenes import models_of_tree
from levels.geometry.model import PushbroomModel
from levels.options import ProcessingOptions
from levels.products import read_product
from levels.readers.gcp import GCP_COLUMNS, ControlPointSet, read_gcps
from levels.readers.l0 import read_l0
from levels.warmup import WARM_UP_ARCHIVE
from levels.work import Pass, Request, plan, run

#: Where the points put the ground, from where GEO's model sees it (east, north; m).
SHIFT_M = (600.0, -400.0)
#: The adjusted model against the points (m): the points are exact, so only the priors'
#: pull is left (measured 4 m, 0.013 of the 300 m pixel).
ON_THE_POINTS_M = 15.0
RADIUS_M = 6_378_137.0


def _model(path: Path) -> PushbroomModel:
    _, models = models_of_tree(read_product(path, images=False).geometry)
    return models["P"]


def _request(
    levels: tuple[str, ...], out: Path, gcps: ControlPointSet | None = None, **more: object
) -> Request:
    archive = read_l0(WARM_UP_ARCHIVE)
    one = Pass((archive,), ("w",), () if gcps is None else (gcps,))
    return Request(ProcessingOptions(levels=levels), out, (one,), **more)  # type: ignore[arg-type]


def _make(levels: tuple[str, ...], out: Path, gcps: ControlPointSet | None = None) -> list:
    return list(run(plan(_request(levels, out, gcps))).products)


@pytest.fixture(scope="module")
def points(tmp_path_factory: pytest.TempPathFactory) -> tuple[ControlPointSet, PushbroomModel]:
    """Ten points over the scene at 0–500 m, seen by GEO's model (the 2A's) and moved by
    ``SHIFT_M``; the last of them 2 km further (a blunder)."""
    (made,) = _make(("2A",), tmp_path_factory.mktemp("w2a"))
    model = _model(made.path)
    rng = np.random.default_rng(1)
    n = 10
    line = rng.uniform(0, model.n_lines - 1, n)
    col = rng.uniform(0, model.n_columns - 1, n)
    g = model.image_to_ground(line, col, rng.uniform(0.0, 500.0, n))
    east = np.full(n, SHIFT_M[0])
    east[-1] += 2000.0
    gcps = ControlPointSet(
        tuple(f"g{k}" for k in range(n)),
        g.lon_rad + east / (RADIUS_M * np.cos(g.lat_rad)),
        g.lat_rad + SHIFT_M[1] / RADIUS_M,
        g.h_m,
        line,
        col,
        np.full(n, 8.0),
        np.full(n, 5.0),
        np.full(n, 0.3),
        np.ones(n, dtype=np.int64),
    )
    return gcps, model


def _miss_m(model: PushbroomModel, gcps: ControlPointSet) -> np.ndarray:
    g = model.image_to_ground(gcps.line, gcps.column, gcps.h_m)
    east = (g.lon_rad - gcps.lon_rad) * RADIUS_M * np.cos(g.lat_rad)
    return np.hypot(east, (g.lat_rad - gcps.lat_rad) * RADIUS_M)


def test_level_2_moves_the_scene_onto_its_points_and_carries_its_adjustment(
    points, tmp_path: Path
) -> None:
    gcps, geo = points
    (made,) = _make(("2",), tmp_path, gcps)
    assert made.kind == "2" and made.path.name == "w_s000_2.nc"
    good = slice(0, -1)  # all but the blunder
    before = _miss_m(geo, gcps)[good]
    assert np.allclose(before, np.hypot(*SHIFT_M), rtol=1e-3)
    after = _miss_m(_model(made.path), gcps)[good]
    assert after.max() <= ON_THE_POINTS_M
    p = read_product(made.path, images=False)
    assert p.level == "2" and p.map_grid is not None
    adj = p.geometry["adjustment"]
    assert adj["covariance"].shape == (12, 12)
    assert np.all(np.linalg.eigvalsh(adj["covariance"]) > 0)
    assert json.loads(adj["points"]["status"]) == ["used"] * 9 + ["rejected"]


def test_level_2_without_points_is_refused_while_planning(tmp_path: Path) -> None:
    with pytest.raises(GcpError, match="level 2 of w needs control points"):
        _make(("2",), tmp_path / "none")
    assert not (tmp_path / "none").exists()  # refused before any work
    # a file with a header and no point reads (a twin's HRV without points), but level 2
    # of that HRV alone is refused
    empty_file = tmp_path / "none.gcp.csv"
    empty_file.write_text("# nothing measured\n" + ",".join(GCP_COLUMNS) + "\n")
    empty = read_gcps(empty_file)
    assert len(empty) == 0
    with pytest.raises(GcpError, match="no control point of this HRV"):
        _make(("2",), tmp_path / "empty", empty)


def test_level_2_takes_its_adjustment_from_a_directory(
    points, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A step taken from a directory, as ASP's entry points are: level 2 made again on the
    adjustment its products carry (no point given, nothing solved) is the same product,
    byte for byte in its image; a directory without them is refused while planning."""
    import levels.adjust.passes

    gcps, _ = points
    (first,) = _make(("2",), tmp_path / "a", gcps)
    solved: list[int] = []
    adjust_strips = levels.adjust.passes.adjust_strips
    monkeypatch.setattr(
        levels.adjust.passes,
        "adjust_strips",
        lambda *a, **k: solved.append(1) or adjust_strips(*a, **k),
    )
    work = plan(_request(("2",), tmp_path / "b", adjustment_dir=tmp_path / "a"))
    assert f"adjustment:w: - (taken from {tmp_path / 'a'})" in work.text()
    (again,) = run(work).products
    assert solved == []
    a, b = (read_product(m.path) for m in (first, again))
    assert np.array_equal(a.bands["P"].image, b.bands["P"].image)
    ta, tb = a.geometry["adjustment"], b.geometry["adjustment"]
    assert np.array_equal(ta["covariance"], tb["covariance"])
    assert np.array_equal(ta["pass_parameters"], tb["pass_parameters"])
    with pytest.raises(GcpError, match="no level 2 of w in"):
        plan(_request(("2",), tmp_path / "c", adjustment_dir=tmp_path / "b" / "none"))
