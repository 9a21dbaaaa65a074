"""A day at the station (`station day`) and the capacity model checked against it (`station
capacity validate`): the plan drawn as the model draws it, the trace-driven model against
hand-computed queues, a reduced day end to end through a real front end and real workers,
and a day killed mid-way and resumed."""

from __future__ import annotations

import itertools
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from _tiny_day import DAY
from _tiny_day import tiny_day_file as _tiny

from station.archive_catalogue import CATALOGUE_FILE, Catalogue
from station.capacity.plan import (
    DayPlan,
    PlannedOrder,
    PlannedPass,
    PlannedSegment,
    draw_plan,
    read_plan,
)
from station.capacity.validate import (
    DayUnits,
    PlannedSimulation,
    as_day,
    compare,
    own_days,
    predict,
)
from station.cli import main
from station.day.config import load_day
from station.day.preflight import SCENE_S
from station.errors import ScenarioError

#: A day's bound in these tests (s): about 30 s on 2 shared cores; a hang fails.
DAY_TIMEOUT_S = 300


def test_the_shipped_day_is_what_the_issue_asks() -> None:
    """Six passes or more, one with both HRVs, about forty orders, some urgent, two
    workers, a clock of 60 or more."""
    scn = load_day(DAY)
    plan = draw_plan(scn.capacity, scn.day.start_s, scn.day.hours)
    assert len(plan.passes) >= 6
    assert any(len(p.segments) == 2 for p in plan.passes)
    assert 30 <= len(plan.orders) <= 50 and any(o.urgent for o in plan.orders)
    assert scn.day.workers == 2 and scn.day.clock >= 60


def test_the_plan_is_drawn_as_the_model_draws_and_reads_back(tmp_path: Path) -> None:
    scn = load_day(DAY)
    plan = draw_plan(scn.capacity, scn.day.start_s, scn.day.hours)
    assert plan == draw_plan(scn.capacity, scn.day.start_s, scn.day.hours)  # from the seed
    ends = [(p.aos_s, p.aos_s + p.duration_s) for p in plan.passes]
    assert all(b[0] >= a[1] for a, b in itertools.pairwise(ends))  # one antenna
    for o in plan.orders:
        p, s = plan.segment(o.pass_name, o.hrv)
        assert 0 <= o.scene < s.scenes and o.order_s >= p.aos_s
    assert read_plan(plan.write(tmp_path / "plan.json")) == plan
    (tmp_path / "bad.json").write_text('{"format": "other"}')
    with pytest.raises(ScenarioError, match="not a day plan"):
        read_plan(tmp_path / "bad.json")


def _service(cor_s: float, cv: float = 0.0) -> dict:
    e = {"mean_s": cor_s, "cv": cv}
    return {
        "ingest": {"fixed_s": 0.0, "s_per_signal_s": 0.0, "cv": 0.0},
        "geo": {m: {"fixed_s": 0.0, "s_per_scene": 0.0, "cv": 0.0} for m in ("P", "XS")},
        "cor_s": {m: {lv: e for lv in ("1A", "1B", "2A")} for m in ("P", "XS")},
    }


def test_the_days_model_queues_as_computed_by_hand() -> None:
    """One pass of one scene (its signal 9.2 s at a clock of 1), three orders at once on
    one worker, fixed 10 s jobs: the urgent one first, then the others in turn."""
    p = PlannedPass("p", "SPOT 1", 0.0, 600.0, (PlannedSegment(1, "P", 1),))
    orders = (
        PlannedOrder("a", "p", 1, 0, "1A", False, 100.0),
        PlannedOrder("b", "p", 1, 0, "2A", False, 100.0),
        PlannedOrder("u", "p", 1, 0, "2A", True, 100.0),
    )
    plan = DayPlan(0.0, 1.0, (p,), orders, 0)
    sim = PlannedSimulation(plan, DayUnits(2, 2, 1, 1.0), _service(10.0), seed=1, tick_s=0.0)
    f = sim.run()
    signal = SCENE_S + 0.2
    assert f["ingest.utilisation"] == pytest.approx(signal / (2 * 3600.0))
    assert f["cor.utilisation"] == pytest.approx(30.0 / 3600.0)
    # the first served at once (100 s); the other two wait 10 and 20 s: mean 10 s
    assert f["cor.wait_mean_h"] == pytest.approx(10.0 / 3600.0)
    assert sorted(sim.from_order["2A"]) == pytest.approx([10.0, 30.0])  # urgent first
    assert sim.from_order["1A"] == pytest.approx([20.0])


def test_jobs_sharing_the_machine_each_go_slower_as_measured() -> None:
    """Two 10 s jobs at once on two workers whose jobs are 1.5 times slower two at a time:
    both end at 15 s; a third, queued, then runs alone."""
    p = PlannedPass("p", "SPOT 1", 0.0, 600.0, (PlannedSegment(1, "P", 1),))
    orders = tuple(PlannedOrder(n, "p", 1, 0, "2A", False, 100.0) for n in "abc")
    service = _service(10.0) | {"cor_contention": {"2": 1.5}}
    sim = PlannedSimulation(
        plan := DayPlan(0.0, 1.0, (p,), orders, 0),
        DayUnits(2, 2, 2, 1.0),
        service,
        seed=1,
        tick_s=0.0,
    )
    sim.run()
    assert plan.orders and sorted(sim.from_order["2A"]) == pytest.approx([15.0, 15.0, 25.0])


def test_the_prediction_interval_covers_the_models_own_days() -> None:
    """Days played by the model itself (seeds of their own) fall inside its 95 % interval
    about as often as said: each figure's coverage over 30 such days, and the rows
    ``compare`` makes of one."""
    scn = load_day(DAY)
    plan = draw_plan(scn.capacity, scn.day.start_s, scn.day.hours)
    units = DayUnits(2, 2, 2, 60.0)
    service = _service(3.0, cv=0.3)
    predicted = predict(plan, units, service, 200, seed=1)
    days = predict(plan, units, service, 40, seed=10_000)
    for key in ("cor.utilisation", "2A.from_order.mean_h", "2A.from_acquisition.p95_h"):
        lo, hi = np.percentile(predicted[key], [2.5, 97.5])
        coverage = np.mean((days[key] >= lo) & (days[key] <= hi))
        assert coverage >= 0.8, (key, coverage)  # 95 % said; 40 days, 200 replications
    day = as_day({k: v[0] for k, v in days.items()})
    rows = compare(day, predicted)
    assert len(rows) == 18 and all(
        r["interval"][0] - 1e-12 <= r["predicted"] <= r["interval"][1] + 1e-12 for r in rows
    )
    scores = own_days(predicted, days)
    assert scores.shape == (40,) and scores.max() <= 18
    assert scores.mean() >= 18 * 0.8  # each figure inside ~95 % of the time, as above


@pytest.fixture(scope="module")
def tiny_day(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """The reduced day, run whole once: (its file, its directory)."""
    tmp = tmp_path_factory.mktemp("day")
    path = _tiny(tmp)
    out = tmp / "whole"
    rc = subprocess.run(
        [sys.executable, "-m", "station.cli", "day", str(path), "--out", str(out), "-q"],
        timeout=DAY_TIMEOUT_S,
        capture_output=True,
        text=True,
    )
    assert rc.returncode == 0, rc.stderr[-3000:]
    return path, out


def _catalogue_ids(out: Path) -> set[str]:
    with Catalogue(out / "archive" / CATALOGUE_FILE, create=False) as cat:
        return cat.ids()


def test_a_day_archives_catalogues_and_makes_its_orders(tiny_day: tuple[Path, Path]) -> None:
    _, out = tiny_day
    report = json.loads((out / "day.json").read_text())
    plan = read_plan(out / "plan.json")
    c = report["counts"]
    assert c["passes_archived"] == c["passes"] == len(plan.passes) >= 2
    assert c["made"] == c["orders_in_window"] and c["not_held"] == c["failed"] == 0
    assert c["made_twice"] == 0
    ids = _catalogue_ids(out)
    for o in plan.orders:
        p = next(p for p in plan.passes if p.name == o.pass_name)
        tag = p.name if len(p.segments) == 1 else f"{p.name}_hrv{o.hrv}"
        scene = f"{tag}_s{o.scene:03d}"
        assert scene in ids  # GEO's scene, catalogued by the front end
        if o.order_s < plan.hours * 3600.0:
            assert f"{scene}_{o.level}" in ids  # the product, catalogued by its worker
    for stage in ("ingest", "geo", "cor"):
        assert 0.0 < report["stages"][stage]["utilisation"] < 1.0
    assert (out / "queues.png").stat().st_size > 1000


def test_capacity_validate_puts_the_model_beside_the_day(tiny_day, capsys, monkeypatch) -> None:
    """With the service times the day measured before its clock and after it; then with
    a session measured now (here, the day's first again: its measuring is the day's);
    then with those read back from their file."""
    import station.day.calibrate as calibrate

    _, out = tiny_day
    rc = main(["capacity", "validate", str(out), "--replications", "20", "--json", "-q"])
    result = json.loads(capsys.readouterr().out)
    assert [s["when"] for s in result["service"]["sessions"]] == ["before", "after"]
    assert rc in (0, 1) and rc == (0 if result["consistent"] else 1)
    assert 0 <= result["own_days"]["inside_p5"] <= result["own_days"]["inside_mean"] <= 18
    rows = result["rows"]
    assert {r.get("stage") for r in rows} >= {"ingest", "geo", "cor"}
    for r in rows:
        lo, hi = r["interval"]
        assert lo <= r["predicted"] <= hi and np.isfinite(r["measured"])
    assert result["inside"] == sum(r["inside"] for r in rows)
    first = result["service"]["sessions"][0]
    monkeypatch.setattr(calibrate, "day_service", lambda scn: dict(first))
    argv = ["capacity", "validate", str(out), "--replications", "20", "--json", "-q"]
    assert main([*argv, "--sessions", "1"]) in (0, 1)
    now = json.loads(capsys.readouterr().out)
    assert [s["when"] for s in now["service"]["sessions"]] == ["validate"]
    assert (out / "validation.json").is_file() and (out / "service_validate.json").is_file()
    # the day's own service times kept; read back from their file: the same prediction
    rc2 = main([*argv, "--service", str(out / "service_day.json")])
    again = json.loads(capsys.readouterr().out)
    assert [r["predicted"] for r in again["rows"]] == [r["predicted"] for r in rows]
    assert rc2 == rc


def test_a_day_killed_midway_resumes_to_the_same_products(tiny_day, tmp_path: Path) -> None:
    """Killed (its whole process group: the day, its front end, its workers) once its first
    product is made, then resumed: the same catalogue and products as the whole day's, and
    nothing made twice."""
    path, whole = tiny_day
    out = tmp_path / "killed"
    cmd = [
        sys.executable,
        "-m",
        "station.cli",
        "day",
        str(path),
        "--no-calibrate",
        "--out",
        str(out),
        "-q",
    ]
    proc = subprocess.Popen(
        cmd, start_new_session=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
    )
    events = out / "events.jsonl"
    deadline = time.time() + DAY_TIMEOUT_S
    try:
        while time.time() < deadline and proc.poll() is None:
            if events.is_file() and '"made"' in events.read_text():
                break
            time.sleep(0.05)
        assert proc.poll() is None, "the day ended before it could be killed"
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)  # the group this test started
        proc.wait(30)
    resumed = subprocess.run(
        [*cmd, "--resume"], timeout=DAY_TIMEOUT_S, capture_output=True, text=True
    )
    assert resumed.returncode == 0, resumed.stderr[-3000:]
    report = json.loads((out / "day.json").read_text())
    assert report["counts"]["runs"] == 2 and report["counts"]["made_twice"] == 0
    assert _catalogue_ids(out) == _catalogue_ids(whole)
    made = sorted(p.name for p in (out / "products").rglob("*") if p.is_file())
    assert made == sorted(p.name for p in (whole / "products").rglob("*") if p.is_file())
    again = subprocess.run(
        [*cmd[:-1], "--resume", "--json"], timeout=DAY_TIMEOUT_S, capture_output=True, text=True
    )
    assert again.returncode == 0
    assert json.loads(again.stdout)["counts"]["made"] == report["counts"]["made"]


def test_bad_days_are_refused_in_one_line(tmp_path: Path, capsys, monkeypatch) -> None:
    """More than the machine holds is refused before any work, with the estimate; a day
    directory is not overwritten; validate wants a day's directory."""
    import station.day.preflight as preflight

    path = _tiny(tmp_path)
    monkeypatch.setattr(preflight, "_available_mb", lambda: 500.0)
    assert main(["day", str(path), "--out", str(tmp_path / "b")]) == 2
    err = capsys.readouterr().err
    assert "MB of memory" in err and "500 MB are available" in err
    monkeypatch.undo()
    monkeypatch.setattr(preflight, "cores", lambda: 2)
    assert main(["day", str(path), "--out", str(tmp_path / "c"), "--workers", "5"]) == 2
    assert "5 workers on 2 core(s)" in capsys.readouterr().err
    assert not (tmp_path / "b" / "events.jsonl").exists()  # refused before work
    (tmp_path / "d").mkdir()
    (tmp_path / "d" / "plan.json").write_text("{}")
    assert main(["day", str(path), "--out", str(tmp_path / "d")]) == 2
    assert "--resume" in capsys.readouterr().err
    assert main(["day", str(path), "--out", str(tmp_path / "e"), "--resume"]) == 2
    assert "holds no day" in capsys.readouterr().err
    assert main(["capacity", "validate", str(tmp_path)]) == 2
    assert "not a station day" in capsys.readouterr().err


def test_the_days_front_end_lives_until_its_input_closes(tmp_path: Path) -> None:
    """``station serve --until-stdin-closes``, as a day starts it: listening until the
    pipe from its starter is closed, then gone by itself (exit 0), no pass needed."""
    from station.day.front import launch_front_end, port_of, stop_front_end

    proc = launch_front_end(tmp_path)
    try:
        assert port_of(proc, tmp_path) > 0
        time.sleep(0.5)
        assert proc.poll() is None  # still listening: no --passes to count down
    finally:
        stop_front_end(proc, 20.0)
    assert proc.returncode == 0, (tmp_path / "serve.log").read_text()[-2000:]
