"""Products while the pass goes on (``station serve --levels 1A,2A``): each scene made as
soon as its lines are in, while later scenes still arrive.

At every archive the front end writes while a channel's stream arrives
(:mod:`station.live.frontend`), the scenes whose last line has arrived, with a margin of
lines beyond it (:data:`MARGIN_S` of them: the gyro records GEO interpolates across a
scene's ends), are handed to one worker. It makes them from that archive through the unit
of work (:mod:`levels.work`, ``Request.scenes``), each once, into the pass's directory, the
ingest going on meanwhile. At the stream's end the scenes left are made from the whole
pass's archive.

A scene made early is made on the pass as known then. Its line clock and its attitude are
fitted over the lines arrived so far, so its products are the pass's near-real-time ones,
not byte for byte those a reprocessing of the whole archive makes (a real station's
near-real-time products differ from its archive's in the same way). The pass's report says,
per scene, when its last line was in the archive, when its products were written, the
latency between, and whether that was before the stream ended (LOS).
"""

from __future__ import annotations

import logging
import threading
import time
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from station.srrs.receiver import DecodedPass

__all__ = ["MARGIN_S", "NearRealTime"]

_log = logging.getLogger(__name__)

#: Seconds of lines a scene waits for beyond its last line before it is made.
MARGIN_S = 1.0


@dataclass(eq=False)
class _Channel:
    """What the worker knows of one channel: its scenes made or handed over, when each
    scene's last line was first in an archive."""

    tag: str
    where: Path
    scene_cut: dict[str, int]
    started_s: float
    handed: set[int] = field(default_factory=set)
    last_line_at: dict[int, float] = field(default_factory=dict)
    made: list[dict[str, object]] = field(default_factory=list)
    jobs: list[Future] = field(default_factory=list)
    los_s: float | None = None


class NearRealTime:
    """One worker making the scenes of every channel as they complete (module docstring)."""

    def __init__(self, levels: tuple[str, ...]) -> None:
        self.levels = levels
        self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="nrt")
        self._channels: dict[str, _Channel] = {}
        self._lock = threading.Lock()

    def channel(self, tag: str, where: Path, scene_cut: dict[str, int], started_s: float) -> None:
        """A channel's stream has begun."""
        self._channels[tag] = _Channel(tag, where, dict(scene_cut), started_s)

    def archived(self, tag: str, path: Path, decoded: DecodedPass, final: bool = False) -> None:
        """The front end has written ``path``, the archive of ``decoded`` so far (``final``:
        the whole stream's): hand over the scenes it completes."""
        c = self._channels[tag]
        now = time.perf_counter()
        n_lines, n_det = decoded.images[0].shape
        rows = np.flatnonzero(decoded.valid[0].any(axis=1))
        last = int(rows[-1]) if rows.size else -1
        margin = int(np.ceil(MARGIN_S / max(decoded.line_period_s, 1e-6)))
        from levels.geo.scenes import cut_scenes

        lines = c.scene_cut.get("scene_lines") or n_det
        ready = []
        for cut in cut_scenes(n_lines, lines, c.scene_cut.get("overlap_lines", 0)):
            end = cut.first_line + cut.n_lines - 1
            if last >= end:
                c.last_line_at.setdefault(cut.index, now)
            if cut.index not in c.handed and (final or last >= end + margin):
                ready.append(cut.index)
        if final:
            c.los_s = now - c.started_s
        if not ready:
            return
        c.handed.update(ready)
        c.jobs.append(self._pool.submit(self._make, c, path, frozenset(ready)))

    def _make(self, c: _Channel, path: Path, scenes: frozenset[int]) -> None:
        from levels.options import ProcessingOptions
        from levels.readers.l0 import read_l0
        from levels.work import Pass, Request, plan, run

        try:
            archive = read_l0(path)  # whole, before the next archive replaces it
            options = ProcessingOptions(
                levels=self.levels,
                scene_lines=c.scene_cut.get("scene_lines", 0),
                overlap_lines=c.scene_cut.get("overlap_lines", 0),
            )
            work = plan(Request(options, c.where, (Pass((archive,), (c.tag,)),), scenes=scenes))
            result = run(work)
        except Exception as exc:  # said, the front end goes on
            _log.warning("%s: scenes %s not made: %s", c.tag, sorted(scenes), exc)
            return
        done = time.perf_counter()
        for m in result.products:
            k = m.scene[0] if m.scene else -1
            at = c.last_line_at.get(k)
            c.made.append(
                {
                    "scene": k,
                    "level": m.kind,
                    "file": m.path.name,
                    "last_line_s": None if at is None else round(at - c.started_s, 3),
                    "made_s": round(done - c.started_s, 3),
                    "latency_s": None if at is None else round(done - at, 3),
                }
            )
        _log.info("%s: scenes %s made (%s)", c.tag, sorted(scenes), ", ".join(self.levels))

    def finish(self, tag: str) -> list[dict[str, object]]:
        """Wait for a channel's scenes; what was made, with its latencies, in order."""
        c = self._channels[tag]
        for job in c.jobs:
            job.result()
        for row in c.made:
            made = row["made_s"]
            row["before_los"] = c.los_s is not None and isinstance(made, float) and made < c.los_s
        return sorted(c.made, key=lambda r: str(r["file"]))  # scene by scene, then level

    def close(self) -> None:
        self._pool.shutdown(wait=True)
