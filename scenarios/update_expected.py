"""Regenerate ``scenarios/<name>/expected/`` from the current code.

Run only when a change of results is intended and understood; the diff of the JSON files is
then the record of what changed. ``tests/test_scenarios.py`` compares runs with these files.

- ``summary.json``: the emulator's summary of every scenario (geometry only, ``render=False``,
  except for the reduced scenes, which are rendered and also sent through the downlink:
  their ``downlink`` entry is the comparable part of the downlink report). A scenario
  imaged by both HRVs has one summary per HRV, under ``hrvs``.
- ``run.json``: for the reduced scenes, the comparable part of ``station run``'s report
  (decode statistics, products, quality figures; no wall times or file sizes).
"""

from __future__ import annotations

import json
import sys
import tempfile
from pathlib import Path

from station.chain.report import comparable, downlink_report
from station.chain.session import downlink
from station.loader import load_scenario
from station.run import comparable_report, run_scenario
from station.spacecraft.emulator import emulate_pass
from station.spacecraft.summary import summarize

HERE = Path(__file__).resolve().parent
#: Reduced scenes: rendered, sent through the downlink and run end to end in the tests.
RENDERED = {
    "antimeridian",
    "quickstart",
    "small_test",
    "noisy_channel",
    "tilt27_rugged",
    "cuiaba_pass",
    "westin_gap",
    "pass_ends",
    "single_gcp",
    "twin_gcp",
    "fractal_relief",
    "dem_errors",
}


def expected_run(report: dict) -> dict:
    """What ``run.json`` holds of a run's report (the software version left out)."""
    rep = comparable_report(report)
    rep.pop("software", None)
    return rep


def main(names: list[str]) -> None:
    for path in sorted(HERE.glob("*.toml")):
        if names and path.stem not in names:
            continue
        scn = load_scenario(path)
        summaries = []
        for acq in emulate_pass(scn, render=scn.name in RENDERED):
            summaries.append(summarize(acq))
            if scn.name in RENDERED:
                summaries[-1]["downlink"] = comparable(downlink_report(acq, downlink(acq)))
        summary = summaries[0] if len(summaries) == 1 else {"hrvs": summaries}
        out = HERE / path.stem / "expected"
        out.mkdir(parents=True, exist_ok=True)
        if scn.name in RENDERED:
            with tempfile.TemporaryDirectory() as tmp:
                report = run_scenario(scn, tmp, quicklooks=False)
            (out / "run.json").write_text(json.dumps(expected_run(report), indent=2) + "\n")
            print(f"wrote {(out / 'run.json').relative_to(HERE.parent)}")
        (out / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
        print(f"wrote {(out / 'summary.json').relative_to(HERE.parent)}")


if __name__ == "__main__":
    main(sys.argv[1:])
