"""Fuzz the receiver: random and mutated byte streams, no unhandled exception allowed.

Every input must give either a decoded pass whose accounts balance (delivered + lost =
sent on every channel) or a :class:`~station.srrs.receiver.ReceiverError`; anything else is
printed with the seed that reproduces it, and the script exits with status 1.

Run: ``python tools/fuzz_receiver.py [n_inputs] [seed]`` (default 100000, 0). The base
streams are a reduced P and a reduced XS pass (clean), emulated once.
"""

from __future__ import annotations

import sys
import time
import traceback
from collections import Counter

import numpy as np

from station.chain.fuzzing import frames_of, mutate
from station.scenario import scenario_from_dict
from station.spacecraft.downlink import transmit
from station.spacecraft.emulator import emulate
from station.srrs.receiver import ReceiverError, receive

_DOWN = {"bit_rate_mbps": 0.25, "preamble_s": 0.02, "postamble_s": 0.02}
BASES = [
    {"seed": 1, "instrument": {"n_detectors": 200, "n_lines": 60}, "downlink": _DOWN},
    {"seed": 2, "instrument": {"mode": "XS", "n_detectors": 100, "n_lines": 40}, "downlink": _DOWN},
]


def main() -> int:
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 100_000
    seed = int(sys.argv[2]) if len(sys.argv) > 2 else 0
    bases = []
    for spec in BASES:
        scn = scenario_from_dict({**spec, "pass": {"ground_pass_days": 0.0}, "gcps": {"count": 0}})
        acq = emulate(scn)
        tx = transmit(acq, scn.downlink, np.random.default_rng(0))
        bases.append((tx.cadus.ravel(), frames_of(tx.cadus)))
    outcomes: Counter[str] = Counter()
    failures = 0
    t0 = time.perf_counter()
    for i in range(n):
        rng = np.random.default_rng([seed, i])
        stream, frames = bases[i % len(bases)]
        kind, data = mutate(stream, frames, rng)
        try:
            d = receive(data)
            balanced = all(a.delivered + a.lost == a.sent for a in d.accounts.values())
            outcomes["decoded" if balanced else "UNBALANCED"] += 1
            failures += not balanced
        except ReceiverError:
            outcomes["receiver_error"] += 1
        except Exception:  # the whole point: report anything else
            failures += 1
            outcomes["UNHANDLED"] += 1
            print(f"input {i} (seed [{seed}, {i}], {kind}): unhandled exception")
            traceback.print_exc()
        if (i + 1) % 10_000 == 0:
            print(f"{i + 1} inputs, {time.perf_counter() - t0:.0f} s: {dict(outcomes)}", flush=True)
    print(f"{n} inputs in {time.perf_counter() - t0:.0f} s: {dict(outcomes)}")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
