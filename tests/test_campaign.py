"""``station campaign``: many L0 archives reprocessed as one job, one report, the failures
named and the others finished, the products those of ``station process``."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import h5py
import numpy as np
import pytest

from levels.products import product_name
from station.cli import EXIT_BAD_INPUT, main


@pytest.fixture(scope="module")
def archives(run_dir, tmp_path_factory) -> Path:
    """A directory of two good archives (one in a subdirectory) and a truncated one."""
    d = tmp_path_factory.mktemp("archive")
    l0 = run_dir / "small_test.l0.h5"
    shutil.copy(l0, d / "pass_a.l0.h5")
    (d / "older").mkdir()
    shutil.copy(l0, d / "older" / "pass_b.l0.h5")
    (d / "pass_c.l0.h5").write_bytes(l0.read_bytes()[:50_000])
    return d


def test_a_campaign_names_its_failures_and_finishes_the_rest(archives, tmp_path, capsys):
    listing = tmp_path / "more.txt"
    listing.write_text(f"# the same archive again, by a list\n{archives / 'pass_a.l0.h5'}\n")
    out = tmp_path / "campaign"
    code = main(["campaign", str(archives), str(listing), "--out", str(out)])
    captured = capsys.readouterr()
    assert code == EXIT_BAD_INPUT
    err = [ln for ln in captured.err.splitlines() if ln.startswith("station: error")]
    assert len(err) == 1 and "1 of 3 archive(s) failed: pass_c" in err[0] and "truncated" in err[0]
    assert "\r" not in captured.err and "scene/s" not in captured.err  # no bar into a log
    report = json.loads((out / "campaign.json").read_text())
    assert report["summary"] == report["summary"] | {"archives": 3, "ok": 2, "failed": 1}
    status = {a["name"]: a["status"] for a in report["archives"]}
    assert status == {"pass_a": "ok", "pass_b": "ok", "pass_c": "failed"}
    assert "pass_c" in captured.out and "FAILED (bad input)" in captured.out
    # the products are station process's, byte for byte in every image
    single = tmp_path / "single"
    assert main(["process", str(archives / "pass_a.l0.h5"), "--out", str(single)]) == 0
    capsys.readouterr()
    for level in ("1A", "1B", "2A"):
        name = product_name("pass_a", 0, level, on_map=level == "2A")
        with h5py.File(out / "pass_a" / name) as a, h5py.File(single / name) as b:
            for var in ("P", "P_valid"):
                assert np.array_equal(a[var][()], b[var][()])


def test_a_campaign_without_archives_is_bad_input(tmp_path, capsys):
    assert main(["campaign", str(tmp_path), "--out", str(tmp_path / "o")]) == EXIT_BAD_INPUT
    assert "no L0 archives" in capsys.readouterr().err


def test_archives_are_planned_one_after_another_in_process(archives, tmp_path, monkeypatch):
    """A year of passes is never planned all at once: in process, each archive's scenes
    are made before the next archive is read (what a worker holds stays one pass)."""
    import levels.process
    import station.reprocess

    events = []
    plan, scene = station.reprocess.plan_reprocess, levels.process.make_scene

    def planned(paths, *a, **k):
        events.append(("plan", Path(paths[0]).name))
        return plan(paths, *a, **k)

    def made(ctx, s):
        events.append(("scene", ctx.name))
        return scene(ctx, s)

    monkeypatch.setattr(station.reprocess, "plan_reprocess", planned)
    monkeypatch.setattr(levels.process, "make_scene", made)
    good = [archives / "pass_a.l0.h5", archives / "older" / "pass_b.l0.h5"]
    assert main(["campaign", *map(str, good), "--out", str(tmp_path / "o"), "--quiet"]) == 0
    assert events == [
        ("plan", "pass_a.l0.h5"),
        ("scene", "pass_a"),
        ("plan", "pass_b.l0.h5"),
        ("scene", "pass_b"),
    ]
