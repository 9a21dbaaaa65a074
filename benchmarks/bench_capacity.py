"""Speed of the capacity model: a simulated year of Cuiabá on one core.

The scenario is ``scenarios/capacity/cuiaba.toml`` (two satellites, both HRVs, every stage,
failures, shifts and a 3-day COR outage), one replication. Figures printed:

* the pass prediction: the orbit integrated over one 26-day repeat cycle and the passes
  over the station found in it, done once per station and reused by every replication;
* one replication of a year (plus the warm-up): wall time, the simpy events it took, and
  the ratio of simulated time to wall time (the peer: real time);
* the total against the target of issue 7: a simulated year in under 10 s on one core.

Run: ``python benchmarks/bench_capacity.py [days]`` (default: the scenario's 365). Python
and simpy are single-threaded; numpy's BLAS is not used in the loop.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import simpy
from _smoke import SMOKE

from station.capacity.config import load_capacity, with_value
from station.capacity.model import pass_pattern, simulate
from station.capacity.study import load_service

TARGET_S = 10.0
SCENARIO = Path(__file__).resolve().parents[1] / "scenarios" / "capacity" / "cuiaba.toml"


def main() -> None:
    scn = load_capacity(SCENARIO)
    if len(sys.argv) > 1 or SMOKE:
        scn = with_value(scn, "simulation.days", sys.argv[1] if len(sys.argv) > 1 else "10")
    service = load_service(scn)
    t0 = time.perf_counter()
    aos = pass_pattern(scn.ground_station).aos_s
    t_passes = time.perf_counter() - t0

    events = 0
    step = simpy.Environment.step

    def counting(env: simpy.Environment) -> None:
        nonlocal events
        events += 1
        step(env)

    simpy.Environment.step = counting  # type: ignore[method-assign]
    try:
        t0 = time.perf_counter()
        rep = simulate(scn, service, 0)
        t_sim = time.perf_counter() - t0
    finally:
        simpy.Environment.step = step  # type: ignore[method-assign]
    sim_days = scn.simulation.days + scn.simulation.warmup_days
    total = t_passes + t_sim
    st = rep.station
    print(
        f"scenario: {scn.name}, {len(scn.satellites)} satellites, "
        f"{scn.simulation.days:g} days + {scn.simulation.warmup_days:g} of warm-up"
    )
    print(f"pass prediction (one 26-day cycle, {aos.size} passes): {t_passes:.2f} s")
    print(
        f"simulation: {t_sim:.2f} s for {events} events ({events / t_sim / 1e3:.0f} k/s); "
        f"{st['passes']:.0f} passes, {st['scenes']:.0f} scenes, {st['products']:.0f} "
        f"products"
    )
    print(f"simulated time / wall time: {sim_days * 86400 / t_sim:.2e} × real time")
    print(
        f"total {total:.2f} s; target < {TARGET_S:.0f} s: ratio {TARGET_S / total:.1f} "
        f"({'met' if total < TARGET_S else 'NOT met'})"
    )


if __name__ == "__main__":
    main()
