"""The reduced passes the several-pass tests run (tie points, blocks): 600 detectors with a
10× IFOV (100 m pixels, same swath and physics), 600 lines, 400 m of relief, up to 2A."""

from __future__ import annotations

from pathlib import Path

PASS = """
name = "{name}"
seed = {seed}
[pass]
date_utc = "{date}"
[instrument]
mirror_step = {step}
n_detectors = 600
n_lines = 600
[world]
relief_m = 400.0
[gcps]
count = {gcps}
[downlink]
bit_rate_mbps = 2.0
preamble_s = 0.1
postamble_s = 0.1
[processing]
levels = ["2A"]
{extra}
"""


def run_pass(
    d: Path, name: str, seed: int, date: str, step: int, gcps: int = 12, extra: str = ""
) -> tuple[Path, Path]:
    """A reduced pass (``PASS``) run end to end into ``d/name``: its scenario and run."""
    from station.cli import main

    scenario = d / f"{name}.toml"
    scenario.write_text(
        PASS.format(name=name, seed=seed, date=date, step=step, gcps=gcps, extra=extra)
    )
    run = d / name
    assert main(["run", str(scenario), "--out", str(run), "--quiet", "--no-quicklooks"]) == 0
    return scenario, run
