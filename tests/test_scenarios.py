"""Each shipped scenario against its expected summaries (scenarios/<name>/expected/):
the emulator's summary of every scenario, and ``station run``'s report of the reduced ones."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest

from station.loader import load_scenario
from station.spacecraft.emulator import emulate_pass
from station.spacecraft.summary import summarize

ROOT = Path(__file__).resolve().parents[1]
SCENARIOS = sorted((ROOT / "scenarios").glob("*.toml"))


def _update_expected() -> ModuleType:
    """``scenarios/update_expected.py``, the script that writes the expected files."""
    spec = importlib.util.spec_from_file_location(
        "update_expected", ROOT / "scenarios" / "update_expected.py"
    )
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


UPDATE = _update_expected()
# the reduced scenes, rendered and run end to end; the others are full-size: geometry only
RENDERED = UPDATE.RENDERED
COORD_TOL_DEG = 1e-6  # 0.1 m: integrator round-off across machines is far below
LENGTH_TOL_KM = 1e-4
MEAN_COUNTS_TOL = 0.05  # a few pixels rounding the other way on another CPU


# the rendered scenarios' summaries are checked on the acquisitions their run emulates
# (test_run_matches_its_expected_report): one rendering and one downlink each
@pytest.mark.parametrize(
    "path", [p for p in SCENARIOS if p.stem not in RENDERED], ids=lambda p: p.stem
)
def test_scenario_matches_its_expected_summary(path: Path) -> None:
    scn = load_scenario(path)
    _matches_summaries(scn.name, emulate_pass(scn, render=False))


def _matches_summaries(name: str, acqs, decoded: list[dict] | None = None) -> None:
    """Every HRV's summary against ``expected/summary.json``; ``decoded``: the downlink
    figures of a run of the same acquisitions (its report's ``decode``), else none."""
    expected = json.loads((ROOT / "scenarios" / name / "expected" / "summary.json").read_text())
    wanted = expected["hrvs"] if len(acqs) > 1 else [expected]  # one summary per HRV
    assert len(wanted) == len(acqs)
    for k, (acq, want) in enumerate(zip(acqs, wanted, strict=True)):
        _matches_summary(acq, want, None if decoded is None else decoded[k])


def _subset(got, want):
    """``got`` reduced to the keys ``want`` has (a run's report says more than a summary)."""
    if isinstance(want, dict) and isinstance(got, dict):
        return {k: _subset(got[k], w) if k in got else None for k, w in want.items()}
    if isinstance(want, list) and isinstance(got, list) and len(got) == len(want):
        return [_subset(g, w) for g, w in zip(got, want, strict=True)]
    return got


def _matches_summary(acq, expected: dict, decoded: dict | None) -> None:
    got = summarize(acq)
    if decoded is not None:  # counts of frames and lines: exact
        assert _subset(decoded, expected["downlink"]) == expected["downlink"]
    assert got["strip"] == expected["strip"] | {
        "satellite_altitude_km": pytest.approx(expected["strip"]["satellite_altitude_km"], abs=1e-6)
    }
    gf, ef = got["footprint"], expected["footprint"]
    assert np.ravel(gf["corners_lat_lon_deg"]) == pytest.approx(
        np.ravel(ef["corners_lat_lon_deg"]), abs=COORD_TOL_DEG
    )
    assert gf["centre_lat_lon_deg"] == pytest.approx(ef["centre_lat_lon_deg"], abs=COORD_TOL_DEG)
    assert gf["width_first_line_km"] == pytest.approx(ef["width_first_line_km"], abs=LENGTH_TOL_KM)
    assert gf["all_located"]
    assert [p["aos_utc"][:19] for p in got["passes"]] == [
        p["aos_utc"][:19] for p in expected["passes"]
    ]
    assert got["handover"] == expected["handover"]
    assert len(got["bands"]) == len(expected["bands"])
    for g, e in zip(got["bands"], expected["bands"], strict=True):
        assert g["mean_counts"] == pytest.approx(e["mean_counts"], abs=MEAN_COUNTS_TOL)
        assert g["failed_rays"] == e["failed_rays"] == 0


#: Named tolerances of a run's figures, by the unit at the end of their key. Geometry is
#: float64 throughout (checkpoints, approximation errors): across machines it moves by
#: round-off only. Figures read from images (stripe levels, valid fractions) can move by a
#: few pixels rounding the other way under numba's fastmath on another CPU.
RUN_TOL = {"_m": 0.01, "_px": 1e-4, "_counts": 0.02}
VALID_FRACTION_TOL = 1e-4
RUN_REL = 1e-6  # everything else numeric (MTF figures, ...)


def _close(got, want, key: str) -> bool:
    if isinstance(want, dict):
        return (
            isinstance(got, dict)
            and set(got) == set(want)
            and all(_close(got[k], want[k], f"{key}/{k}") for k in want)
        )
    if isinstance(want, list):
        return (
            isinstance(got, list)
            and len(got) == len(want)
            and all(_close(g, w, key) for g, w in zip(got, want, strict=True))
        )
    if isinstance(want, bool) or not isinstance(want, float | int) or "n_points" in key:
        return got == want  # counts, names, flags: exact
    tol = next((t for suffix, t in RUN_TOL.items() if key.endswith(suffix)), None)
    if "/valid_fraction/" in key:  # per band: ".../valid_fraction/P"
        tol = VALID_FRACTION_TOL
    if tol is None:
        return got == pytest.approx(want, rel=RUN_REL, abs=1e-12)
    return abs(got - want) <= tol


def _diff(got, want, key: str = "") -> list[str]:
    """The keys where a run departs from its expected report (for the failure message)."""
    if isinstance(want, dict) and isinstance(got, dict):
        return [
            d
            for k in sorted(set(got) | set(want))
            for d in (
                _diff(got.get(k), want.get(k), f"{key}/{k}")
                if k in got and k in want
                else [f"{key}/{k}: only in {'run' if k in got else 'expected'}"]
            )
        ]
    if isinstance(want, list) and isinstance(got, list) and len(got) == len(want):
        return [
            d
            for i, (g, w) in enumerate(zip(got, want, strict=True))
            for d in _diff(g, w, f"{key}[{i}]")
        ]
    return [] if _close(got, want, key) else [f"{key}: got {got!r}, expected {want!r}"]


@pytest.mark.parametrize("name", sorted(RENDERED))
def test_run_matches_its_expected_report(
    name: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import station.spacecraft.emulator as emulator
    from station.run import run_scenario

    want = json.loads((ROOT / "scenarios" / name / "expected" / "run.json").read_text())
    emulated = []

    def emulate(*args, **kwargs):
        acqs = emulate_pass(*args, **kwargs)
        if kwargs.get("render", True):  # the run's own (a DEM's export emulates one too)
            emulated[:] = acqs
        return acqs

    monkeypatch.setattr(emulator, "emulate_pass", emulate)
    report = run_scenario(
        load_scenario(ROOT / "scenarios" / f"{name}.toml"), tmp_path, quicklooks=False
    )
    # the emulator's summary of the same acquisitions, the downlink's counts the run's
    _matches_summaries(name, emulated, [h["decode"] for h in report["hrvs"]])
    got = UPDATE.expected_run(report)  # what scenarios/update_expected.py writes of it
    differences = _diff(got, want)
    assert not differences, "\n".join(differences[:20])
