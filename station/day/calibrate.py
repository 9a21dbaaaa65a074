"""The service times of a day's stages, measured on this machine on a pass of their own (not
the day's): what ``station capacity validate`` gives the capacity model.

Two calibration passes (both HRVs, one in P and one in XS, :data:`SCENES` scenes a
segment, the day's reduced sizes and rate, seeds of their own) are emulated, then each sent
to a front end (``station serve``, in its own process, as in the day) at the day's clock
times the line rate. Per channel, the wall time from its first byte to its archive
written (**ingest**): from the two passes, a channel's fixed cost and its cost per second
of signal; and from then to its scenes catalogued, per scene, on the second pass (**GEO**,
warm as in the day after its first pass). Then each order kind (mode × level) is made
:data:`REPEATS` times from the second pass's archive by the day's kind of worker (a spawned
process, warm), one job at a time: the wall time from dispatch to the product catalogued
(**COR**), its mean and coefficient of variation; and k at once for k = 2 … workers: how
many times slower a job is when k share the machine (``cor_contention``: the cores and
the memory bandwidth they share).
"""

from __future__ import annotations

import json
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from multiprocessing import get_context
from pathlib import Path

import numpy as np

from station.archive_catalogue import CATALOGUE_FILE
from station.capacity.plan import PlannedPass, PlannedSegment
from station.day import work
from station.day.config import DayScenario
from station.day.preflight import SCENE_S
from station.errors import StationError

__all__ = ["REPEATS", "SCENES", "day_service"]

#: Scenes a segment of each calibration pass: two passes, a channel's fixed cost and its
#: cost per second of signal.
SCENES = (1, 3)
REPEATS = 4
LEVELS = ("1A", "1B", "2A")
#: Added to the day's seed: the calibration pass is not one of the day's.
CALIBRATION_SEED = 424242


def _stats(x: list[float]) -> dict[str, object]:
    a = np.asarray(x, float)
    return {
        "mean_s": float(a.mean()),
        "cv": float(a.std(ddof=1) / a.mean()) if a.size > 1 else 0.0,
        "n": int(a.size),
        "samples_s": [float(v) for v in a],  # the model's replications resample them
    }


def _send(out: Path, streams: tuple, port: int, scn: DayScenario, name: str) -> dict:
    """A calibration pass sent to the front end, once it has archived and catalogued it:
    its ``live.json``."""
    from station.live.sender import send_streams

    ann, chans, one = streams
    send_streams(ann, chans, "127.0.0.1", port, scn.day.clock, one)
    report = out / "archive" / name / "live.json"
    deadline = time.time() + 120.0
    while not report.is_file():
        if time.time() > deadline:
            raise StationError(f"calibration: the front end did not archive {name}")
        time.sleep(0.02)
    time.sleep(0.05)  # written whole (it is replaced at once, but be sure it is closed)
    return json.loads(report.read_text())


def _cor(pool: ProcessPoolExecutor, jobs: list[tuple], at_once: int) -> list[float]:
    """Wall time of each job from dispatch to return, ``at_once`` dispatched together."""
    times = []
    for k in range(0, len(jobs), at_once):
        t = time.time()
        futures = [pool.submit(work.make_order, *job) for job in jobs[k : k + at_once]]
        for f in as_completed(futures):
            f.result()
            times.append(time.time() - t)
    return times


#: The calibration passes: their segments' (mode, scenes). Two of both HRVs (a channel's
#: fixed cost and its cost a second of signal), one channel alone (how much two channels at
#: once slow each other in the front end's one process), and the second again while every
#: worker is busy (how much the workers' jobs slow the front end).
PASSES = (
    (("P", SCENES[0]), ("XS", SCENES[0])),
    (("P", SCENES[1]), ("XS", SCENES[1])),
    (("P", SCENES[1]),),
    (("P", SCENES[1]), ("XS", SCENES[1])),
)


def day_service(scn: DayScenario, workdir: Path | None = None) -> dict[str, object]:
    """The day's service times measured (module docstring), as a table."""
    from station.day.run import _start_front_end, _stop

    day = scn.day
    seed = scn.capacity.seed + CALIBRATION_SEED
    with tempfile.TemporaryDirectory(dir=workdir) as tmp:
        out = Path(tmp)
        (out / "passes").mkdir()
        planned = []
        for k, segs in enumerate(PASSES):
            segments = tuple(PlannedSegment(h + 1, m, n) for h, (m, n) in enumerate(segs))
            p = PlannedPass(f"calibration{k}", "SPOT 1", 0.0, 600.0, segments)
            toml = out / "passes" / f"{p.name}.toml"
            toml.write_text(
                work.pass_scenario(p, seed + k, day.start_s, day.p_detectors, day.bit_rate_mbps)
            )
            planned.append(p)
        ctx = get_context("spawn")
        catalogue = str(out / "archive" / CATALOGUE_FILE)
        with ProcessPoolExecutor(day.workers, mp_context=ctx, initializer=work.warm) as pool:
            emulated = [
                pool.submit(work.emulate, str(out / "passes" / f"{p.name}.toml")) for p in planned
            ]
            streams = [f.result() for f in emulated]
            proc, port = _start_front_end(out, len(planned))
            try:
                lives = [_send(out, streams[k], port, scn, planned[k].name) for k in range(3)]
                l0 = {
                    m: out / "archive" / "calibration1" / f"calibration1_hrv{h}.l0.h5"
                    for h, m in ((1, "P"), (2, "XS"))
                }
                busy = [
                    pool.submit(
                        work.make_order,
                        str(l0["P"]),
                        k % SCENES[1],
                        "2A",
                        str(out / "products" / f"busy{k}"),
                        catalogue,
                    )
                    for k in range(6 * day.workers)
                ]
                time.sleep(0.2)  # every worker on a job
                lives.append(_send(out, streams[3], port, scn, planned[3].name))
                busy_after = sum(not f.done() for f in busy)
                busy_runs = [f.result() for f in busy]
            finally:
                _stop(proc, 120.0)
            ingest = _ingest(lives, busy_after >= day.workers)
            cor_ingesting = _cor_while_ingesting(busy_runs, lives[3])
            last = lives[1]["channels"]  # GEO on the second pass: warm, as in the day
            geo = {
                mode: {
                    "mean_s": (c["catalogued_s"] - c["archived_s"]) / SCENES[1],
                    "cv": 0.0,
                    "n": 1,
                }
                for mode, c in zip(("P", "XS"), last, strict=True)
            }
            cor, together = _cor_table(pool, l0, out, catalogue, day.workers)
    return {
        "format": "spot-station-day-service-times",
        "format_version": 2,
        "measured_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        "clock": day.clock,
        "workers": day.workers,
        "p_detectors": day.p_detectors,
        "ingest": ingest,
        "geo_s_per_scene": geo,
        "cor_s": cor,
        "cor_contention": {str(k): float(np.mean(v)) for k, v in together.items()},
        "cor_slowdown_ingesting": cor_ingesting,
    }


def _cor_table(
    pool: ProcessPoolExecutor, l0: dict[str, Path], out: Path, catalogue: str, workers: int
) -> tuple[dict[str, dict[str, dict[str, object]]], dict[int, list[float]]]:
    """Each order kind made :data:`REPEATS` times alone, and k at once for k = 2 … workers:
    its times, and how many times slower each is k at once."""
    cor: dict[str, dict[str, dict[str, object]]] = {}
    together: dict[int, list[float]] = {k: [] for k in range(2, workers + 1)}
    for mode in ("P", "XS"):
        cor[mode] = {}
        for level in LEVELS:
            jobs = [
                (
                    str(l0[mode]),
                    k % SCENES[1],
                    level,
                    str(out / "products" / str(k)),
                    catalogue,
                )
                for k in range(max(REPEATS, workers))
            ]
            alone = _cor(pool, jobs[:REPEATS], 1)
            cor[mode][level] = _stats(alone)
            for k in together:  # k of them at once: how much slower each is
                ratio = float(np.mean(_cor(pool, jobs[:k], k)) / np.mean(alone))
                together[k].append(ratio)
    return cor, together


def _signal_s(live: dict) -> float:
    """A pass's channels' seconds of signal, from their bytes at their line rate."""
    return float(
        np.mean([8.0 * c["bytes"] / (c["line_rate_mbps"] * 1e6) for c in live["channels"]])
    )


def _ingest(lives: list[dict], busy_held: bool) -> dict[str, float]:
    """The front end's law (module docstring) from the four calibration passes."""
    signal = [_signal_s(live) for live in lives[:2]]
    t = [float(np.mean([c["archived_s"] for c in live["channels"]])) for live in lives]
    per_s = (t[1] - t[0]) / (signal[1] - signal[0])
    fixed = max(0.0, t[0] - per_s * signal[0])
    spread = [
        c["archived_s"] / np.mean([x["archived_s"] for x in lv["channels"]])
        for lv in lives[:2]
        for c in lv["channels"]
    ]
    return {
        "fixed_s": fixed,
        "s_per_signal_s": per_s,
        # a channel's signal beyond its scenes' (the sender's lead-in and the last lines)
        "lead_s": signal[0] - SCENES[0] * SCENE_S,
        "cv": float(np.std(spread)),
        "slowdown_two_channels": max(1.0, t[1] / t[2]),
        # measured only if the workers were still busy when the pass was in
        "slowdown_workers_busy": max(1.0, t[3] / t[1]) if busy_held else 1.0,
    }


def _cor_while_ingesting(busy: list[dict], live: dict) -> float:
    """How many times slower a job is while the front end ingests a pass: each busy job's
    time against the share of it the ingest overlapped, ``t = t0 (1 + (f - 1) share)``,
    with ``t0`` the jobs it did not overlap (1.0 when none did, or all did)."""
    c0 = min(c["started_unix"] for c in live["channels"])
    c1 = max(c["started_unix"] + c["archived_s"] for c in live["channels"])
    t = np.array([r["made_unix"] - r["started_unix"] for r in busy])
    a = np.array([r["started_unix"] for r in busy])
    share = np.clip(np.minimum(a + t, c1) - np.maximum(a, c0), 0.0, None) / t
    alone, over = t[share == 0.0], share > 0.25
    if not alone.size or not over.any():
        return 1.0
    return max(1.0, 1.0 + float(np.mean((t[over] / alone.mean() - 1.0) / share[over])))
