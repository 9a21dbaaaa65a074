"""One unit of work (:mod:`levels.work`) on two recorded passes alone: ``levels`` plans the
tie points, the block's one adjustment, level 2, the pair's DEM and level 3 over it, makes
each once, and refuses what it cannot make while planning, before any work.

The two passes are those of ``scenarios/stereo/stereo_pair.toml`` recorded by the station
in a subprocess (only their L0 archives, control points, 1A and 2A): this module reads them
as any user of the library would read a station's archives, and imports no ``station``."""

from __future__ import annotations

import dataclasses
import re
import subprocess
import sys
from pathlib import Path

import pytest

from levels.errors import DemError, GcpError, OptionsError
from levels.options import ProcessingOptions
from levels.products import read_product
from levels.readers.gcp import read_gcps
from levels.readers.l0 import read_l0
from levels.work import Pass, Request, Step, plan, run

ROOT = Path(__file__).resolve().parents[2]
NAMES = ("stereo_pair_a", "stereo_pair_b")
#: The pair's levels, as `station process A B --levels 2,DEM,3` asks them.
PAIR_LEVELS = ("2", "DEM", "3")


@pytest.fixture(scope="module")
def recorded(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The stereo pair's two passes recorded (L0, control points, 1A and 2A), by the
    station's command in a process of its own."""
    text = (ROOT / "scenarios" / "stereo" / "stereo_pair.toml").read_text()
    recorded_only = re.sub(r"(?m)^levels = .*$", 'levels = ["1A", "2A"]', text)
    recorded_only = re.sub(r"(?m)^stereo = true$", "stereo = false", recorded_only)
    assert recorded_only.count('["1A", "2A"]') == 1 and "stereo = false" in recorded_only
    where = tmp_path_factory.mktemp("pair")
    toml = where / "stereo_pair.toml"
    toml.write_text(recorded_only)
    run_dir = where / "run"
    command = [sys.executable, "-m", "station.cli", "run", str(toml), "--out", str(run_dir)]
    subprocess.run([*command, "-q", "--no-quicklooks"], check=True, timeout=300, cwd=ROOT)
    return run_dir


def _request(run_dir: Path, out: Path, **options: object) -> Request:
    passes = []
    for name in NAMES:
        archive = read_l0(run_dir / name / f"{name}.l0.h5", lazy=True)
        gcps = read_gcps(run_dir / name / f"{name}.gcp.csv", archive.n_lines, archive.n_columns)
        passes.append(Pass((archive,), (name,), (gcps,)))
    opts = ProcessingOptions(levels=PAIR_LEVELS, adjustment="block", tie_height_sigma_m=5.0)
    return Request(dataclasses.replace(opts, **options), out, tuple(passes))


def test_two_passes_make_their_dem_and_level_3_each_node_once(
    recorded: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """From the archives alone: the passes' own 1A and 2A, the tie points, one block
    adjustment, level 2 written once per scene, the pair's DEM, level 3 over it on level
    2's model; the plan says so before any work."""
    import levels.process

    calls: list[str] = []
    adjust_block, write_product = levels.process.adjust_block, levels.process.write_product

    def adjusting(*args: object, **kwargs: object) -> object:
        calls.append("adjust")
        return adjust_block(*args, **kwargs)

    def writing(path: Path, *args: object, **kwargs: object) -> object:
        calls.append(Path(path).name)
        return write_product(path, *args, **kwargs)

    monkeypatch.setattr(levels.process, "adjust_block", adjusting)
    monkeypatch.setattr(levels.process, "write_product", writing)
    work = plan(_request(recorded, tmp_path / "out"))
    assert [n.step for n in work.nodes] == [
        Step.SCENES,
        Step.SCENES,
        Step.TIES,
        Step.ADJUSTMENT,
        Step.LEVEL2,
        Step.LEVEL2,
        Step.PAIR,
        Step.OVER_PAIR,
        Step.OVER_PAIR,
    ]
    assert not calls  # planned: nothing made yet
    result = run(work)
    assert calls.count("adjust") == 1
    written = [c for c in calls if c != "adjust"]
    assert len(written) == len(set(written))  # no product written twice
    (dem,) = result.of(Step.PAIR)
    assert dem.kind == "DEM" and dem.export is not None and dem.export.is_file()
    level3 = result.of(Step.OVER_PAIR)
    assert sorted(m.key for m in level3) == list(NAMES)
    for m in level3:
        product = read_product(m.path)
        assert product.level == "3"
        assert product.geometry["adjustment"]  # on level 2's model, the block's
        assert Path(str(product.quality["dem"]["source"])).name == dem.export.name
    assert {m.kind for m in result.of(Step.SCENES)} == {"1A", "2A"}
    assert [m.kind for m in result.of(Step.LEVEL2)] == ["2", "2"]
    assert result.ties["pairs"][0]["points"] > 0


def test_the_block_takes_its_ties_and_adjustment_from_a_run(
    recorded: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Level 2 of the block again, its tie points and its adjustment taken from the first
    run's ``ties/`` and ``block/`` (as ASP's entry points take a step's files): no point
    needed, nothing matched or solved, the same images byte for byte."""
    import numpy as np

    import levels.process
    import levels.work

    first = run(plan(_request(recorded, tmp_path / "a", levels=("2",))))
    calls: list[str] = []
    monkeypatch.setattr(levels.process, "adjust_block", lambda *a, **k: calls.append("adjust"))
    monkeypatch.setattr(levels.work, "tie_points", lambda *a, **k: calls.append("ties"))
    two = _request(recorded, tmp_path / "b", levels=("2",))
    bare = tuple(dataclasses.replace(p, gcps=()) for p in two.passes)
    taken = dataclasses.replace(
        two, passes=bare, ties_dir=tmp_path / "a" / "ties", adjustment_dir=tmp_path / "a" / "block"
    )
    work = plan(taken)
    assert [n.taken is not None for n in work.of(Step.TIES) + work.of(Step.ADJUSTMENT)] == [
        True,
        True,
    ]
    again = run(work)
    assert calls == []
    pairs = zip(first.of(Step.LEVEL2), again.of(Step.LEVEL2), strict=True)
    for a, b in pairs:
        assert a.path.name == b.path.name
        ia, ib = (read_product(m.path).bands for m in (a, b))
        assert all(np.array_equal(ia[k].image, ib[k].image) for k in ia)


def test_what_cannot_be_made_is_refused_while_planning(recorded: Path, tmp_path: Path) -> None:
    """A kind of pair with one pass, level 2 without control points, level 3 without a
    DEM, an unknown kind: each refused by :func:`levels.work.plan`, nothing written."""
    out = tmp_path / "out"
    two = _request(recorded, out)
    one = dataclasses.replace(two, passes=two.passes[:1])
    with pytest.raises(OptionsError, match="pair of passes"):
        plan(one)
    bare = tuple(dataclasses.replace(p, gcps=()) for p in two.passes)
    with pytest.raises(GcpError, match="control points"):
        plan(dataclasses.replace(two, passes=bare))
    alone = dataclasses.replace(one, options=dataclasses.replace(one.options, levels=("3",)))
    with pytest.raises(DemError, match="DEM"):
        plan(alone)
    with pytest.raises(OptionsError, match="not a level"):
        plan(dataclasses.replace(two, options=dataclasses.replace(two.options, levels=("X",))))
    with pytest.raises(OptionsError, match="level 2 too"):
        plan(dataclasses.replace(two, options=dataclasses.replace(two.options, levels=("DEM",))))
    assert not out.exists()


def test_the_shipped_archive_through_the_one_plan(tmp_path: Path) -> None:
    """``levels.api``'s example: the archive shipped with the package, one pass of one
    request, its plan one node, every product in the one result with its scene."""
    from levels.api import open_archive
    from levels.warmup import WARM_UP_ARCHIVE

    one = Pass((open_archive(WARM_UP_ARCHIVE),), ("w",))
    work = plan(Request(ProcessingOptions(levels=("1A", "2A")), tmp_path, (one,)))
    assert [n.id for n in work.nodes] == ["scenes:w"]
    assert work.text() == ["scenes:w: 1A, 2A"]  # what the plan says before any work
    result = run(work)
    assert [(m.kind, m.key, m.scene is not None) for m in result.of(Step.SCENES)] == [
        ("1A", "w", True),
        ("2A", "w", True),
    ]
    assert all(m.path.is_file() for m in result.products)
    assert result.pass_products("w", Step.SCENES).scenes[0].paths.keys() == {"1A", "2A"}


def test_points_handed_on_in_memory_are_those_their_file_records(tmp_path: Path) -> None:
    """Control points found on a reference go to the adjustment in memory, as their file
    records them: a reprocessing from the file reads the same numbers, bit for bit."""
    import numpy as np

    from levels.readers.gcp import ControlPointSet, write_gcps

    rng = np.random.default_rng(58)
    n = 40
    points = ControlPointSet(
        tuple(f"p{k}" for k in range(n)),
        np.radians(rng.uniform(-60.0, -50.0, n)),
        np.radians(rng.uniform(-20.0, -10.0, n)),
        rng.uniform(0.0, 2000.0, n),
        rng.uniform(0.0, 599.0, n),
        rng.uniform(0.0, 599.0, n),
        rng.uniform(1.0, 30.0, n),
        rng.uniform(1.0, 30.0, n),
        rng.uniform(0.1, 1.0, n),
        np.ones(n, dtype=np.int64),
        reference=np.ones(n, dtype=bool),
    )
    kept = points.as_recorded()
    read = read_gcps(write_gcps(tmp_path / "p.gcp.csv", points), 600, 600)
    for field in ("lon_rad", "lat_rad", "h_m", "line", "column", "sigma_ground_m", "sigma_px"):
        assert np.array_equal(getattr(kept, field), getattr(read, field)), field
