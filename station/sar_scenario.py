"""A SAR frame's scenario (``[sar]``, ``[world]``, ``[dem]``): one ERS-1 frame and what the
processing centre makes of it (:mod:`station.run_sar` runs it; :mod:`station.loader` reads
it from its file)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from levels.kinds import Unit
from levels.options import build_section, option
from levels.registry import kind, kind_names
from station.errors import ScenarioError
from station.scenario import DemConfig, WorldConfig, check_name

__all__ = ["SarConfig", "SarScenario", "sar_scenario_from_dict"]


@dataclass(frozen=True)
class SarConfig:
    """``[sar]``: one ERS-1 frame and what the processing centre makes of it."""

    date_utc: str = option("1995-08-15", "date_utc", "day of the frame (UTC)")
    target_lat_deg: float = option(
        -15.6, "target_lat_deg", "latitude of the frame's centre", 1.0, -80.0, 80.0
    )
    target_lon_deg: float = option(
        -56.1, "target_lon_deg", "longitude of the frame's centre", 1.0, -180.0, 180.0
    )
    lines: int = option(400, "lines", "lines of the detected image", lo=16, hi=40000)
    samples: int = option(
        400, "samples", "slant-range samples of the detected image", lo=16, hi=40000
    )
    azimuth_looks: int = option(
        5, "azimuth_looks", "pulses a line (line interval = looks / PRF)", lo=1, hi=100
    )
    range_looks: int = option(
        2, "range_looks", "range samples a sample (spacing = looks × 7.9 m)", lo=1, hi=100
    )
    speckle_looks: float = option(
        3.0, "speckle_looks", "looks of the speckle (0: none)", 1.0, 0.0, 1000.0
    )
    state_error_m: float = option(
        0.0, "state_error_m", "1σ error of the annotation's state vectors, per axis", 1.0, 0.0, 1e4
    )
    state_bias_m: tuple[float, float, float] = option(
        [0.0, 0.0, 0.0],
        "state_bias_m",
        "the post-facto orbit's offset along, across (left) and radial at the frame's centre",
    )
    state_drift_m_per_s: tuple[float, float, float] = option(
        [0.0, 0.0, 0.0], "state_drift_m_per_s", "its drift, the same axes"
    )
    levels: tuple[str, ...] = option(
        ("GEC",), "levels", "products to make", choices=lambda: kind_names(Unit.FRAME)
    )
    pixel_size_m: float = option(25.0, "pixel_size_m", "output pixel (UTM)", 1.0, 1.0, 1000.0)
    reference_height_m: float = option(
        float("nan"),
        "reference_height_m",
        "GEC's height above the ellipsoid (default: the world's base height)",
    )
    backscatter: str = option(
        "cos2",
        "backscatter",
        "the terrain's law on the local incidence: σ⁰ = ρ·cos²θ, or ρ·cos θ (γ⁰ = ρ)",
        choices=("cos2", "gamma"),
    )
    flatten: bool = option(False, "flatten", "GTC: γ⁰ by terrain flattening too (gamma0)")


@dataclass(frozen=True)
class SarScenario:
    """A SAR frame's scenario: a name, a seed, the frame, the world and the DEM."""

    name: str = "ers"
    seed: int = 38
    sar: SarConfig = field(default_factory=SarConfig)
    world: WorldConfig = field(default_factory=WorldConfig)
    dem: DemConfig | None = None
    base_dir: str = "."
    source: str = ""
    source_sha256: str = ""

    def __post_init__(self) -> None:
        check_name(self.name)
        over = [lv for lv in self.sar.levels if "dem" in kind(lv).needs]
        if over and self.dem is None:
            raise ScenarioError(
                f"[sar] levels has {over[0]!r}: it needs the DEM the station is handed, a "
                "[dem] table"
            )

    def path(self, relative: str) -> Path:
        p = Path(relative)
        return p if p.is_absolute() else Path(self.base_dir) / p

    def inputs(self) -> list[Path]:
        """The files the scenario reads: itself and its world's DEM."""
        given = [self.world.dem_path] if self.world.kind == "dem" else []
        return [Path(self.source)] * bool(self.source) + [self.path(p) for p in given]

    @property
    def reference_height_m(self) -> float:
        h = self.sar.reference_height_m
        return self.world.base_height_m if np.isnan(h) else h


SECTIONS = {"sar": SarConfig, "world": WorldConfig, "dem": DemConfig}


def sar_scenario_from_dict(data: dict[str, object], p: Path) -> SarScenario:
    """A SAR scenario from its file's table (``p`` the file: its directory the base of
    its paths, its stem the default name); :class:`ScenarioError` says what is wrong.
    :func:`station.loader.load_any` reads the file."""
    kwargs: dict[str, Any] = {"base_dir": str(p.resolve().parent)}
    for key, value in data.items():
        if key in ("name", "seed"):
            want = str if key == "name" else int
            if not isinstance(value, want) or isinstance(value, bool):
                raise ScenarioError(
                    f"{key} = {value!r}: expected {'a string' if want is str else 'an integer'}"
                )
            kwargs[key] = value
        elif key in SECTIONS:
            kwargs[key] = build_section(SECTIONS[key], key, value, ScenarioError)
        else:
            allowed = ", ".join(["name", "seed", *SECTIONS])
            raise ScenarioError(f"{p}: unknown key {key!r} in a SAR scenario; allowed: {allowed}")
    kwargs.setdefault("name", p.stem)
    return SarScenario(**kwargs)
