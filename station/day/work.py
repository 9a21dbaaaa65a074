"""What a day's processes do: each planned pass as a pass scenario, its emulation (before
the clock starts: the spacecraft is not the station's load), and one order's product made
from the pass's L0 archive and catalogued (a processing worker's job).

These run in the worker processes (``concurrent.futures`` with the spawn context): plain
functions of plain arguments.
"""

from __future__ import annotations

import os
import time
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from station.capacity.plan import PlannedPass

if TYPE_CHECKING:
    from station.live.sender import Stream
    from station.live.wire import Announcement

__all__ = ["channel_tag", "emulate", "make_order", "pass_scenario", "scene_id", "warm"]

#: The day's passes are dated from the capacity model's pass pattern: its epoch's day.
PATTERN_DATE = np.datetime64("1998-02-20", "D")


def channel_tag(p: PlannedPass, hrv: int) -> str:
    """The name of an HRV's channel and archive (``station run``'s: the pass's name, with
    ``_hrv<k>`` when both HRVs image)."""
    return p.name if len(p.segments) == 1 else f"{p.name}_hrv{hrv}"


def scene_id(p: PlannedPass, hrv: int, scene: int) -> str:
    """A scene's id in the catalogue (:func:`station.archive_catalogue.archive_items`)."""
    return f"{channel_tag(p, hrv)}_s{scene:03d}"


def pass_scenario(
    p: PlannedPass, seed: int, start_s: float, p_detectors: int, bit_rate_mbps: float
) -> str:
    """A planned pass as a pass scenario (TOML text): each HRV's segment of reduced scenes
    (``p_detectors`` in P, half in XS, a scene as many lines as detectors), dated on the
    pass's day."""
    day = PATTERN_DATE + np.timedelta64(int((start_s + p.aos_s) // 86400.0), "D")
    lines = [
        f"# {p.satellite}'s pass at {p.aos_s:.0f} s into the day (station day)",
        f'name = "{p.name}"',
        f"seed = {seed}",
        "",
        "[pass]",
        f'date_utc = "{day}"',
        "",
        "[downlink]",
        f"bit_rate_mbps = {bit_rate_mbps}",
        "preamble_s = 0.1",
        "postamble_s = 0.1",
    ]
    for s in p.segments:
        n = p_detectors if s.mode == "P" else p_detectors // 2
        lines += [
            "",
            "[[instrument]]" if len(p.segments) > 1 else "[instrument]",
            f"hrv = {s.hrv}",
            f'mode = "{s.mode}"',
            f"n_detectors = {n}",
            f"n_lines = {n * s.scenes}",
        ]
    return "\n".join(lines) + "\n"


def warm() -> int:
    """A worker's start: the kernels loaded before the clock starts (its process id)."""
    from levels.warmup import warm_up

    warm_up()
    return os.getpid()


def emulate(scenario: str) -> tuple[Announcement, list[Stream], bool]:
    """A pass's scenario emulated into its channels' streams
    (:func:`station.live.sender.emulated_streams`)."""
    from station.live.sender import emulated_streams

    return emulated_streams(Path(scenario))


def make_order(l0: str, scene: int, level: str, out_dir: str, catalogue: str) -> dict[str, object]:
    """One order's product: level ``level`` of scene ``scene`` of the archive ``l0`` made
    into ``out_dir`` and catalogued in ``catalogue`` (one transaction); when it ran (the
    wall clock) and what it wrote."""
    t0 = time.time()
    from levels.options import ProcessingOptions
    from levels.readers.l0 import read_l0
    from levels.work import Pass, Request, plan, run
    from station.archive_catalogue import Catalogue, add_products

    archive = read_l0(l0)
    cut = archive.scene_cut
    options = ProcessingOptions(
        levels=(level,),
        scene_lines=int(cut.get("scene_lines", 0)),
        overlap_lines=int(cut.get("overlap_lines", 0)),
    )
    tag = Path(l0).name.removesuffix(".l0.h5")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    work = plan(Request(options, out, (Pass((archive,), (tag,)),), scenes=frozenset({scene})))
    result = run(work)
    paths = [m.path for m in result.products]
    t1 = time.time()
    with Catalogue(catalogue) as cat:
        add_products(cat, paths)
    return {
        "started_unix": t0,
        "made_unix": t1,
        "done_unix": time.time(),
        "files": [p.name for p in paths],
        "pid": os.getpid(),
    }
