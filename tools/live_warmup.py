"""Regenerate ``station/data/warmup.cadu``: what ``station serve`` decodes once before it
listens, so that its receiver's kernels are loaded (numba's cache) before the first pass
arrives, not while it does. It is 128 kB of the stream of ``scenarios/warmup.toml``'s pass
(the one ``levels/data/warmup.l0.h5`` holds) as the channel delivers it, from 4 kB before
its first data frame: fill and data frames, a line's packets, their time codes.

    python tools/live_warmup.py
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from station.chain.session import downlink
from station.loader import load_scenario
from station.spacecraft.emulator import emulate_pass
from station.srrs.receiver import receive

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "station" / "data" / "warmup.cadu"
WINDOW_BYTES, LEAD_BYTES = 128 << 10, 4 << 10


def main() -> None:
    (acq,) = emulate_pass(load_scenario(ROOT / "scenarios" / "warmup.toml"))
    rx = downlink(acq).reception
    decoded = receive(rx.stream, rx.n_bits)
    first = int(decoded.frame_bit_offset[np.flatnonzero(decoded.frame_vc == 1)[0]] // 8)
    start = max(0, first - LEAD_BYTES)
    OUT.write_bytes(rx.stream[start : start + WINDOW_BYTES].tobytes())
    print(f"{OUT}: {WINDOW_BYTES} bytes from byte {start} of the warm-up pass's stream")


if __name__ == "__main__":
    main()
