"""The service times of a day's stages, measured on this machine on a pass of their own (not
the day's): what ``station capacity validate`` gives the capacity model.

A calibration pass (both HRVs, one in P and one in XS, :data:`SCENES` scenes each, the
day's reduced sizes and rate, a seed of its own) is emulated, then sent to a front end
(``station serve``, in its own process, as in the day) at the day's clock times the line
rate: per channel, the wall time from its first byte to its archive written, per second of
signal (**ingest**), and from then to its scenes catalogued, per scene (**GEO**). Then
each order kind (mode × level) is made :data:`REPEATS` times from its archive by the
day's kind of worker (a spawned process, warm), one job at a time: the wall time from
dispatch to the product catalogued (**COR**), its mean and coefficient of variation.
"""

from __future__ import annotations

import json
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context
from pathlib import Path

import numpy as np

from station.archive_catalogue import CATALOGUE_FILE
from station.capacity.plan import PlannedPass, PlannedSegment
from station.day import work
from station.day.config import DayScenario
from station.day.preflight import SCENE_S

__all__ = ["REPEATS", "SCENES", "day_service"]

SCENES = 2
REPEATS = 3
LEVELS = ("1A", "1B", "2A")
#: Added to the day's seed: the calibration pass is not one of the day's.
CALIBRATION_SEED = 424242


def _stats(x: list[float]) -> dict[str, float]:
    a = np.asarray(x, float)
    return {
        "mean_s": float(a.mean()),
        "cv": float(a.std(ddof=1) / a.mean()) if a.size > 1 else 0.0,
        "n": int(a.size),
    }


def day_service(scn: DayScenario, workdir: Path | None = None) -> dict[str, object]:
    """The day's service times measured (module docstring), as a table."""
    from station.day.run import _start_front_end, _stop
    from station.live.sender import send_streams

    day = scn.day
    segments = (PlannedSegment(1, "P", SCENES), PlannedSegment(2, "XS", SCENES))
    p = PlannedPass("calibration", "SPOT 1", 0.0, 600.0, segments)
    with tempfile.TemporaryDirectory(dir=workdir) as tmp:
        out = Path(tmp)
        (out / "passes").mkdir()
        toml = out / "passes" / "calibration.toml"
        toml.write_text(
            work.pass_scenario(
                p,
                scn.capacity.seed + CALIBRATION_SEED,
                day.start_s,
                day.p_detectors,
                day.bit_rate_mbps,
            )
        )
        ctx = get_context("spawn")
        with ProcessPoolExecutor(1, mp_context=ctx, initializer=work.warm) as pool:
            ann, chans, one = pool.submit(work.emulate, str(toml)).result()
            proc, port = _start_front_end(out, 1)
            try:
                send_streams(ann, chans, "127.0.0.1", port, day.clock, one)
            finally:
                _stop(proc, 120.0)
            live = json.loads((out / "archive" / "calibration" / "live.json").read_text())
            signal_s = SCENES * SCENE_S + 0.2
            ingest = [c["archived_s"] / signal_s for c in live["channels"]]
            geo = [(c["catalogued_s"] - c["archived_s"]) / SCENES for c in live["channels"]]
            cor: dict[str, dict[str, dict[str, float]]] = {}
            for s in segments:
                l0 = out / "archive" / "calibration" / f"{work.channel_tag(p, s.hrv)}.l0.h5"
                cor[s.mode] = {}
                for level in LEVELS:
                    times = []
                    for k in range(REPEATS):
                        t = time.time()
                        pool.submit(
                            work.make_order,
                            str(l0),
                            k % SCENES,
                            level,
                            str(out / "products"),
                            str(out / "archive" / CATALOGUE_FILE),
                        ).result()
                        times.append(time.time() - t)
                    cor[s.mode][level] = _stats(times)
    return {
        "format": "spot-station-day-service-times",
        "format_version": 1,
        "measured_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        "clock": day.clock,
        "p_detectors": day.p_detectors,
        "ingest_s_per_signal_s": _stats(ingest),
        "geo_s_per_scene": {s.mode: _stats([g]) for s, g in zip(segments, geo, strict=True)},
        "cor_s": cor,
    }
