"""Scenario files: defaults, SI conversion once, and clear rejections naming key and value."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from station.loader import describe_keys, load_scenario
from station.scenario import (
    Scenario,
    ScenarioError,
    scenario_from_dict,
)

ROOT = Path(__file__).resolve().parents[1]


def test_three_lines_are_a_scenario(tmp_path: Path) -> None:
    f = tmp_path / "s.toml"
    f.write_text('name = "izmit"\n[instrument]\nmirror_step = 93\n')
    scn = load_scenario(f)
    assert scn.name == "izmit"
    assert scn.instrument.mirror_step == 93
    assert scn.orbit == Scenario().orbit  # every other section defaults
    assert scn.base_dir == str(tmp_path)


def test_both_hrvs_are_two_instrument_tables(tmp_path: Path) -> None:
    f = tmp_path / "s.toml"
    f.write_text('[[instrument]]\nhrv = 2\nmode = "XS"\n[[instrument]]\nhrv = 1\n')
    scn = load_scenario(f)
    assert [(i.hrv, i.mode) for i in scn.instruments] == [(2, "XS"), (1, "P")]
    assert scn.instrument is scn.instruments[0]  # the first aims the orbit
    assert load_scenario(ROOT / "scenarios" / "small_test.toml").more_instruments == ()


def test_units_converted_once_to_si() -> None:
    scn = scenario_from_dict(
        {
            "orbit": {"kind": "elements", "altitude_km": 830.0, "inclination_deg": 98.0},
            "attitude": {"roll_offset_urad": 100, "jitter_amplitude_urad": [1, 2, 3]},
        }
    )
    assert scn.orbit.altitude_m == 830e3
    assert scn.orbit.inclination_rad == pytest.approx(math.radians(98.0), rel=1e-15)
    assert scn.attitude.roll0_rad == pytest.approx(100e-6, rel=1e-15)
    assert scn.attitude.jitter_amplitude_rad == pytest.approx((1e-6, 2e-6, 3e-6), rel=1e-15)
    # defaults are in SI too
    assert Scenario().ground_station.elevation_mask_rad == pytest.approx(math.radians(5.0))


@pytest.mark.parametrize(
    ("table", "message"),
    [
        ({"orbit": {"altitude": 800}}, "[orbit] unknown key 'altitude'; allowed: altitude_km"),
        ({"orbits": {}}, "unknown key 'orbits'"),
        ({"orbit": {"altitude_km": "822"}}, "[orbit] altitude_km = '822': expected a number"),
        ({"orbit": {"altitude_km": 5000}}, "expected a number in [200, 2000]"),
        ({"orbit": {"kind": "sgp4"}}, "one of 'phased', 'elements', 'tle'"),
        ({"orbit": {"kind": "tle"}}, "needs tle_path"),
        ({"instrument": {"mirror_step": 2.0}}, "mirror_step = 2.0: expected an integer"),
        ({"instrument": {"twin": "yes"}}, "twin = 'yes': expected true or false"),
        ({"instrument": {"mode": "XS", "n_detectors": 6000}}, "XS has at most 3000"),
        ({"instrument": {"first_detector": 5990, "detector_count": 20}}, "within the 6000"),
        ({"attitude": {"jitter_amplitude_urad": [1, 2]}}, "a list of 3 numbers"),
        ({"attitude": {"drift_scale": math.nan}}, "drift_scale = nan"),
        ({"pass": {"date_utc": "20 Feb 1998"}}, "expected a UTC day"),
        ({"seed": -1}, "seed = -1"),
        ({"seed": True}, "seed = True"),
        ({"world": []}, "[world] must be a table"),
        ({"instrument": [{"hrv": 1}, {"hrv": 1, "mode": "XS"}]}, "hrv = [1, 1]"),
        ({"instrument": [{"hrv": 1}, {"hrv": 2}, {}]}, "given 3 times"),
        ({"instrument": [{"hrv": 1}, {"mode": "PX"}]}, "[instrument] mode = 'PX'"),
        ({"channel": {"outage_duration_s": -1.0}}, "outage_duration_s = -1.0"),
    ],
)
def test_bad_values_are_rejected_by_name(table: dict, message: str) -> None:
    with pytest.raises(ScenarioError) as err:
        scenario_from_dict(table)
    assert message in str(err.value)


def test_file_errors(tmp_path: Path) -> None:
    with pytest.raises(ScenarioError, match="not found"):
        load_scenario(tmp_path / "missing.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text("[orbit\n")
    with pytest.raises(ScenarioError, match="not valid TOML"):
        load_scenario(bad)


def test_relative_paths_resolve_from_the_scenario(tmp_path: Path) -> None:
    scn = scenario_from_dict({"orbit": {"kind": "tle", "tle_path": "a.tle"}}, tmp_path)
    assert scn.path(scn.orbit.tle_path) == tmp_path / "a.tle"


def test_every_key_is_described() -> None:
    text = describe_keys()
    for key in ("altitude_km", "roll_offset_urad", "mirror_step", "period_s", "relief_m"):
        assert f"  {key} = " in text


@pytest.mark.parametrize("path", sorted((ROOT / "scenarios").glob("*.toml")), ids=str)
def test_shipped_scenarios_load(path: Path) -> None:
    assert isinstance(load_scenario(path), Scenario)


def test_one_loader_reads_each_file_once_and_says_what_it_is(monkeypatch) -> None:
    """``station.loader.load_any``: a pass, a block and a SAR frame from one read of their
    file each; the typed loaders refuse the other kinds naming what the file is."""
    import station.loader as loader
    from station.loader import BlockScenario, load_any, load_block, load_sar
    from station.sar_scenario import SarScenario

    reads: list[Path] = []
    real = loader.read_toml

    def counted(path, what="scenario"):
        reads.append(Path(path))
        return real(path, what)

    monkeypatch.setattr(loader, "read_toml", counted)
    files = {
        Scenario: ROOT / "scenarios" / "small_test.toml",
        BlockScenario: ROOT / "scenarios" / "blocks" / "two_passes.toml",
        SarScenario: ROOT / "scenarios" / "sar" / "ers_gec.toml",
    }
    for want, path in files.items():
        reads.clear()
        got = load_any(path)
        assert isinstance(got, want) and reads == [path]
        assert got.source == str(path.resolve()) and len(got.source_sha256) == 64
    blk = load_block(files[BlockScenario])
    assert len(blk.passes) >= 2 and all(isinstance(s, Scenario) for s in blk.passes)
    assert len({s.source_sha256 for s in blk.passes}) == len(blk.passes)  # each its own
    with pytest.raises(
        ScenarioError, match=r"a block of several passes \(\[\[passes\]\]\), not one"
    ):
        load_scenario(files[BlockScenario])
    with pytest.raises(ScenarioError, match=r"describes one pass, not a SAR frame"):
        load_sar(files[Scenario])
    with pytest.raises(ScenarioError, match=r"a SAR frame \(\[sar\]\), not a block"):
        load_block(files[SarScenario])


@pytest.mark.parametrize("day", ["1949-12-31", "1066-10-14", "2200-01-01", "2600-01-01"])
def test_a_day_the_clocks_cannot_take_is_refused_before_work(day: str) -> None:
    """Before 1950 the time codes are negative (the receiver crashed on them, exit 3);
    from 2200 the nanosecond clocks near their end: refused with the days allowed."""
    with pytest.raises(ScenarioError, match=r"give a day from 1950-01-01 .* to 2199-12-31"):
        scenario_from_dict({"name": "d", "pass": {"date_utc": day}})


def test_a_day_outside_spot_service_is_one_warning(monkeypatch) -> None:
    """1970 and 2150: emulated, with one warning naming the missions' dates; 1998: none."""
    import station.preflight as preflight

    said: list[str] = []
    monkeypatch.setattr(preflight._log, "warning", lambda msg, *a: said.append(msg % a))
    for day, warned in (("1970-06-01", True), ("2150-01-01", True), ("1998-02-20", False)):
        said.clear()
        preflight.check_scenario(scenario_from_dict({"name": "d", "pass": {"date_utc": day}}))
        assert len(said) == warned, said
        if warned:
            assert "no SPOT 1–4 flew then" in said[0] and "1986-02-22" in said[0]
