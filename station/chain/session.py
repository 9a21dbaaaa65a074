"""One pass through the station's front end: send, impair, receive, record.

:func:`downlink` runs the sender (:mod:`station.spacecraft.downlink`), the channel
(:mod:`station.spacecraft.channel`) and the receiver (:mod:`station.srrs.receiver`) on an
emulated acquisition, with the random draws of the downlink and the channel seeded from the
scenario's seed apart from the emulator's own streams; :func:`record` writes the L0 archive.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from station.spacecraft.channel import Reception, impair
from station.spacecraft.downlink import Transmission, transmit
from station.spacecraft.emulator import Acquisition
from station.spacecraft.passes import elevation_rad
from station.srrs.receiver import DecodedPass, receive
from station.srrs.recorder import BandAncillary, write_l0

__all__ = ["DownlinkResult", "ancillary_of", "downlink", "record"]

_DOWNLINK_STREAM = 100  # spawn key of the downlink's random stream, apart from the emulator's


@dataclass(frozen=True, eq=False)
class DownlinkResult:
    """The three stages of one pass and the wall time each took (s)."""

    transmission: Transmission
    reception: Reception
    decoded: DecodedPass
    timings_s: dict[str, float] = field(default_factory=dict)


def downlink(acq: Acquisition) -> DownlinkResult:
    """Send an acquisition through the scenario's downlink and channel, and receive it.

    Each HRV has its own X-band channel (SPOT 1–4's two image channels), with its own
    random draws; a scenario's outage strikes both.
    """
    scn = acq.scenario
    key = (_DOWNLINK_STREAM,) if acq.index == 0 else (_DOWNLINK_STREAM, acq.index)
    rng_tx, rng_ch = np.random.default_rng(np.random.SeedSequence(scn.seed, spawn_key=key)).spawn(2)
    clock = time.perf_counter
    t0 = clock()
    tx = transmit(acq, scn.downlink, rng_tx)
    t1 = clock()
    gs = scn.ground_station
    elev = elevation_rad(acq.orbit, tx.slot_t_s, gs.lat_rad, gs.lon_rad, gs.height_m)
    rx = impair(tx.cadus, tx.slot_t_s, elev, scn.channel, tx.bit_rate_bit_per_s, rng_ch)
    t2 = clock()
    decoded = receive(rx.stream, rx.n_bits)
    t3 = clock()
    return DownlinkResult(
        tx, rx, decoded, {"transmit": t1 - t0, "channel": t2 - t1, "receive": t3 - t2}
    )


def ancillary_of(acq: Acquisition) -> list[BandAncillary]:
    """What the station is handed per band besides telemetry (nominal tables)."""
    return [
        BandAncillary(b.name, b.look_nominal, b.table_gain, b.table_offset_counts)
        for b in acq.hrv.bands
    ]


def record(acq: Acquisition, result: DownlinkResult, path: str | Path) -> Path:
    """Write the L0 archive of a received pass, with the bulletins and nominal tables."""
    scn = acq.scenario
    return write_l0(
        path,
        result.decoded,
        acq.bulletins,
        acq.epoch.t0_utc,
        ancillary_of(acq),
        scenario_name=scn.name,
        provenance=scn.provenance(),
        scene_cut={
            "scene_lines": scn.processing.scene_lines,
            "overlap_lines": scn.processing.overlap_lines,
        },
    )
