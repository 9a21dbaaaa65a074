"""Regenerate ``scenarios/expected/<name>.json`` from the current code.

Run only when a change of results is intended and understood; the diff of the JSON files is
then the record of what changed. ``tests/test_scenarios.py`` compares runs with these files.
Geometry only (``render=False``) except for the reduced scenes, which are rendered and also
sent through the downlink: their ``downlink`` entry is the comparable part of the report.
"""

from __future__ import annotations

import json
from pathlib import Path

from station.scenario import load_scenario
from station.spacecraft.emulator import emulate
from station.spacecraft.summary import summarize
from station.srrs.report import comparable, downlink_report
from station.srrs.session import downlink

HERE = Path(__file__).resolve().parent
RENDERED = {"small_test", "noisy_channel"}


def main() -> None:
    for path in sorted(HERE.glob("*.toml")):
        scn = load_scenario(path)
        acq = emulate(scn, render=scn.name in RENDERED)
        summary = summarize(acq)
        if scn.name in RENDERED:
            summary["downlink"] = comparable(downlink_report(acq, downlink(acq)))
        out = HERE / "expected" / f"{path.stem}.json"
        out.write_text(json.dumps(summary, indent=2) + "\n")
        print(f"wrote {out.relative_to(HERE.parent)}")


if __name__ == "__main__":
    main()
