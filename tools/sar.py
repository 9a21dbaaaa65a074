"""The SAR scenarios at the size you ask, through ``station run``'s own code (issue 38):
each frame emulated, geocoded (GEC, GTC), measured against the truth, its table printed.

    python tools/sar.py                      # both shipped scenarios, as shipped
    python tools/sar.py --set sar.lines=1000 --set sar.samples=1000 --out runs/sar_1000
    python tools/sar.py ers_gec --set sar.state_error_m=1.0

The runs go to ``<out>/<scenario>`` (default ``runs/sar``); ``--set SECTION.KEY=VALUE``
changes a key of the scenarios (``[sar]``, ``[world]``, ``[dem]``; values in JSON). A
full-size frame (8300 lines of 3 azimuth looks × 5000 samples, 12.5 m pixels) takes
minutes and memory: the truth's masks are computed four times finer than the output.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import tomllib
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from overrides import scenario_changes

ROOT = Path(__file__).resolve().parents[1]


def main(argv: list[str] | None = None) -> int:
    from levels.options import build_section
    from station.errors import ScenarioError
    from station.loader import load_sar
    from station.run_sar import run_sar, sar_summary
    from station.sar_scenario import SECTIONS

    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("names", nargs="*", default=["ers_gec", "ers_gtc"])
    p.add_argument("--set", action="append", default=[], metavar="SECTION.KEY=VALUE")
    p.add_argument("--out", default="runs/sar")
    args = p.parse_args(argv)
    changes = scenario_changes(args.set)
    for name in args.names:
        path = ROOT / "scenarios" / "sar" / f"{name}.toml"
        scn = load_sar(path)
        table = tomllib.loads(path.read_text())
        for section, keys in changes.items():
            if section not in SECTIONS:
                raise ScenarioError(f"--set {section}.…: a SAR scenario has {list(SECTIONS)}")
            merged = {**table.get(section, {}), **keys}
            built = build_section(SECTIONS[section], section, merged, ScenarioError)
            scn = dataclasses.replace(scn, **{section: built})
        out = Path(args.out) / scn.name
        report = run_sar(scn, out)
        print(sar_summary(report, out))
        print(f"  times (s): {report['timings_s']}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
