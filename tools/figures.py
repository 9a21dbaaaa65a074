"""Every figure the README quotes, regenerated on this machine, with the commit and machine.

    python tools/figures.py                 # every section but the full-size ones (~3 min)
    python tools/figures.py --full          # also the full P scene's downlink figures
    python tools/figures.py --bench         # also every benchmark and study (~1 hour)
    python tools/figures.py --section levels
    python tools/figures.py --bench --write docs   # docs/accuracy.md and docs/performance.md

``--bench`` runs every benchmark (``benchmarks/``: speed, each beside its peer) and every
study behind a README figure (``tools/level2.py``, ``level3.py``, ``blocks.py``,
``spot_benchmark.py``, ``sar.py``, ``stereo.py``: accuracy against the truth), their
printed lines into the pages.

Each row gives the figure, what this run measured and what the README says; a figure the
run cannot measure says which tool does (the fuzzer's 130 000 streams are a long campaign:
``tools/fuzz_receiver.py``). Speeds are machine-dependent and come from the benchmarks,
each of which prints its peer (GDAL, pyproj, real time) measured in the same run.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import platform
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np

from levels.geo.level2a import Level2AGeometry
from station.fixtures import emulated_scene
from station.scenario import ERRORS_OFF, merge_tables

ROOT = Path(__file__).resolve().parents[1]
REFDATA = Path(os.environ.get("SPOT_REFDATA", ROOT.parent / "shared" / "refdata"))
DAY_S = 86400.0
Row = tuple[str, str, str]  # figure, measured, README


# --- geometry: real scenes ----------------------------------------------------------------


def geometry() -> Iterator[Row]:
    from levels.locate import check_frame

    for name, readme in (
        ("spot5_hrg1_A_20050313_altai_METADATA.DIM", "0.053 m"),
        ("spot2_hrv1_P_19980220_izmit_METADATA.DIM", "2.49 m"),
        ("spot4_hrvir2_M_20120115_altai_METADATA.DIM", "1.56 m"),
    ):
        check = check_frame(REFDATA / "dimap" / name)
        yield (
            f"{check.scene} ({check.attitude}), max miss",
            f"{check.error_m.max():.3f} m",
            readme,
        )


# --- the emulator ------------------------------------------------------------------------


def emulator() -> Iterator[Row]:
    from levels.geometry.ellipsoid import WGS84
    from levels.geometry.times import Epoch
    from station.scenario import scenario_from_dict
    from station.spacecraft.attitude import TruthAttitude, westin_variogram_rad2
    from station.spacecraft.emulator import emulate, truth_model
    from station.spacecraft.imaging import trace_pixels
    from station.spacecraft.orbit import (
        RE_M,
        _mean_elements_for,
        _node_to_node,
        ascending_node_ecef,
        node_state,
        phased_targets,
    )
    from station.spacecraft.placement import place_orbit

    period, rate = phased_targets(369, 26)
    a, i = node_state(period, rate)
    t_node, d_raan = _node_to_node(a, i, 0.0)
    a_mean, i_mean = _mean_elements_for(period, rate, 0.0)
    yield (
        "SPOT orbit solved",
        f"mean {(a_mean - RE_M) / 1e3:.1f} km, "
        f"{np.degrees(i_mean):.3f}°, nodal period {t_node / 60:.2f} min, node "
        f"{np.degrees(d_raan / t_node) * DAY_S:.5f}°/day",
        "822.4 km, 98.698°, 101.46 min, 0.98565°/day",
    )
    cuiaba = (np.radians(-15.555), np.radians(-56.07), 200.0)
    orbit, _ = place_orbit(
        Epoch("1998-02-20", name="day"),
        a,
        i,
        0.0,
        10.5,
        cuiaba[0],
        cuiaba[1],
        (0.0, 26 * DAY_S + 7000),
    )
    shift = ascending_node_ecef(orbit, 26 * DAY_S) - ascending_node_ecef(orbit, 0.0)
    yield ("ground-track repeat after 26 days", f"{np.linalg.norm(shift) / 1e3:.1f} km", "2.3 km")
    from station.capacity.passes import pass_pattern
    from station.scenario import GroundStationConfig

    pattern = pass_pattern(GroundStationConfig())  # the default pass's orbit, one cycle
    days = pattern.cycle_s / DAY_S
    yield (
        "passes over Cuiabá, 5° mask, 26 days",
        f"{pattern.aos_s.size / days:.2f}/day, median "
        f"{np.median(pattern.duration_s) / 60:.2f} min, "
        f"{pattern.daylight.sum() / days:.2f}/day in daylight",
        "3.88/day, median 11.25 min, 1.92/day in daylight",
    )

    small = {"n_detectors": 300, "n_lines": 300, "psf_samples": 2}
    cases = {
        "nadir": {"instrument": small},
        "27°": {"instrument": {**small, "mirror_step": 93}},
        "full-array window": {
            "instrument": {"first_detector": 2900, "detector_count": 200, "n_lines": 200}
        },
        "XS twin": {"instrument": {"mode": "XS", "twin": True, "n_detectors": 300, "n_lines": 300}},
        "SRTM DEM": {},  # scenarios/tilt27_rugged.toml at 300 detectors
    }
    rugged = ROOT / "scenarios" / "tilt27_rugged.toml"
    worst, swath = {}, {}
    for name, over in cases.items():
        if name == "SRTM DEM":
            from station.loader import load_scenario

            base = load_scenario(rugged)
            scn = dataclasses.replace(
                base, instrument=dataclasses.replace(base.instrument, n_detectors=300, n_lines=300)
            )
        else:
            scn = scenario_from_dict(merge_tables(over, {"pass": {"ground_pass_days": 0.0}}))
        acq = emulate(scn, render=False)
        rng = np.random.default_rng(3)
        line = rng.uniform(0, acq.hrv.n_lines - 1, 2000)
        col = rng.uniform(0, acq.hrv.n_columns - 1, 2000)
        t = acq.line_times_s[0] + line * acq.hrv.line_period_s
        pts, ok = trace_pixels(acq.orbit, acq.attitude, acq.hrv.bands[0], acq.world, t, col)
        back = truth_model(acq).ground_to_image(pts[ok, 0], pts[ok, 1], pts[ok, 2])
        worst[name] = max(np.abs(back.line - line[ok]).max(), np.abs(back.column - col[ok]).max())
        if name in ("nadir", "27°"):
            tc = acq.line_times_s[acq.hrv.n_lines // 2]
            n = acq.hrv.n_columns
            e, _ = trace_pixels(
                acq.orbit, acq.attitude, acq.hrv.bands[0], acq.world, [tc, tc], [-0.5, n - 0.5]
            )
            ends = WGS84.to_ecef(e[:, 0], e[:, 1], e[:, 2])
            swath[name] = np.linalg.norm(ends[1] - ends[0]) / 1e3
    yield (
        "raw pixels re-projected (2000 random pixels each)",
        ", ".join(f"{k} {v:.1e}" for k, v in worst.items()) + " px",
        "≤ 2.3e-7 px",
    )
    yield (
        "P swath at nadir / at 27° (mid-strip line)",
        f"{swath['nadir']:.1f} km / {swath['27°']:.1f} km",
        "59.4 km / 78.6 km",
    )

    m = 1500
    rng = np.random.default_rng(2024)
    draws = [TruthAttitude.generate(0.0, 40.0, rng, drift_step_s=0.125) for _ in range(m)]
    t, drift = draws[0].t_grid_s, np.stack([d.drift_rad for d in draws])
    worst_rel = 0.0
    for axis in range(3):
        for lag in (0.5, 2.0, 8.0, 31.0):
            k = round(lag / (t[1] - t[0]))
            inc = drift[:, 8 + k, axis] - drift[:, 8, axis]
            rel = np.mean(inc**2) / float(westin_variogram_rad2(axis, lag)) - 1.0
            worst_rel = max(worst_rel, abs(rel))
    yield (
        "Westin variograms, 1500 drifts, 4 lags × 3 axes, worst relative miss",
        f"{100 * worst_rel:.1f} % (4σ: {100 * 4 * np.sqrt(2 / m):.1f} %)",
        "all within 4σ (±14.6 %)",
    )


# --- the receiving station ---------------------------------------------------------------


def receiver(full: bool) -> Iterator[Row]:
    yield (
        "RS(255,223) dual basis, known-answer codewords",
        "pytest tests/test_telemetry.py",
        "CCSDS 131.0-B",
    )
    yield (
        "fuzz of the products' and L0 readers",
        "python tools/fuzz_products.py 10000 (a long campaign)",
        "10 000 damaged files, no defect, no crash",
    )
    yield (
        "fuzz",
        "python tools/fuzz_receiver.py (a long campaign)",
        "130 000 streams, no unhandled exception",
    )
    if not full:
        yield ("clean channel, full P scene; line clock", "with --full", "")
        yield ("accounting, BER 1e-7 … 1e-3", "with --full (tools/accounting_sweep.py)", "")
        return
    from station.chain.report import downlink_report
    from station.chain.session import downlink
    from station.scenario import scenario_from_dict
    from station.spacecraft.emulator import emulate

    clean = {"ber": 0.0, "burst_rate_per_s": 0.0}
    for mode, readme in (
        ("P", "max 7, RMS 0.42 counts; line clock within 60 µs"),
        ("XS", "bit for bit"),
    ):
        acq = emulate(
            scenario_from_dict(
                {
                    "instrument": {"mode": mode},
                    "pass": {"ground_pass_days": 0.0},
                    "gcps": {"count": 0},
                    "channel": clean,
                }
            )
        )
        rep = downlink_report(acq, downlink(acq))
        b = rep["bands"][0]
        yield (
            f"clean channel, full {mode} scene: error vs raw counts; line clock",
            f"max {b['max_error_vs_raw_counts']}, RMS {b['rms_error_vs_raw_counts']:.2f}; "
            f"clock within {rep['line_clock']['max_error_vs_truth_us']:.0f} µs",
            readme,
        )
    run = subprocess.run(
        [sys.executable, str(ROOT / "tools" / "accounting_sweep.py")],
        capture_output=True,
        text=True,
        check=False,
    )
    last = (run.stdout.strip().splitlines() or ["(no output)"])[-1]
    yield (
        "accounting sweep (tools/accounting_sweep.py)",
        last,
        "sent = delivered + lost, masks exact, pixels as sent",
    )


# --- the processing centre's levels ------------------------------------------------------


def levels_figures() -> Iterator[Row]:
    from levels.geo.level1b import level1b_geometry
    from levels.geo.level2a import level2a_geometry
    from levels.geo.maps import map_crs
    from station.scenario import scenario_from_dict
    from station.spacecraft.emulator import emulate
    from station.truth.optical import Truth, checkpoints_1b, checkpoints_2a

    def scene(data: dict):
        acq = emulate(scenario_from_dict(data), render=False)
        _pg, s, res = emulated_scene(acq)
        return acq, s, res

    from station.scenario import read_toml

    tables = {
        c: read_toml(ROOT / "scenarios" / f"cuiaba_p_{f}.toml")[0]
        for c, f in (("nadir", "nadir"), ("27°", "27deg"))
    }
    inv, polys, b1 = {}, {}, {}
    for case, data in tables.items():
        _acq, s, res = scene(data)
        crs = map_crs("utm", s.centre_lat_rad, s.centre_lon_rad)
        for rows, cols in (("attitude", "butting"), ("regular", "butting"), ("regular", "regular")):
            g = level2a_geometry(s, res, crs, grid_rows=rows, grid_columns=cols)
            errs = {
                m: g.approximation_error(s.model, 450.0, m)["max_px"]
                for m in ("nearest4", "poly3", "poly4", "poly5")
            }
            inv[case, rows, cols] = errs["nearest4"]
            if rows == "attitude":
                polys[case] = [errs[m] for m in ("poly3", "poly4", "poly5")]
                if case == "nadir":
                    skew = _row_skew(g)
        g1 = level1b_geometry(s, res)
        e = g1.approximation_error(s.model)
        b1[case] = (e["max_px"], e["rms_px"], np.ptp(g1.h(np.arange(g1.n_rows, dtype=float))))
    yield (
        "2A inverse, four nearest points, max vs model (attitude rows; regular 61)",
        f"nadir {inv['nadir', 'attitude', 'butting']:.3f}, 27° "
        f"{inv['27°', 'attitude', 'butting']:.3f} px ({inv['nadir', 'regular', 'butting']:.3f}, "
        f"{inv['27°', 'regular', 'butting']:.3f})",
        "nadir 0.025, 27° 0.032 px (0.058, 0.051)",
    )
    yield (
        "2A inverse, INPE's exact 61 × 61 regular grid (no butting columns), max",
        f"nadir {inv['nadir', 'regular', 'regular']:.3f}, 27° "
        f"{inv['27°', 'regular', 'regular']:.3f} px",
        "nadir 0.33, 27° 0.34 px",
    )
    yield (
        "1B skew polynomial h, span over the scene (nadir, 27°)",
        f"{b1['nadir'][2]:.0f} px, {b1['27°'][2]:.0f} px",
        "399 px, 394 px (INPE: about ±200 px)",
    )
    _xs_acq, xs_scene, xs_res = scene(merge_tables(tables["nadir"], {"instrument": {"mode": "XS"}}))
    xs = _row_skew(
        level2a_geometry(
            xs_scene, xs_res, map_crs("utm", xs_scene.centre_lat_rad, xs_scene.centre_lon_rad)
        )
    )
    yield (
        "raw lines one 2A row reads, P / XS, nadir (INPE: 950 / 475, track at 9.0°)",
        f"{skew[0]:.0f} / {xs[0]:.0f}: track {skew[1]:.2f}° from the UTM grid's north, "
        f"{skew[1] - skew[2]:.2f}° from true north (grid convergence {skew[2]:.2f}°)",
        "980 / 490, 9.28° on the grid, 9.04° true",
    )
    yield (
        "2A polynomial inverses, order 3, 4, 5, max",
        "; ".join(f"{c} " + ", ".join(f"{v:.2f}" for v in p) for c, p in polys.items()) + " px",
        "nadir 0.43, 0.28, 0.21; 27° 0.50, 0.38, 0.27 px",
    )
    yield (
        "1B polynomials f, g, h, max (RMS) vs model",
        ", ".join(f"{c} {m:.2f} ({r:.2f})" for c, (m, r, _h) in b1.items()) + " px",
        "nadir 0.91 (0.33), 27° 2.01 (0.63) px",
    )

    def errors(over: dict) -> tuple[dict, dict, float]:
        acq, s, res = scene(over)
        truth = Truth(acq, 0)
        crs = map_crs("utm", s.centre_lat_rad, s.centre_lon_rad)
        return (
            checkpoints_1b(truth, s, level1b_geometry(s, res), 0, 11)["line_of_sight"],
            checkpoints_2a(truth, s, level2a_geometry(s, res, crs), 0, 11)["line_of_sight"],
            res,
        )

    off = {}
    for case, table in tables.items():
        e1, e2, res = errors(merge_tables(table, ERRORS_OFF))
        off[case] = (e2["max_px"], np.hypot(e1["mean_1_m"], e1["mean_2_m"]) / res, e1["max_px"])
    yield (
        "checkpoints, errors off: 2A max; 1B mean, max",
        "; ".join(f"{c} 2A {a:.2f}, 1B {m:.2f} / {x:.1f}" for c, (a, m, x) in off.items()) + " px",
        "2A 0.09 nadir, 0.08 at 27°; 1B mean 0.01, max 0.5 / 2.2 px",
    )
    e1, e2, res = errors(tables["nadir"])
    yield (
        "checkpoints, default errors, nadir (2A, 1B RMS)",
        f"{e2['rms_m']:.0f} m, {e1['rms_m']:.0f} m ({e2['rms_px']:.1f} px)",
        "about 215 m (21.5 px)",
    )

    acq = emulate(
        scenario_from_dict(
            merge_tables(ERRORS_OFF, {"instrument": {"mode": "XS", "n_detectors": 1500}})
        ),
        render=False,
    )
    looks = [b.name for b in acq.hrv.bands]
    _pg, s, res = emulated_scene(acq)
    crs = map_crs("utm", s.centre_lat_rad, s.centre_lon_rad)
    first, *others = looks
    g2 = {first: level2a_geometry(s, res, crs, band=first)}
    for b in others:
        g2[b] = level2a_geometry(s, res, crs, band=b, like=g2[first])
    truth = Truth(acq, 0)
    own = [
        checkpoints_2a(truth, s, g2[b], k, 11)["line_of_sight"]["rms_px"]
        for k, b in enumerate(looks)
    ]
    shared = [
        checkpoints_2a(truth, s, g2[first], k, 11)["line_of_sight"]["rms_px"]
        for k, b in enumerate(looks)
    ]
    yield (
        "XS band registration, errors off, 2A checkpoints RMS (band 1's grids for all)",
        ", ".join(f"{v:.3f}" for v in own)
        + " px ("
        + ", ".join(f"{v:.2f}" for v in shared[1:])
        + ")",
        "0.015 px each (0.09, 0.14)",
    )

    import tempfile

    from levels.process import ProcessingRequest, process
    from levels.readers.l0 import read_l0
    from station.chain.session import downlink, record
    from station.loader import load_scenario

    scn = load_scenario(ROOT / "scenarios" / "small_test.toml")
    acq = emulate(scn)
    with tempfile.TemporaryDirectory() as tmp:
        l0 = record(acq, downlink(acq), Path(tmp) / "s.l0.h5")
        options = dataclasses.replace(scn.processing, levels=("1A",))
        [made] = process(ProcessingRequest.of(read_l0(l0), options, tmp, "s"))
    q = made.scenes[0].quality["1A"]
    yield (
        "stripes raw → 1A (scenarios/small_test.toml, 300 lines)",
        f"{q['stripe_level/P/raw_counts']:.2f} → {q['stripe_level/P/level_1a_counts']:.2f} counts",
        "4.69 → 1.27 counts",
    )


def _row_skew(g: Level2AGeometry) -> tuple[float, float, float]:
    """Raw lines the middle row of a 2A grid reads, the raw lines' azimuth on the map grid
    (deg) and the grid's meridian convergence there (deg)."""
    import pyproj

    lines, cols = g.raw_line_span()
    azimuth = float(np.degrees(np.arctan2(lines, cols)))
    e, n = g.map_grid.map_of(g.map_grid.n_rows / 2, g.map_grid.n_cols / 2)
    crs = pyproj.CRS.from_wkt(g.map_grid.crs_wkt)
    lon, lat = pyproj.Transformer.from_crs(crs, "EPSG:4326", always_xy=True).transform(e, n)
    gamma = float(pyproj.Proj(crs).get_factors(lon, lat).meridian_convergence)
    return lines, azimuth, abs(gamma)


# --- capacity ----------------------------------------------------------------------------


def capacity() -> Iterator[Row]:

    from station.capacity.config import load_capacity, with_value
    from station.capacity.model import simulate
    from station.capacity.stage import mmc_wait_h
    from station.capacity.stats import erlang_c_wait_s, mean_ci
    from station.capacity.study import MIN_REPLICATIONS_CI, load_service, run_study

    out = []
    for c, rho in ((1, 0.7), (3, 0.85)):
        mu = 1.0 / 3600.0
        lam = rho * c * mu
        mean, half = mean_ci([mmc_wait_h(lam, mu, c, 6000, s) for s in range(10)])
        out.append(
            f"M/M/{c} ρ {rho}: {mean:.2f} ± {half:.2f} h vs "
            f"{erlang_c_wait_s(lam, mu, c) / 3600:.2f} h"
        )
    yield (
        "M/M/c stage vs Erlang C (10 replications × 6000 jobs)",
        "; ".join(out),
        "2.31 ± 0.19 h vs 2.33 h; 1.64 ± 0.29 h vs 1.62 h",
    )
    cuiaba = load_capacity(ROOT / "scenarios" / "capacity" / "cuiaba.toml")
    scn = with_value(with_value(cuiaba, "resources.cor_workers", "3"), "outage.days", "0")
    rep = simulate(scn, load_service(scn), 0)
    worst = max(
        (abs(s["little_L"] / s["little_lambda_W"] - 1.0), name)
        for name, s in rep.stages.items()
        if s["arrivals_per_day"] > 0 and s["little_lambda_W"] > 0
    )
    yield (
        "Little's law L = λW per stage (a year, 3 COR workers), worst",
        f"{100 * worst[0]:.2f} % ({worst[1]})",
        "within 0.04 % (COR)",
    )
    n = MIN_REPLICATIONS_CI  # intervals from there on
    summary = run_study(
        cuiaba, None, ("resources.cor_workers", ["1", "2", "3", "4"]), n, plots=False
    )
    growth = [r["station"]["cor_backlog_growth_per_day"] for r in summary["runs"]]
    busy = [r["stages"]["cor"]["utilisation"]["mean"] for r in summary["runs"]]
    yield (
        f"COR workers 1–4 ({n} replications): backlog growth, jobs/day",
        ", ".join(f"{g['mean']:.2f} ± {g['ci95']:.2f}" for g in growth),
        "about 11.8, 0.5 (saturated), 0.00, 0.00",
    )
    yield (
        "COR workers 1–4: COR busy",
        ", ".join(f"{100 * b:.0f} %" for b in busy),
        "99, 98, 67, 50 %",
    )
    clear = [r["station"].get("outage_clear_days", {}) for r in summary["runs"]]
    yield (
        "COR workers 1–4: after the 3-day outage, replications cleared; days after (a mean "
        "only where every replication cleared: else censored)",
        ", ".join(f"{c.get('n', 0)}" for c in clear)
        + f" of {n}; "
        + ", ".join("censored" if c.get("censored") else f"{c['mean']:.1f}" for c in clear),
        "about 0, 1–2, 5, 5 of 5; censored, censored, 5.4, 3.4",
    )
    p95 = [r["levels"]["2A"]["latency_p95_h"] for r in summary["runs"]]
    yield (
        "COR workers 1–4: 2A p95 latency from acquisition",
        ", ".join(f"{v['mean']:.0f} h" for v in p95),
        "4741, 289, 88, 80 h",
    )
    from station.capacity.model import cor_window_s

    service = load_service(cuiaba)
    window = {m: cor_window_s(service, cuiaba.service, m) for m in ("P", "XS")}
    cor_2a = {m: service.cor_s[m]["2A"] * cuiaba.service.scale_cor for m in ("P", "XS")}
    yield (
        "COR's raw-line window, extra per 2A job (P, XS) and share of its 1990 time",
        ", ".join(f"{m} {window[m]:.0f} s ({100 * window[m] / cor_2a[m]:.2f} %)" for m in window),
        "36 s, 27 s; under 0.5 %",
    )
    shares = ["0", "0.5", "1"]
    summary = run_study(cuiaba, None, ("landsat.antenna_share", shares), 3, plots=False)
    rows = []
    for share, r in zip(shares, summary["runs"], strict=True):
        st, lv = r["station"], r["levels"]["2A"]
        rows.append(
            f"{share}: SPOT passes lost {st['passes_lost']['mean']:.0f}/yr, scenes/day "
            f"{st['scenes_per_day']['mean']:.1f}, COR backlog "
            f"{st['cor_backlog_growth_per_day']['mean']:+.2f}/day, 2A p95 "
            f"{lv['latency_p95_h']['mean']:.0f} h"
        )
    yield (
        "Landsat's share of the antenna (3 replications)",
        "; ".join(rows),
        "lost 2, 49, 90/yr; scenes 36.8, 35.3, 33.7/day; backlog 1.40, 0.54, −0.02; "
        "p95 530, 289, 169 h",
    )


# --- speed ---------------------------------------------------------------------------------


#: Arguments of a benchmark run here: the stereo benchmark reads the full-size pair that
#: ``tools/stereo.py`` makes (and keeps) in ``runs/stereo_full``, made once for both.
BENCH_ARGS = {"bench_stereo.py": [str(ROOT / "runs" / "stereo_full")]}


def bench() -> Iterator[Row]:
    for script in sorted((ROOT / "benchmarks").glob("bench_*.py")):
        t0 = time.perf_counter()
        run = subprocess.run(
            [sys.executable, str(script), *BENCH_ARGS.get(script.name, [])],
            capture_output=True,
            text=True,
            check=False,
            cwd=ROOT,
        )
        lines = [ln for ln in run.stdout.strip().splitlines() if ln.strip()]
        for ln in lines:
            yield (script.name, ln.strip(), "README: speed tables")
        if run.returncode != 0:
            yield (
                script.name,
                f"FAILED ({run.returncode}): " + (run.stderr.strip().splitlines() or [""])[-1],
                "",
            )
        yield (script.name, f"({time.perf_counter() - t0:.0f} s)", "")


#: The studies behind the README's accuracy figures, each its own tool (``tools/``), run
#: as a user runs it: level 2, level 3, a block, the DIMAP pack and route (P, XS), SAR, the
#: stereo pair, and level 2's prediction over many draws of a pair and of a block.
STUDIES = (
    ("level2.py", []),
    ("level3.py", []),
    ("blocks.py", []),
    ("spot_benchmark.py", []),
    ("dimap_route.py", []),
    ("dimap_route.py", ["--set", 'instrument.mode="XS"']),
    ("sar.py", []),
    ("stereo.py", []),
    ("block_draws.py", ["--draws", "24", "--first", "100"]),
    ("block_draws.py", ["scenarios/blocks/two_passes.toml", "--draws", "16", "--first", "100"]),
)


def studies() -> Iterator[Row]:
    """Every study tool's printed figures (tens of minutes: the stereo pair at full size is
    ten), each line a row."""
    for script, args in STUDIES:
        t0 = time.perf_counter()
        run = subprocess.run(
            [sys.executable, str(ROOT / "tools" / script), *args],
            capture_output=True,
            text=True,
            check=False,
            cwd=ROOT,
        )
        for ln in (ln for ln in run.stdout.strip().splitlines() if ln.strip()):
            yield (script, ln.strip().replace("|", "/"), "README: headline figures")
        if run.returncode != 0:
            last = (run.stderr.strip().splitlines() or [""])[-1]
            yield (script, f"FAILED ({run.returncode}): {last}", "")
        yield (script, f"({time.perf_counter() - t0:.0f} s)", "")


def _header() -> str:
    def git(*args: str) -> str:
        r = subprocess.run(["git", *args], capture_output=True, text=True, cwd=ROOT, check=False)
        return r.stdout.strip()

    import numba
    import scipy

    dirty = " (with uncommitted changes)" if git("status", "--porcelain") else ""
    return (
        f"commit {git('rev-parse', '--short', 'HEAD') or '?'}{dirty}; "
        f"{platform.node()}, {platform.machine()}, {os.cpu_count()} cores, "
        f"{platform.python_implementation()} {platform.python_version()}, numpy "
        f"{np.__version__}, scipy {scipy.__version__}, numba {numba.__version__}; "
        f"{time.strftime('%Y-%m-%d %H:%M:%S %Z')}"
    )


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument(
        "--section",
        action="append",
        choices=["geometry", "emulator", "receiver", "levels", "capacity", "studies"],
        help="only these sections (repeatable)",
    )
    p.add_argument("--full", action="store_true", help="full-size receiver figures too")
    p.add_argument(
        "--bench",
        action="store_true",
        help="run the benchmarks and the studies too (tools/level2.py … stereo.py: every "
        "README figure; about an hour)",
    )
    p.add_argument(
        "--write",
        metavar="DIR",
        help="also write DIR/accuracy.md (the sections) and, with --bench, DIR/performance.md",
    )
    args = p.parse_args(argv)
    sections: dict[str, Callable[[], Iterator[Row]]] = {
        "geometry": geometry,
        "emulator": emulator,
        "receiver": lambda: receiver(args.full),
        "levels": levels_figures,
        "capacity": capacity,
        "studies": studies,
    }
    chosen = args.section or [n for n in sections if n != "studies" or args.bench]
    header = _header()
    print(header)
    measured: dict[str, list[Row]] = {}
    for name in chosen:
        t0 = time.perf_counter()
        print(f"\n## {name}")
        measured[name] = []
        for row in sections[name]():
            figure, value, readme = row
            measured[name].append(row)
            print(
                f"- {figure}: {value}" + (f"   [expected: {readme}]" if readme else ""), flush=True
            )
        print(f"  ({time.perf_counter() - t0:.0f} s)")
    speeds: list[Row] = []
    if args.bench:
        print("\n## speed (benchmarks/)")
        for row in bench():
            speeds.append(row)
            print(f"- {row[0]}: {row[1]}", flush=True)
    if args.write:
        out = Path(args.write)
        _write_doc(out / "accuracy.md", "Accuracy, regenerated", header, measured)
        if speeds:
            _write_doc(out / "performance.md", "Speed, regenerated", header, {"benchmarks": speeds})
    return 0


_TITLES = {
    "geometry": "Real scenes located from their metadata",
    "emulator": "How truthful the emulator is",
    "receiver": "The station's receiver",
    "levels": "The processing centre's levels",
    "capacity": "The capacity model",
    "studies": "The studies behind the README's figures (each tool's own lines)",
    "benchmarks": "Each benchmark's figures and its peer, measured in the same run",
}


def _write_doc(path: Path, title: str, header: str, sections: dict[str, list[Row]]) -> None:
    """A markdown page of the figures measured: one table per section, each saying when it
    was measured. The page's other sections (``--section`` measured only some) are kept
    as they were."""
    kept = _sections_of(path) if path.is_file() else {}
    blocks: dict[str, list[str]] = {}
    for name, rows in sections.items():
        lines = ["", f"## {_TITLES.get(name, name)}", "", f"Measured at {header}.", ""]
        if name == "benchmarks":
            lines += ["| benchmark | printed |", "|---|---|"]
            lines += [f"| `{f}` | {m.replace('|', '/')} |" for f, m, _ in rows]
        else:
            lines += ["| figure | measured | expected |", "|---|---|---|"]
            lines += [f"| {f} | {m} | {e} |" for f, m, e in rows]
        blocks[_TITLES.get(name, name)] = lines
    order = [t for t in kept if t not in blocks] + list(blocks)
    out = [
        f"# {title}",
        "",
        "Written by `python tools/figures.py --bench --write docs`; do not edit by hand.",
        "`docs/levels.md` says how each figure is made.",
    ]
    for t in order:
        out += blocks.get(t) or kept[t]
    path.write_text("\n".join(out) + "\n")


def _sections_of(path: Path) -> dict[str, list[str]]:
    """The ``## `` sections of a page this tool wrote, by title, each with its lines."""
    found: dict[str, list[str]] = {}
    current: list[str] | None = None
    page_measured = ""  # a page written before the sections said when: its own line
    for line in path.read_text().splitlines():
        if line.startswith("Measured at ") and current is None:
            page_measured = line.split(". `docs/")[0].rstrip(".") + "."
        if line.startswith("## "):
            current = found.setdefault(line[3:], ["", line])
            if page_measured:
                current += ["", page_measured]
        elif current is not None:
            current.append(line)
    for lines in found.values():
        while lines and not lines[-1].strip():
            lines.pop()
    return found


if __name__ == "__main__":
    sys.exit(main())
