"""The service times of a day's stages, measured on this machine on passes of their own (not
the day's): what ``station capacity validate`` gives the capacity model.

The calibration passes (:data:`PASSES`: both HRVs or one, :data:`SCENES` scenes a segment,
the day's reduced sizes and rate, seeds of their own) are emulated on the workers while a
front end (``station serve --warm-first``, in its own process, as in the day) starts and
warms, then each is sent at the day's clock times the line rate:

- **ingest**, a channel's wall time from its first byte to its archive written: its
  fixed cost and its cost a second of its pass's signal (``short`` and ``long``), what a
  second of fill saves against a second of image (``fill``), how much two channels at once
  slow each other (``alone``) and how much busy workers slow them (``busy``);
- **GEO**, a channel's archive catalogued as GEO places its scenes, timed here alone on the
  ``short`` and ``long`` archives: a fixed cost and a cost a scene (the model shares the
  front end's process between GEO and the ingest beside it);
- **COR**, each order kind (mode × level) made ``calibration_repeats`` times from the ``long``
  pass's archive by the day's kind of worker (a spawned process, warm), one job at a time:
  the wall time from dispatch to the product catalogued, its mean and coefficient of
  variation; and k at once for k = 2 … workers: how many times slower a job is when k
  share the machine (``cor_contention``: the cores and the memory bandwidth they share);
  and how much slower a job is while the front end ingests (``busy``).
"""

from __future__ import annotations

import dataclasses
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from station.archive_catalogue import CATALOGUE_FILE
from station.capacity.plan import PlannedPass, PlannedSegment
from station.day import work
from station.day.config import DayConfig, DayScenario
from station.day.front import launch_front_end, port_of, stop_front_end
from station.day.pool import DayPool, day_pool, finish_times
from station.day.preflight import SCENE_S
from station.errors import StationError

__all__ = ["SCENES", "SERVICE_FILE", "bracket", "day_service", "read_service"]

#: Scenes a segment of each calibration pass: two passes, a channel's fixed cost and its
#: cost per second of signal.
SCENES = (1, 3)
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


def _cor(pool: DayPool, jobs: list[tuple], at_once: int) -> list[float]:
    """Wall time of each job from dispatch to return, ``at_once`` dispatched together."""
    times = []
    for k in range(0, len(jobs), at_once):
        t = time.time()
        futures = [pool.submit(work.make_order, *job) for job in jobs[k : k + at_once]]
        times += [end - t for end in finish_times(futures)]
    return times


#: A day's service times, measured before its clock and after (:func:`bracket`), or by
#: ``station capacity validate``.
SERVICE_FILE = "service_day.json"
SERVICE_FORMAT = "spot-station-day-service-times"

#: The calibration passes by name: their segments' (mode, scenes), in the order sent.
#: ``short`` and ``long`` (both HRVs): a channel's fixed cost and its cost a second of
#: signal; ``fill``: the P channel of one scene beside an XS of three, its last two scenes'
#: time fill (what a channel's fill saves against image); ``alone``: one channel (how much
#: two channels at once slow each other in the front end's one process); ``busy``: the long
#: pass again while every worker is busy (how much the workers' jobs slow the front end).
PASSES = {
    "short": (("P", SCENES[0]), ("XS", SCENES[0])),
    "long": (("P", SCENES[1]), ("XS", SCENES[1])),
    "fill": (("P", SCENES[0]), ("XS", SCENES[1])),
    "alone": (("P", SCENES[1]),),
    "busy": (("P", SCENES[1]), ("XS", SCENES[1])),
}
#: GEO of each calibration archive timed this many times in this process (after one
#: untimed call that loads its modules); the median is taken.
GEO_REPEATS = 3


def _emulated(out: Path, scn: DayScenario, pool: DayPool) -> dict[str, tuple]:
    """The calibration passes emulated on the workers: their streams, by name."""
    day = scn.day
    seed = scn.capacity.seed + CALIBRATION_SEED
    futures = {}
    for k, (name, segs) in enumerate(PASSES.items()):
        segments = tuple(PlannedSegment(h + 1, m, n) for h, (m, n) in enumerate(segs))
        p = PlannedPass(name, "SPOT 1", 0.0, 600.0, segments)
        toml = out / "passes" / f"{name}.toml"
        toml.write_text(
            work.pass_scenario(p, seed + k, day.start_s, day.p_detectors, day.bit_rate_mbps)
        )
        futures[name] = pool.submit(work.emulate, str(toml))
    return {name: f.result() for name, f in futures.items()}


def _l0(out: Path, name: str) -> dict[str, Path]:
    return {m: out / "archive" / name / f"{name}_hrv{h}.l0.h5" for h, m in ((1, "P"), (2, "XS"))}


def day_service(
    scn: DayScenario, workdir: Path | None = None, pool: DayPool | None = None
) -> dict[str, object]:
    """The day's service times measured (module docstring), as a table: on ``pool``, the
    day's workers, or on local ones of its own (``[day] workers``)."""
    if pool is None:
        with day_pool(scn.day.workers) as local:
            return day_service(scn, workdir, local)
    day = dataclasses.replace(scn.day, workers=pool.workers)
    with tempfile.TemporaryDirectory(dir=workdir) as tmp:
        out = Path(tmp)
        (out / "passes").mkdir()
        catalogue = str(out / "archive" / CATALOGUE_FILE)
        proc = launch_front_end(out)  # warm before its port, as a day's
        try:
            streams = _emulated(out, scn, pool)
            port = port_of(proc, out)
            lives = {
                name: _send(out, streams[name], port, scn, name)
                for name in PASSES
                if name != "busy"
            }
            l0 = _l0(out, "long")
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
            lives["busy"] = _send(out, streams["busy"], port, scn, "busy")
            busy_after = sum(not f.done() for f in busy)
            busy_runs = [f.result() for f in busy]
        finally:
            stop_front_end(proc, 120.0)
        ingest = _ingest(lives, busy_after >= day.workers)
        cor_ingesting = _cor_while_ingesting(busy_runs, lives["busy"])
        geo = _geo(out, catalogue, lives, ingest)
        cor, together = _cor_table(pool, out, catalogue, day)
    return {
        "format": SERVICE_FORMAT,
        "format_version": 3,
        "measured_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        "clock": day.clock,
        "workers": day.workers,
        "p_detectors": day.p_detectors,
        "ingest": ingest,
        "geo": geo,
        "cor_s": cor,
        "cor_contention": {str(k): float(np.mean(v)) for k, v in together.items()},
        "cor_slowdown_ingesting": cor_ingesting,
        "channels": {  # what the ingest law is drawn from: each calibration pass's channels
            name: [
                {"mode": m, "scenes": n, **{k: c[k] for k in ("archived_s", "catalogued_s")}}
                for (m, n), c in zip(PASSES[name], live["channels"], strict=True)
            ]
            for name, live in lives.items()
        },
    }


def _cor_table(
    pool: DayPool, out: Path, catalogue: str, day: DayConfig
) -> tuple[dict[str, dict[str, dict[str, object]]], dict[int, list[float]]]:
    """Each order kind made ``calibration_repeats`` times alone from the ``long`` pass's
    archive (the second of :data:`SCENES`), half as many times from the ``short`` one's
    (what a scene more in the archive costs: the job reads its archive whole and sets up
    GEO for its pass), and k at once for k = 2 … workers: its times, its cost an archive
    scene (``s_per_archive_scene``) and how many times slower each is k at once. The kinds
    take turns, one job each a round: this machine's speed drifts from one minute to the
    next (10-30 % on a shared VM), and a kind's times taken together would each catch one
    moment of it."""
    cor: dict[str, dict[str, dict[str, object]]] = {}
    together: dict[int, list[float]] = {k: [] for k in range(2, day.workers + 1)}
    repeats = day.calibration_repeats
    archives = {name: _l0(out, name) for name in ("short", "long")}

    def jobs(name: str, mode: str, level: str, n: int) -> list[tuple]:
        return [
            (
                str(archives[name][mode]),
                k % SCENES[name == "long"],
                level,
                str(out / "products" / str(k)),
                catalogue,
            )
            for k in range(n)
        ]

    kinds = [(mode, level) for mode in ("P", "XS") for level in LEVELS]
    alone: dict[tuple[str, str], list[float]] = {kind: [] for kind in kinds}
    short: dict[tuple[str, str], list[float]] = {kind: [] for kind in kinds}
    at_once: dict[tuple[int, str, str], list[float]] = {}
    for r in range(repeats):  # round by round: each kind's times spread over the session
        for mode, level in kinds:
            alone[mode, level] += _cor(pool, jobs("long", mode, level, 1), 1)
            if r < max(1, repeats // 2):
                short[mode, level] += _cor(pool, jobs("short", mode, level, 1), 1)
            for k in together:  # k of them at once, once a kind, midway
                if r == repeats // 2:
                    at_once[k, mode, level] = _cor(pool, jobs("long", mode, level, k), k)
    for mode, level in kinds:
        t = alone[mode, level]
        per = (np.mean(t) - np.mean(short[mode, level])) / (SCENES[1] - SCENES[0])
        cor.setdefault(mode, {})[level] = {
            **_stats(t),
            "archive_scenes": SCENES[1],
            "s_per_archive_scene": max(0.0, float(per)),
        }
        for k in together:  # how much slower each is
            together[k].append(float(np.mean(at_once[k, mode, level]) / np.mean(t)))
    return cor, together


def _geo(
    out: Path, catalogue: str, lives: dict[str, dict], ingest: dict[str, float]
) -> dict[str, dict[str, float]]:
    """GEO's law per mode, alone: a channel's fixed cost (its catalogue opened, its archive
    read, the pass's GEO set up, the transaction) and its cost a scene, by least squares on
    the ``short`` and ``long`` passes' archives, each catalogued :data:`GEO_REPEATS` times
    here as the front end's channel does (``FrontEnd._catalogue``), the median taken.
    Alone: in the model GEO shares the front end's process with the ingest beside it. Its
    ``cv``: the spread of the front end's own GEO of the calibration passes' channels about
    the law, times the front end's slowdowns as the model applies them (two channels, whose
    GEO overlap; the workers busy)."""
    from station.archive_catalogue import Catalogue, add_archive

    def once(path: Path) -> float:
        t = time.perf_counter()
        with Catalogue(Path(catalogue)) as cat:
            add_archive(cat, path)
        return time.perf_counter() - t

    once(_l0(out, "short")["P"])  # its modules loaded, untimed
    law = {}
    for mode in ("P", "XS"):
        t = [
            float(np.median([once(_l0(out, name)[mode]) for _ in range(GEO_REPEATS)]))
            for name in ("short", "long")
        ]
        per = max(0.0, (t[1] - t[0]) / (SCENES[1] - SCENES[0]))
        law[mode] = {"fixed_s": max(0.0, t[0] - per * SCENES[0]), "s_per_scene": per}

    def slowed(name: str) -> float:
        two = ingest["slowdown_two_channels"] if len(PASSES[name]) > 1 else 1.0
        return two * (ingest["slowdown_workers_busy"] if name == "busy" else 1.0)

    ratios = [
        (c["catalogued_s"] - c["archived_s"])
        / ((law[m]["fixed_s"] + law[m]["s_per_scene"] * n) * slowed(name))
        for name, live in lives.items()
        for (m, n), c in zip(PASSES[name], live["channels"], strict=True)
    ]
    cv = float(np.std(ratios, ddof=1) / np.mean(ratios))
    return {m: {**v, "cv": cv, "n": len(ratios)} for m, v in law.items()}


def _signal_s(live: dict) -> float:
    """A pass's channels' seconds of signal, from their bytes at their line rate."""
    return float(
        np.mean([8.0 * c["bytes"] / (c["line_rate_mbps"] * 1e6) for c in live["channels"]])
    )


def _mean_archived(live: dict) -> float:
    return float(np.mean([c["archived_s"] for c in live["channels"]]))


def _ingest(lives: dict[str, dict], busy_held: bool) -> dict[str, float]:
    """The front end's law (module docstring) from the calibration passes, for a channel
    beside another: ``fixed_s + s_per_signal_s * signal - fill_saving * fill``, with
    ``signal`` its pass's seconds of signal and ``fill`` those its own scenes do not fill."""
    short, long_ = lives["short"], lives["long"]
    signal = [_signal_s(short), _signal_s(long_)]
    t = [_mean_archived(short), _mean_archived(long_)]
    per_s = (t[1] - t[0]) / (signal[1] - signal[0])
    fixed = max(0.0, t[0] - per_s * signal[0])
    fill_s = (SCENES[1] - SCENES[0]) * SCENE_S  # the fill pass's P channel
    saved = long_["channels"][0]["archived_s"] - lives["fill"]["channels"][0]["archived_s"]
    spread = [c["archived_s"] / _mean_archived(lv) for lv in (short, long_) for c in lv["channels"]]
    return {
        "fixed_s": fixed,
        "s_per_signal_s": per_s,
        "fill_saving": min(per_s, max(0.0, saved / fill_s)),
        # a channel's signal beyond its scenes' (the sender's lead-in and the last lines)
        "lead_s": signal[0] - SCENES[0] * SCENE_S,
        "cv": float(np.std(spread)),
        "slowdown_two_channels": max(1.0, t[1] / _mean_archived(lives["alone"])),
        # measured only if the workers were still busy when the pass was in
        "slowdown_workers_busy": max(1.0, _mean_archived(lives["busy"]) / t[1])
        if busy_held
        else 1.0,
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


def read_service(path: Path) -> dict:
    """A service table (:func:`day_service`'s, or sessions of them) read back."""
    try:
        table = json.loads(Path(path).read_text())
    except (OSError, ValueError) as exc:
        raise StationError(f"{path}: unreadable service times: {exc}") from None
    if not isinstance(table, dict) or table.get("format") != SERVICE_FORMAT:
        raise StationError(f"{path}: not a day's service times")
    for session in table.get("sessions", [table]):
        if session.get("format_version", 0) < 3:
            raise StationError(
                f"{path}: service times of an older calibration (no GEO law, no fill): "
                "measure them again (station capacity validate DAY_RUN --sessions 2)"
            )
    return table


def bracket(scn: DayScenario, out: Path, when: str, pool: DayPool, say: bool = True) -> None:
    """A calibration session measured at the day's time (``when``: ``"before"`` its clock,
    ``"after"`` it), added to ``<out>/``:data:`SERVICE_FILE`; one already there is kept (a
    resumed day). The machine of the day's minutes, not of the validation's."""
    from levels.files import write_json

    path = out / SERVICE_FILE
    sessions: list[dict] = read_service(path).get("sessions", []) if path.is_file() else []
    if any(s.get("when") == when for s in sessions):
        return
    t = time.time()
    sessions.append({**day_service(scn, out, pool), "when": when, "pool": pool.where})
    write_json(path, {"format": SERVICE_FORMAT, "sessions": sessions})
    if say:
        print(
            f"station day: service times measured {when} the clock, on calibration passes of "
            f"their own, in {time.time() - t:.0f} s",
            file=sys.stderr,
            flush=True,
        )
