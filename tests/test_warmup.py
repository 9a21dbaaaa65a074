"""The warm-up that compiles the processing kernels ahead of a first run (levels.warmup):
its archive is this version's L0, and it compiles every kernel a default run calls, with
the types the run calls it with."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: A fresh interpreter runs the warm-up, then a whole default run (emulation included);
#: with a cold cache both compile, about 70 s of one core on a slow host.
SUBPROCESS_TIMEOUT_S = 400

#: In a fresh interpreter: the warm-up, a snapshot of the compiled signatures of every
#: numba kernel of ``levels``, a default ``station run``, and what it compiled beyond them.
_CHECK = """
import importlib, json, pkgutil, sys
import numba.core.registry
import levels
from levels.warmup import warm_up

warm_up()

def kernels():
    out = {}
    for m in pkgutil.walk_packages(levels.__path__, "levels."):
        mod = importlib.import_module(m.name)
        for name, obj in vars(mod).items():
            if isinstance(obj, numba.core.registry.CPUDispatcher) and obj.__module__ == m.name:
                out[f"{m.name}.{name}"] = {str(s) for s in obj.overloads}
    return out

before = kernels()
from station.cli import main
assert main(["run", sys.argv[1], "--out", sys.argv[2], "--quiet", "--no-quicklooks"]) == 0
after = kernels()
print(json.dumps({k: sorted(v - before.get(k, set())) for k, v in after.items()}))
"""


def test_warm_up_compiles_every_kernel_of_a_default_run(tmp_path: Path) -> None:
    """After the warm-up, a default run (the quickstart's P pass, reduced) calls no kernel
    of ``levels`` with types it has not compiled: with the warm-up's cache, the run's
    processing compiles nothing."""
    scenario = ROOT / "scenarios" / "small_test.toml"
    done = subprocess.run(
        [sys.executable, "-c", _CHECK, str(scenario), str(tmp_path / "run")],
        capture_output=True,
        text=True,
        timeout=SUBPROCESS_TIMEOUT_S,
        cwd=tmp_path,
        env=os.environ.copy(),
        check=False,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    new = json.loads(done.stdout.strip().splitlines()[-1])
    assert {k: v for k, v in new.items() if v} == {}
    assert len(new) >= 10  # the walk found the kernels (radiometry, resampling, grids, …)


@pytest.mark.skipif((os.cpu_count() or 1) < 2, reason="one core: no warm-up is started")
def test_a_failed_run_ends_the_warm_up_it_started(monkeypatch, tmp_path: Path) -> None:
    """The emulation fails while the warm-up compiles: the run stops the process it
    started (killed, not left to finish) and the error comes through."""
    import levels.warmup
    import station.spacecraft.emulator
    from station.loader import load_scenario
    from station.run import run_scenario

    started = []
    real_start = levels.warmup.start_warm_up
    monkeypatch.setattr(levels.warmup, "cache_is_cold", lambda: True)
    monkeypatch.setattr(
        levels.warmup, "start_warm_up", lambda: started.append(real_start()) or started[-1]
    )

    def broken(_scn):
        raise RuntimeError("emulator down")

    monkeypatch.setattr(station.spacecraft.emulator, "emulate_pass", broken)
    scn = load_scenario(ROOT / "scenarios" / "small_test.toml")
    with pytest.raises(RuntimeError, match="emulator down"):
        run_scenario(scn, tmp_path / "run", warm_up=True)
    (process,) = started
    assert process is not None
    assert process.returncode is not None and process.returncode < 0  # killed by the run
