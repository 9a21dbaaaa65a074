"""The reduced day of the day's tests (``tests/test_day.py``, and on a cluster
``tests/test_distributed.py``): the shipped day's station and load, its window cut to the
first passes, tiny scenes, a fast clock, a short calibration."""

from __future__ import annotations

from pathlib import Path

DAY = Path(__file__).resolve().parents[1] / "scenarios" / "day" / "cuiaba_day.toml"
#: What the reduced day changes in the shipped day's file.
TINY = {
    "hours = 6.0": "hours = 0.9",
    "clock = 300.0": "clock = 900.0",
    "p_detectors = 1000": "p_detectors = 64",
    "scenes_per_segment = 3.0": "scenes_per_segment = 1.0",
    "delay_mean_h = 1.0": "delay_mean_h = 0.1",
    'name = "cuiaba_day"': 'name = "tiny_day"',
    "calibration_repeats = 8": "calibration_repeats = 2",
}


def tiny_day_file(tmp: Path) -> Path:
    """The reduced day's file, written into ``tmp``."""
    text = DAY.read_text()
    for a, b in TINY.items():
        assert a in text, a
        text = text.replace(a, b)
    path = tmp / "tiny_day.toml"
    path.write_text(text)
    return path
