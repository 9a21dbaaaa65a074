"""The files of outside producers mutated (issue 57): DIMAP zips, ERS frames in ESA's format
and control-point files, every count, size, offset and number field of each, handed to
``station locate`` and ``station process`` by ``tools/fuzz_inputs.py --kind files``.

Here a few hundred cases, as the tool runs them (a process of its own, in a directory of
its own: the failure it shrinks is left there); ``python tools/fuzz_inputs.py 10000 --kind
files`` runs the benchmark-style figure (docs/reliability.md). What must hold: no exit 3,
no case past the tool's bound (a hang), no case raising the peak memory past its bound.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: Cases in CI: about 50 ms each after the tool's base run (a small scene, 4 s).
CASES = 300
#: The whole run's bound (s): measured about 25 s on 2 cores; a hang of one case is the
#: tool's to stop (30 s), this one stops the tool.
RUN_BOUND_S = 300


def test_mutated_dimap_envisat_and_control_point_files_are_refused_cleanly(tmp_path) -> None:
    cmd = [sys.executable, str(ROOT / "tools" / "fuzz_inputs.py"), str(CASES), "--kind", "files"]
    done = subprocess.run(
        [*cmd, "--seed", "7"], cwd=tmp_path, capture_output=True, text=True, timeout=RUN_BOUND_S
    )
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    out = done.stdout
    assert f"{CASES} cases" in out
    assert "exit 3: 0; hangs (past 30 s): 0" in out
    for kind in ("dimap", "envisat", "gcps"):  # each format had its share
        line = next(ln for ln in out.splitlines() if ln.strip().startswith(kind))
        assert int(line.split()[1]) >= CASES // 10, line
