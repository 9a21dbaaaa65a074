"""Capacity planning: the simpy model against queueing theory, the station's figures, and
the command line (`station capacity`)."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest

from station.capacity.config import capacity_from_dict, load_capacity, with_value
from station.capacity.model import Shift, pass_pattern, simulate
from station.capacity.stage import mmc_wait_h
from station.capacity.stats import erlang_c, erlang_c_wait_s, mean_ci, time_weighted
from station.capacity.study import (
    MIN_REPLICATIONS_CI,
    load_service,
    parse_sweeps,
    run_study,
    study_table,
)
from station.cli import main
from station.errors import ScenarioError

ROOT = Path(__file__).resolve().parents[1]
CUIABA = ROOT / "scenarios" / "capacity" / "cuiaba.toml"
#: Little's law per stage, as the issue asks: L = λW within 2 %.
LITTLE_REL = 0.02


@pytest.mark.parametrize(("c", "rho"), [(1, 0.7), (3, 0.85)])
def test_an_mmc_stage_reproduces_erlang_c(c: int, rho: float) -> None:
    """Poisson arrivals, exponential service, c servers: the mean wait of the replications
    holds Erlang C's within their 95 % confidence interval."""
    mu = 1.0 / 3600.0  # one job an hour per server
    lam = rho * c * mu
    waits = [mmc_wait_h(lam, mu, c, 6000, seed) for seed in range(10)]
    mean, half = mean_ci(waits)
    theory_h = erlang_c_wait_s(lam, mu, c) / 3600.0
    assert abs(mean - theory_h) <= half, (mean, half, theory_h)
    assert half < 0.25 * theory_h  # and the interval says something


def test_erlang_c_closed_forms() -> None:
    assert erlang_c(1, 0.5) == pytest.approx(0.5)  # M/M/1: C = ρ
    assert erlang_c(2, 1.0) == pytest.approx(1 / 3)
    assert erlang_c_wait_s(0.8, 1.0, 1) == pytest.approx(4.0)  # ρ/(μ − λ)
    with pytest.raises(ValueError):
        erlang_c(2, 2.0)


def test_time_weighted_figures() -> None:
    tw = time_weighted([0.0, 1.0, 3.0], [2, 0, 4], 4.0)  # 2 for 1, 0 for 2, 4 for 1
    assert tw["mean"] == pytest.approx(1.5) and tw["max"] == 4.0 and tw["p95"] == 4.0


def test_shift_calendar() -> None:
    # t = 0 on a Monday 00:00 at longitude 0: shifts 8–18 h, Monday to Friday
    shift = Shift(8.0, 18.0, 5, 0.0, weekday0=0)
    h = 3600.0
    assert shift.wait_s(7 * h) == pytest.approx(1 * h)
    assert shift.wait_s(9 * h) == 0.0
    assert shift.wait_s(19 * h) == pytest.approx(13 * h)  # to Tuesday 8 h
    assert shift.wait_s(4 * 86400 + 19 * h) == pytest.approx(2 * 86400 + 13 * h)  # Fri → Mon
    west = Shift(8.0, 18.0, 7, np.radians(-60.0), weekday0=0)  # local = UTC − 4 h
    assert west.wait_s(11 * h) == pytest.approx(1 * h)


@pytest.fixture(scope="module")
def cuiaba():
    return load_capacity(CUIABA)


def _short(scn, **changes):
    scn = with_value(scn, "simulation.days", "90")
    for k, v in changes.items():
        scn = with_value(scn, k.replace("__", "."), v)
    return scn


def test_passes_come_from_the_orbit(cuiaba) -> None:
    pattern = pass_pattern(cuiaba.ground_station)
    aos, dur, daylight = pattern.aos_s, pattern.duration_s, pattern.daylight
    assert pattern.cycle_s == 26 * 86400.0
    per_day = aos.size / 26.0
    assert per_day == pytest.approx(3.88, abs=0.05)  # the emulator's 26-day figure (README)
    assert 0.4 < daylight.mean() < 0.6  # the descending half, in daylight
    assert 9.0 < np.median(dur) / 60.0 < 13.0  # minutes (README: median 11.25)


def test_littles_law_holds_per_stage(cuiaba) -> None:
    """L (time-weighted counters) against λW (the completed jobs' own records) over the
    scenario's year: apart only by the jobs still in a stage when the run ends."""
    scn = with_value(with_value(cuiaba, "resources.cor_workers", "3"), "outage.days", "0")
    rep = simulate(scn, load_service(scn), 0)
    for name, s in rep.stages.items():
        if s["arrivals_per_day"] > 0 and s["little_lambda_W"] > 0:
            assert s["little_L"] == pytest.approx(s["little_lambda_W"], rel=LITTLE_REL), name


def test_the_station_figures_hang_together(cuiaba) -> None:
    scn = _short(cuiaba, resources__cor_workers="3", outage__days="0")
    rep = simulate(scn, load_service(scn), 0)
    st = rep.station
    # two satellites, 3.9 passes a day each; the imaging ones: daylight × plan probability
    assert st["passes"] / 90 == pytest.approx(2 * 3.88, rel=0.05)
    assert st["imaging_passes"] / st["passes"] == pytest.approx(0.5 * 0.8, abs=0.06)
    assert st["segments"] + st["segments_lost"] <= 2 * st["imaging_passes"]
    assert st["orders"] / st["scenes"] == pytest.approx(0.6, abs=0.03)
    assert st["products"] <= st["orders"]
    n = sum(v["products"] for v in rep.levels.values())
    assert n == st["products"]
    mix = [rep.levels[lv]["products"] / n for lv in ("1A", "1B", "2A")]
    assert mix == pytest.approx([0.2, 0.3, 0.5], abs=0.03)
    for v in rep.levels.values():  # latency percentiles in order
        p = [v[f"latency_p{q}_h"] for q in (50, 90, 95, 99)]
        assert p == sorted(p) and p[0] > 0
    for s in rep.stages.values():
        assert 0.0 <= s["utilisation"] <= 1.0
    # the tape playback waits for the operators: weekends and nights
    assert rep.stages["transcription"]["wait_mean_h"] > 4.0
    straight = simulate(with_value(scn, "resources.recording", "disk"), load_service(scn), 0)
    assert "transcription" not in straight.stages
    assert straight.levels["2A"]["latency_p50_h"] < rep.levels["2A"]["latency_p50_h"]


def test_an_outage_builds_a_backlog_that_clears(cuiaba) -> None:
    scn = _short(
        cuiaba,
        resources__cor_workers="3",
        outage__start_day="30",
        outage__days="5",
        failures__cor_mtbf_h="0",
    )
    st = simulate(scn, load_service(scn), 0).station
    orders_per_day = 0.6 * st["scenes_per_day"]
    assert st["outage_backlog_peak"] >= 0.5 * 5 * orders_per_day  # most of 5 days' orders
    assert 0.0 <= st["outage_clear_days"] < 20.0


def test_a_sweep_finds_where_the_backlog_stops_growing(cuiaba, tmp_path: Path) -> None:
    scn = _short(cuiaba, outage__days="0")
    summary = run_study(scn, tmp_path, ("resources.cor_workers", ["1", "3"]), replications=2)
    growth = [r["station"]["cor_backlog_growth_per_day"]["mean"] for r in summary["runs"]]
    assert growth[0] > 5.0 and abs(growth[1]) < 0.5  # one workstation cannot keep up
    for name in (
        "summary.json",
        "stages.csv",
        "levels.csv",
        "station.csv",
        "queues.csv",
        "queues.png",
        "latency.png",
        "sweep.png",
    ):
        assert (tmp_path / name).stat().st_size > 0
    with open(tmp_path / "stages.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert {r["resources.cor_workers"] for r in rows} == {"1", "3"}
    cor = [r for r in rows if r["stage"] == "cor" and r["figure"] == "utilisation"]
    assert float(cor[0]["mean"]) > 0.95 > float(cor[1]["mean"])


def test_replications_give_intervals_and_are_reproducible(cuiaba) -> None:
    """Five replications give intervals, the same twice; three give means alone (Student's
    t of two degrees of freedom is 4.3: an interval wider than what it bounds), said so."""
    scn = with_value(_short(cuiaba), "simulation.days", "30")
    a = run_study(scn, None, replications=MIN_REPLICATIONS_CI)
    b = run_study(scn, None, replications=MIN_REPLICATIONS_CI)
    assert a == b
    cor = a["runs"][0]["stages"]["cor"]["utilisation"]
    assert cor["ci95"] > 0 and math.isfinite(cor["mean"])
    lat = a["runs"][0]["levels"]["2A"]["latency_p95_h"]
    assert lat["ci95"] > 0 and f"{lat['mean']:.1f} ±" in study_table(a)  # latency's too
    few = run_study(scn, None, replications=3)
    assert math.isnan(few["runs"][0]["stages"]["cor"]["utilisation"]["ci95"])
    table = study_table(few)
    assert "no intervals: 5 replications or more" in table and " ±" not in table
    assert few["runs"][0]["verdict"].startswith("no verdict: 3 replication(s)")


def test_an_outage_not_cleared_by_the_horizon_is_censored(cuiaba) -> None:
    """A backlog that some replications do not clear before the horizon ends: no mean over
    the others (biased low), the censored count said."""
    scn = _short(
        cuiaba,
        simulation__days="40",
        resources__cor_workers="2",
        outage__start_day="36",
        outage__days="3",
    )
    summary = run_study(scn, None, replications=2)
    clear = summary["runs"][0]["station"]["outage_clear_days"]
    assert clear["censored"] >= 1 and math.isnan(clear["mean"])
    assert "not cleared by the end of the horizon in" in study_table(summary)


def test_a_load_is_said_inside_or_outside_what_the_day_checked() -> None:
    from station.capacity.study import checked

    assert checked(0.2, 2).startswith("inside the load checked against a day")
    assert checked(0.9, 2).startswith("outside the load") and "COR 90 % busy" in checked(0.9, 2)
    assert checked(0.2, 8).startswith("outside the load")


def test_two_sweeps_make_a_grid_with_a_verdict_and_a_figure_each(cuiaba, tmp_path) -> None:
    """--sweep twice: every combination, each with its verdict and its titled queue figure;
    a key swept twice refused (a second --sweep silently replaced the first)."""
    scn = with_value(_short(cuiaba, outage__days="0"), "simulation.days", "30")
    sweeps = [("resources.cor_workers", ["1", "3"]), ("resources.geo_workers", ["1", "2"])]
    summary = run_study(scn, tmp_path, sweeps, replications=MIN_REPLICATIONS_CI)
    assert [r["value"] for r in summary["runs"]] == ["1 × 1", "1 × 2", "3 × 1", "3 × 2"]
    assert summary["sweep"] == "resources.cor_workers × resources.geo_workers"
    verdicts = [r["verdict"] for r in summary["runs"]]
    assert all(v.startswith("saturated: the COR backlog grows by") for v in verdicts[:2])
    assert not any(v.startswith("saturated") for v in verdicts[2:]), verdicts
    assert all((tmp_path / f"queues_{k}.png").stat().st_size > 0 for k in range(4))
    assert "verdict: saturated" in study_table(summary)
    # the year's COR is near saturation, outside the load the model was checked at
    checks = [r["checked"] for r in summary["runs"]]
    assert all(c.startswith("outside the load the model was checked") for c in checks[:2])
    assert "checked: " in study_table(summary)
    with pytest.raises(ScenarioError, match="given twice"):
        parse_sweeps(["resources.cor_workers=1,2", "resources.cor_workers=3"])


@pytest.mark.parametrize(
    ("table", "message"),
    [
        ({"resources": {"cor_workers": 0}}, "[resources] cor_workers = 0"),
        ({"orders": {"mix": [0.5, 0.5, 0.5]}}, "must add to 1"),
        ({"shifts": {"start_h": 18.0, "end_h": 8.0}}, "must be after start_h"),
        ({"shifts": {"staffed": ["antenna"]}}, "[shifts] staffed"),
        ({"satellite": {"name": "x"}}, "[[satellite]]"),
        ({"satellites": []}, "unknown key 'satellites'"),
    ],
)
def test_bad_capacity_scenarios_are_rejected_by_name(table: dict, message: str) -> None:
    with pytest.raises(ScenarioError) as err:
        capacity_from_dict(table)
    assert message in str(err.value)


def test_sweep_of_an_unknown_key_is_rejected(cuiaba) -> None:
    with pytest.raises(ScenarioError, match="no key 'workers'"):
        with_value(cuiaba, "resources.workers", "3")


def test_capacity_command(cuiaba, tmp_path: Path, capsys) -> None:
    scn = tmp_path / "short.toml"
    text = CUIABA.read_text().replace("days = 365.0", "days = 20.0")
    scn.write_text(
        text.replace(
            'file = "service_times.json"', f'file = "{CUIABA.parent / "service_times.json"}"'
        )
    )
    out = tmp_path / "out"
    assert main(["capacity", str(scn), "--out", str(out), "--replications", "2", "--no-plots"]) == 0
    text_out = capsys.readouterr().out
    assert "cuiaba_capacity: 20 days" in text_out and "L/λW" in text_out
    summary = json.loads((out / "summary.json").read_text())
    assert summary["replications"] == 2 and not (out / "queues.png").exists()
    for argv, message in [
        (["capacity", str(tmp_path / "none.toml")], "not found"),
        (["capacity", str(scn), "--sweep", "cor_workers=1,2"], "SECTION.KEY=V1"),
        (["capacity", str(scn), "--sweep", "resources.cor_workers=0"], "cor_workers = 0"),
        (["capacity", str(scn), "--replications", "0"], "at least 1"),
    ]:
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert message in err and "Traceback" not in err
    bad = tmp_path / "bad_service.toml"
    bad.write_text(text.replace('file = "service_times.json"', 'file = "missing.json"'))
    assert main(["capacity", str(bad)]) == 2
    assert "station capacity calibrate" in capsys.readouterr().err


def test_calibration_measures_this_code(tmp_path: Path, capsys) -> None:
    assert main(["capacity", "calibrate", "--out", str(tmp_path / "st.json")]) == 0
    table = json.loads((tmp_path / "st.json").read_text())
    for mode in ("P", "XS"):
        cor = table["cor_s"][mode]
        # 1B and 2A each include 1A and the deconvolution (which of the two is slower is a
        # timing, not asserted: machines are shared)
        assert 0 < cor["1A"] < min(cor["1B"], cor["2A"])
        assert table["geo_s_per_scene"][mode] > 0 and table["archive_s"][mode]["2A"] > 0
    assert table["ingest_s_per_signal_s"] > 0
    assert table["sar_gtc_s_per_frame"] > 0  # an ERS-1 frame's GTC (issue 38)
    assert "wrote" in capsys.readouterr().out


#: Counts drawn with probability p out of n: a binomial's 4σ, n p (1 − p) under the root.
def _binomial_4sigma(n: float, p: float) -> float:
    return 4.0 * math.sqrt(max(n * p * (1.0 - p), 1.0))


def test_landsat_takes_the_antenna_and_spot_loses_passes(cuiaba) -> None:
    """Paper 004: the antenna is shared with Landsat. Every Landsat pass drawn to be tracked
    is either tracked or finds the antenna taken; SPOT loses passes to the tracked ones, and
    more with a larger share."""
    from station.capacity.passes import pass_pattern
    from station.scenario import OrbitConfig

    base = _short(cuiaba, outage__days="0", failures__antenna_mtbf_h="0")
    service = load_service(base)
    none = simulate(with_value(base, "landsat.antenna_share", "0"), service, 0).station
    every = simulate(with_value(base, "landsat.antenna_share", "1"), service, 0).station
    ls = base.landsat
    landsat = pass_pattern(
        base.ground_station,
        OrbitConfig(
            repeat_revs=ls.repeat_revs,
            repeat_days=ls.repeat_days,
            descending_node_local_time_h=ls.descending_node_local_time_h,
        ),
    )
    assert landsat.cycle_s == 16 * 86400.0
    warmup, end = (
        base.simulation.warmup_days * 86400.0,
        (base.simulation.warmup_days + base.simulation.days) * 86400.0,
    )
    aos = np.concatenate([landsat.aos_s + k * landsat.cycle_s for k in range(8)])
    expected = np.count_nonzero((aos >= warmup) & (aos < end))
    assert every["landsat_passes_tracked"] + every["landsat_passes_missed"] == expected
    assert none["landsat_passes_tracked"] == 0 and none["passes_lost"] == 0  # no failures
    assert every["passes_lost"] > 0
    assert every["scenes"] < none["scenes"]


def test_tm_jobs_and_film_products_load_their_stages(cuiaba) -> None:
    """TM processing shares the COR units; a share of 1A and 1B orders goes to film."""
    base = _short(cuiaba, outage__days="0", resources__cor_workers="4")
    service = load_service(base)
    no_film = with_value(base, "orders.film_fraction", "0")
    plain = simulate(with_value(no_film, "landsat.tm_jobs_per_day", "0"), service, 0)
    with_tm = simulate(no_film, service, 0)  # TM draws from a stream of its own
    rep = simulate(base, service, 0)
    days, ls, od = base.simulation.days, base.landsat, base.orders
    # Poisson arrivals: the count within 4σ of its mean
    n_tm = with_tm.station["tm_jobs"]
    assert abs(n_tm - ls.tm_jobs_per_day * days) < 4 * math.sqrt(ls.tm_jobs_per_day * days)
    # the TM hours appear in COR's busy time (4 units): n draws of cv 0.2 sum to their mean
    # within 4 · 0.2 / √n (5 %); the SPOT jobs' order of service, and so which draw each
    # takes, moves a little too
    extra = with_tm.stages["cor"]["utilisation"] - plain.stages["cor"]["utilisation"]
    tm_share = n_tm * ls.tm_job_s / (4 * days * 86400.0)
    assert extra == pytest.approx(tm_share, rel=0.25)
    assert "film" not in plain.stages and plain.station["film_products"] == 0
    n_1a_1b = rep.levels["1A"]["products"] + rep.levels["1B"]["products"]
    film = rep.station["film_products"]
    assert abs(film - od.film_fraction * n_1a_1b) < _binomial_4sigma(n_1a_1b, od.film_fraction)
    busy = film * base.service.film_s / (days * 86400.0)
    assert rep.stages["film"]["utilisation"] == pytest.approx(busy, rel=0.1)


def test_cor_window_of_raw_lines() -> None:
    """INPE: a north-up line reads 950 raw lines (P); this code measures 980 at Cuiabá. A
    COR buffer smaller than that window reads the raw scene again, once per buffer-full."""
    from station.capacity.config import ServiceConfig
    from station.capacity.model import Service, cor_window_s

    service = Service(0.0, {}, {}, {}, "", {"P": 980.1, "XS": 490.0})
    small = ServiceConfig(cor_memory_mb=4.0, raw_read_mb_per_s=1.0)
    # P: 980 lines × 6000 B = 5.9 MB, two buffer-fulls: one more read of the 36 MB scene
    assert cor_window_s(service, small, "P") == pytest.approx(36.0)
    # XS: 490 lines × 3 bands × 3000 B = 4.4 MB: one more read of the 27 MB scene
    assert cor_window_s(service, small, "XS") == pytest.approx(27.0)
    assert cor_window_s(service, ServiceConfig(cor_memory_mb=6.0), "P") == 0.0
    assert cor_window_s(service, ServiceConfig(), "P") == 0.0  # unlimited
    # a table that predates the measure falls back on INPE's own figures (950 / 475)
    old = Service(0.0, {}, {}, {})
    assert cor_window_s(old, ServiceConfig(cor_memory_mb=5.0), "P") == pytest.approx(36.0)


def test_ers_takes_the_antenna_and_its_frames_load_cor(cuiaba) -> None:
    """Issue 38: ERS-1's passes share the antenna as Landsat's do (tracked or finding it
    taken, SPOT losing passes to them), and each tracked pass's frames to geocode take
    COR for the GTC time measured on this code."""
    from dataclasses import replace

    from station.capacity.model import pass_patterns

    base = _short(cuiaba, outage__days="0", failures__antenna_mtbf_h="0")
    base = with_value(with_value(base, "landsat.antenna_share", "0"), "ers.antenna_share", "1")
    # ERS-1's 3-day phase (43 revolutions, its commissioning and ice phases): the same
    # code as the 35-day cycle's, a twelfth of the orbit to propagate for the test
    base = with_value(with_value(base, "ers.repeat_revs", "43"), "ers.repeat_days", "3")
    service = load_service(base)
    assert service.sar_gtc_s_per_frame > 0  # scenarios/capacity/service_times.json
    patterns = pass_patterns(base)
    ers = patterns[2]
    assert ers is not None and ers.cycle_s == 3 * 86400.0
    assert patterns[1] is None  # no Landsat
    every = simulate(base, service, 0, patterns).station
    no_ers = with_value(base, "ers.antenna_share", "0")
    none = simulate(no_ers, service, 0, (patterns[0], None, None)).station
    warmup = base.simulation.warmup_days * 86400.0
    end = warmup + base.simulation.days * 86400.0
    aos = np.concatenate([ers.aos_s + k * ers.cycle_s for k in range(40)])
    expected = np.count_nonzero((aos >= warmup) & (aos < end))
    assert every["ers_passes_tracked"] + every["ers_passes_missed"] == expected
    assert none["ers_passes_tracked"] == 0 and none["sar_frames"] == 0
    assert every["passes_lost"] > none["passes_lost"]
    # frames: Poisson of mean frames_per_pass × gtc_fraction per tracked pass, within 4σ
    mean = every["ers_passes_tracked"] * base.ers.frames_per_pass * base.ers.gtc_fraction
    assert abs(every["sar_frames_recorded"] - mean) < 4 * math.sqrt(mean)
    # at 1990's speed (scale_cor) a frame takes COR for a day and more: they pile up
    assert 0 < every["sar_frames"] < every["sar_frames_recorded"]
    assert every["cor_backlog_growth_per_day"] > none["cor_backlog_growth_per_day"]
    with pytest.raises(ScenarioError, match="calibrate"):  # a file from before SAR's figure
        simulate(base, replace(service, sar_gtc_s_per_frame=0.0), 0, patterns)
