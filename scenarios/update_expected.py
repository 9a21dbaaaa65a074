"""Regenerate ``scenarios/expected/<name>.json`` from the current code.

Run only when a change of results is intended and understood; the diff of the JSON files is
then the record of what changed. ``tests/test_scenarios.py`` compares runs with these files.
Geometry only (``render=False``) except for ``small_test``, which is rendered.
"""

from __future__ import annotations

import json
from pathlib import Path

from station.scenario import load_scenario
from station.spacecraft.emulator import emulate
from station.spacecraft.summary import summarize

HERE = Path(__file__).resolve().parent
RENDERED = {"small_test"}


def main() -> None:
    for path in sorted(HERE.glob("*.toml")):
        scn = load_scenario(path)
        summary = summarize(emulate(scn, render=scn.name in RENDERED))
        out = HERE / "expected" / f"{path.stem}.json"
        out.write_text(json.dumps(summary, indent=2) + "\n")
        print(f"wrote {out.relative_to(HERE.parent)}")


if __name__ == "__main__":
    main()
