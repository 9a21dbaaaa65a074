"""The station's reports, declared once: which file a directory's report is, its format's
name and version, what it says the directory is, and the one header every report opens
with (format, version, the software that wrote it).

``station run`` writes ``report.json`` (a pass, a block of passes, a SAR frame),
``station process`` ``process.json``, ``station campaign`` ``campaign.json``;
``station compare`` tells what wrote a directory by them (:func:`report_of`) and compares
only directories of one kind.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypedDict

from station import __version__
from station.errors import StationError

if TYPE_CHECKING:
    from station.sar_scenario import SarScenario
    from station.scenario import Scenario

__all__ = [
    "BLOCK_RUN",
    "CAMPAIGN",
    "DAY",
    "PASS_RUN",
    "PROCESS",
    "REPORTS",
    "SAR_RUN",
    "ReportFormat",
    "ScenarioEntry",
    "json_text",
    "report_of",
    "scenario_entry",
]


@dataclass(frozen=True)
class ReportFormat:
    """A report: its file in the directory, its format's name and version, and what the
    directory holding it is (in words, for messages)."""

    file: str
    name: str
    version: int
    what: str
    #: Where the report names what its directory is made of (its keys, in order): a
    #: scenario's name, the products' names; an output of another is not replaced.
    owner: tuple[str, ...] = ("scenario", "name")

    def owner_in(self, report: Mapping[str, object]) -> object:
        """What ``report`` (an earlier output's) says its directory is made of, or None."""
        value: object = report
        for key in self.owner:
            if not isinstance(value, Mapping) or key not in value:
                return None
            value = value[key]
        return value

    def header(self, **fields: Any) -> dict[str, object]:
        """The report's opening: its format, version and the software that wrote it, then
        ``fields`` (in order)."""
        return {
            "format": self.name,
            "format_version": self.version,
            "software": f"spot-station {__version__}",
            **fields,
        }


#: 2: one section per HRV ("hrvs"), products tagged by HRV.
PASS_RUN = ReportFormat("report.json", "spot-station-run", 2, "the run of a pass")
BLOCK_RUN = ReportFormat("report.json", "spot-station-block-run", 1, "the run of a block")
SAR_RUN = ReportFormat("report.json", "spot-station-sar-run", 1, "the run of a SAR frame")
PROCESS = ReportFormat("process.json", "spot-station-process", 1, "a reprocessing", ("names",))
CAMPAIGN = ReportFormat("campaign.json", "spot-station-campaign", 1, "a campaign", ("format",))
LIVE_PASS = ReportFormat("live.json", "spot-station-live-pass", 1, "a pass served live", ("pass",))
DAY = ReportFormat("day.json", "spot-station-day", 1, "a day at the station", ("day",))
#: Every report this version writes.
REPORTS = (PASS_RUN, BLOCK_RUN, SAR_RUN, PROCESS, CAMPAIGN, LIVE_PASS, DAY)


def report_of(d: Path) -> ReportFormat | None:
    """The report at the root of directory ``d`` (None if it has none); a report file of
    a format this version does not know is refused, naming it."""
    for file in dict.fromkeys(r.file for r in REPORTS):
        path = d / file
        if not path.is_file():
            continue
        try:
            fmt = json.loads(path.read_text(encoding="utf-8")).get("format")
        except (ValueError, UnicodeDecodeError, AttributeError):
            raise StationError(f"{path}: not a report (JSON object)") from None
        known = [r for r in REPORTS if r.file == file and r.name == fmt]
        if not known:
            names = ", ".join(r.name for r in REPORTS if r.file == file)
            raise StationError(f"{path}: format {fmt!r} is no report this version knows ({names})")
        return known[0]
    return None


class ScenarioEntry(TypedDict):
    """What a run's report says of its scenario."""

    name: str
    file: str
    sha256: str
    seed: int


def scenario_entry(scn: Scenario | SarScenario) -> ScenarioEntry:
    """What a run's report says of its scenario (a pass's or a SAR frame's): name, file,
    its bytes' SHA-256, seed."""
    return ScenarioEntry(
        name=scn.name,
        file=Path(scn.source).name if scn.source else "",
        sha256=scn.source_sha256,
        seed=scn.seed,
    )


def json_text(data: object) -> str:
    """A report (or any of its parts) as indented JSON, NumPy values as numbers."""
    from levels.files import json_default

    return json.dumps(data, indent=2, default=json_default)
