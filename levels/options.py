"""Declared options: TOML tables turned at once into frozen dataclasses, and the processing
options of the processing centre.

Every field of an options dataclass is declared once with :func:`option`: its TOML name
(unit-suffixed: ``reference_height_m``, ``altitude_km``), the factor to SI, its allowed range
and a one-line meaning. :func:`build_section` checks a parsed TOML table against those
declarations and converts it; :func:`describe_section` lists them. The messages and the
listing are generated from the declarations, so they cannot drift apart. The station's
scenario and capacity files are declared the same way (they import these helpers).

:class:`ProcessingOptions` is what the processing centre is asked to do with a pass: the
``[processing]`` table of a scenario, or of a file of its own for
``station process L0.h5 --options FILE``.
"""

from __future__ import annotations

import math
import typing
from collections.abc import Callable
from dataclasses import MISSING, dataclass, field, fields
from enum import StrEnum
from typing import Any

from levels.choices import (
    AdjustmentScope,
    DemVertical,
    GridColumns,
    GridRows,
    Interpolation1B,
    InverseMethod,
    Level,
    Resampling,
    RobustLoss,
)
from levels.errors import OptionsError
from levels.hdf5 import DEFLATE_LEVEL
from levels.registry import level_names

__all__ = [
    "LEVELS",
    "MIN_PIXEL_SIZE_M",
    "ProcessingOptions",
    "build_section",
    "describe_section",
    "describe_value",
    "option",
]

#: The built-in levels, in processing order (:class:`levels.choices.Level`; more can be
#: registered, :mod:`levels.registry`).
LEVELS = tuple(str(lv) for lv in Level)

_URAD = 1e-6
#: The finest output pixel a scene may be asked for (m): a twentieth of SPOT's 10 m; below,
#: a map grid of a scene would not fit any machine (1 mm on a 60 km scene: 3.6e15 pixels).
MIN_PIXEL_SIZE_M = 0.5


def option(
    default: Any,
    key: str,
    doc: str,
    scale: float = 1.0,
    lo: float | None = None,
    hi: float | None = None,
    choices: tuple[str, ...] | Callable[[], tuple[str, ...]] | None = None,
) -> Any:
    """Declare a field: TOML ``key`` (unit-suffixed), factor to SI, range, meaning.

    ``default`` is given in TOML units (degrees, km, µrad) and converted like a read value.
    ``choices``: the allowed strings, or a function giving them when a value is checked
    (the registered levels); a field typed as a :class:`~enum.StrEnum` takes its members.
    """
    meta = {"key": key, "doc": doc, "scale": scale, "lo": lo, "hi": hi, "choices": choices}
    if isinstance(default, list | tuple) and all(isinstance(v, str) for v in default):
        return field(default=tuple(default), metadata=meta)
    if isinstance(default, list | tuple):
        si = tuple(float(v) * scale for v in default)
        return field(default=si, metadata=meta)
    if isinstance(default, float):
        default = default * scale
    return field(default=default, metadata=meta)


def choices_of(meta: Any, typ: Any = None) -> tuple[str, ...]:
    """The strings a declared field accepts: its enum's members, or its ``choices``."""
    if isinstance(typ, type) and issubclass(typ, StrEnum):
        return tuple(str(m) for m in typ)
    given = meta["choices"]
    return tuple(given()) if callable(given) else tuple(given or ())


def describe_value(meta: Any, typ: Any) -> str:
    """What a declared field accepts, in words ("a number in [0, 5]", "one of 'P', 'XS'")."""
    choices = choices_of(meta, typ)
    if choices and typing.get_args(typ) == (str, Ellipsis):
        return "a list, without repeats, of " + ", ".join(repr(c) for c in choices)
    if choices:
        return "one of " + ", ".join(repr(c) for c in choices)
    kind = {int: "an integer", float: "a number", str: "a string", bool: "true or false"}.get(
        typ, ""
    )
    if typing.get_args(typ) == (float, Ellipsis):
        kind = "a list of numbers"
    elif typing.get_origin(typ) is tuple:
        kind = f"a list of {len(typing.get_args(typ))} numbers"
    lo, hi = meta["lo"], meta["hi"]
    if lo is not None and hi is not None:
        return f"{kind} in [{lo:g}, {hi:g}]"
    return kind


def _convert(section: str, f: Any, typ: Any, value: Any, error: type[Exception]) -> Any:
    meta = f.metadata
    name = f"[{section}] {meta['key']}" if section else meta["key"]
    allowed = describe_value(meta, typ)

    def bad() -> Exception:
        return error(f"{name} = {value!r}: expected {allowed}")

    def number(v: Any) -> float:
        if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
            raise bad()
        lo, hi = meta["lo"], meta["hi"]
        if (lo is not None and v < lo) or (hi is not None and v > hi):
            raise bad()
        return float(v) * meta["scale"]

    if typ is bool:
        if not isinstance(value, bool):
            raise bad()
        return value
    if isinstance(typ, type) and issubclass(typ, StrEnum):
        if not isinstance(value, str) or value not in choices_of(meta, typ):
            raise bad()
        return typ(value)
    if typ is str:
        if not isinstance(value, str):
            raise bad()
        if meta["choices"] and value not in choices_of(meta):
            raise bad()
        return value
    if typ is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise bad()
        number(value)
        return value
    if typ is float:
        return number(value)
    if typing.get_args(typ) == (str, Ellipsis):
        if (
            not isinstance(value, list)
            or not value
            or len(set(value)) != len(value)
            or any(v not in choices_of(meta) for v in value)
        ):
            raise bad()
        return tuple(value)
    if typing.get_origin(typ) is tuple:  # of numbers: fixed length, or any (float, ...)
        args = typing.get_args(typ)
        fixed = args[-1] is not Ellipsis
        if not isinstance(value, list) or not value or (fixed and len(value) != len(args)):
            raise bad()
        return tuple(number(v) for v in value)
    raise TypeError(f"unsupported field type {typ!r}")  # a declaration bug, not user input


def build_section(
    cls: type, section: str, table: Any, error: type[Exception] = OptionsError
) -> Any:
    """An instance of the declared dataclass ``cls`` from the TOML table of ``[section]``.

    An unknown key, a wrong type, a value out of range or a failed cross-field check of
    ``__post_init__`` raises ``error`` naming the key, the value and what is allowed.
    """
    if not isinstance(table, dict):
        raise error(f"[{section}] must be a table, got {table!r}")
    hints = typing.get_type_hints(cls)
    by_key = {f.metadata["key"]: f for f in fields(cls) if "key" in f.metadata}
    unknown = sorted(set(table) - set(by_key))
    if unknown:
        raise error(f"[{section}] unknown key {unknown[0]!r}; allowed: {', '.join(sorted(by_key))}")
    kwargs = {
        f.name: _convert(section, f, hints[f.name], table[key], error)
        for key, f in by_key.items()
        if key in table
    }
    try:
        return cls(**kwargs)
    except error:
        raise
    except (TypeError, ValueError) as exc:  # cross-field checks of __post_init__
        raise error(f"[{section}] {exc}") from None


def describe_section(section: str, cls: type) -> list[str]:
    """Lines listing every key of ``[section]``: default (TOML units), range and meaning."""
    lines = [f"[{section}]"]
    hints = typing.get_type_hints(cls)
    for f in fields(cls):
        meta = f.metadata
        if "key" not in meta:
            continue
        default = f.default if f.default is not MISSING else None
        if isinstance(default, StrEnum):
            default = str(default)
        elif isinstance(default, float):
            default = default / meta["scale"]
        elif isinstance(default, tuple):
            default = [v if isinstance(v, str) else round(v / meta["scale"], 12) for v in default]
        lines.append(
            f"  {meta['key']} = {default!r}  # {meta['doc']}; {describe_value(meta, hints[f.name])}"
        )
    return lines


@dataclass(frozen=True)
class ProcessingOptions:
    """The processing centre: which levels, how scenes are cut, GEO's and COR's options.

    The reference height is the scene's mean altitude the producer would take from a global
    DEM: levels 1B and 2A are located on the ellipsoid raised by it. The PSF is the
    instrument's nominal one, which the deconvolution of 1B and 2A inverts.
    """

    levels: tuple[str, ...] = option(
        ["1A", "1B", "2A"],
        "levels",
        "levels to produce (2: with control points; 3: over a DEM, on level 2's model when 2 "
        "is made too)",
        choices=level_names,
    )
    scene_lines: int = option(
        0, "scene_lines", "lines per scene (0: as many as detectors)", lo=0, hi=10**6
    )
    overlap_lines: int = option(
        0, "overlap_lines", "lines shared by consecutive scenes", lo=0, hi=10**6
    )
    min_valid_share: float = option(
        0.5,
        "min_valid_share",
        "a scene is made when at least this share of its lines (of a whole scene's, for the "
        "pass's last, partial scene) arrived; else skipped, with the reason in the report",
        1.0,
        0.0,
        1.0,
    )
    reference_height_m: float = option(
        450.0, "reference_height_m", "mean scene altitude of levels 1B and 2A", 1.0, -500.0, 9000.0
    )
    pixel_size_m: float = option(
        0.0,
        "pixel_size_m",
        "output pixel (0: 10 m P, 20 m XS, times the detector scale; else at least "
        f"{MIN_PIXEL_SIZE_M} m)",
        1.0,
        0.0,
        10000.0,
    )
    interpolation_1b: Interpolation1B = option(
        Interpolation1B.CUBIC, "interpolation_1b", "1B column interpolation"
    )
    lines_1b: Interpolation1B = option(
        Interpolation1B.CUBIC,
        "lines_1b",
        "1B line interpolation: cubic (the rows on the continuous line its RPCs describe), "
        "or nearest (INPE's: each row a whole raw line, up to half a line off its RPCs)",
    )
    resampling_2a: Resampling = option(Resampling.CUBIC, "resampling_2a", "2A resampling")
    inverse_2a: InverseMethod = option(InverseMethod.NEAREST4, "inverse_2a", "2A inverse mapping")
    grid_rows: GridRows = option(
        GridRows.ATTITUDE,
        "grid_rows",
        "2A direct-grid rows: at the attitude samples or INPE's regular 61",
    )
    grid_columns: GridColumns = option(
        GridColumns.BUTTING,
        "grid_columns",
        "2A direct-grid columns: INPE's 61 plus both sides of each CCD butting, or INPE's "
        "regular 61 only (with grid_rows = 'regular': INPE's exact 61 × 61)",
    )
    crs: str = option("utm", "crs", "2A map: 'utm' (zone of the centre), 'som', or EPSG/WKT")
    deconvolution: bool = option(True, "deconvolution", "deconvolve 1B and 2A")
    deflate_level: int = option(
        DEFLATE_LEVEL,
        "deflate_level",
        "deflate level of the products' image bands (0: stored, 1.7–2.1× larger for a full "
        "P scene; 1–3: ISA-L's levels, 2 the smallest of the fastest; 4–9: zlib's, slower "
        "and hardly smaller)",
        lo=0,
        hi=9,
    )
    psf_fwhm_px: float = option(
        1.2, "psf_fwhm_px", "nominal PSF of the instrument (FWHM)", 1.0, 0.0, 5.0
    )
    noise_to_signal: float = option(
        0.05,
        "noise_to_signal",
        "Wiener noise-to-signal ratio of the deconvolution",
        1.0,
        1e-4,
        10.0,
    )
    adjustment: AdjustmentScope = option(
        AdjustmentScope.PASS,
        "adjustment",
        "level 2: one adjustment over the whole pass (Westin), each scene alone, both "
        "HRVs of a twin pass together (one platform: points in one HRV refine the other), "
        "or every pass given together, tied by their tie points (docs/blocks.md)",
    )
    tie_height_sigma_m: float = option(
        10.0,
        "tie_height_sigma_m",
        "level 2 of a block: 1σ of the DEM's height under each tie point (with dem_path)",
        1.0,
        0.1,
        1000.0,
    )
    stereo: bool = option(
        False,
        "stereo",
        "a block of two passes: their DEM by dense matching on epipolar images after level 2 "
        "(docs/stereo.md), and level 3 over it instead of a DEM from outside",
    )
    prior_ephemeris_m: tuple[float, float, float] = option(
        [300.0, 150.0, 50.0],
        "prior_ephemeris_m",
        "level 2 a priori 1σ of the ephemeris bias along, across track, radial",
        1.0,
        0.1,
        1e5,
    )
    prior_ephemeris_drift_m_per_s: tuple[float, float, float] = option(
        [0.1, 0.05, 0.02],
        "prior_ephemeris_drift_m_per_s",
        "level 2 a priori 1σ of the growth of that bias",
        1.0,
        1e-4,
        100.0,
    )
    prior_attitude_rad: tuple[float, float, float] = option(
        [500.0, 500.0, 500.0],
        "prior_attitude_urad",
        "level 2 a priori 1σ of the attitude offsets in roll, pitch, yaw",
        _URAD,
        0.1,
        5e4,
    )
    prior_attitude_rate_rad_per_s: float = option(
        0.1,
        "prior_attitude_rate_urad_per_s",
        "level 2 a priori 1σ of a scene's attitude rate error (gyro noise over a scene)",
        _URAD,
        1e-3,
        1e3,
    )
    gyro_noise_rad_per_s: float = option(
        0.5,
        "gyro_noise_urad_per_s",
        "level 2: the gyros' 1σ noise per record, the attitude's random walk between scenes",
        _URAD,
        1e-3,
        1e3,
    )
    variogram_scale: float = option(
        1.0,
        "variogram_scale",
        "level 2: factor on Westin's variograms weighting attitude jumps over gaps",
        1.0,
        1e-3,
        100.0,
    )
    attitude_jitter_rad: tuple[float, float, float] = option(
        [0.21, 0.21, 0.07],
        "attitude_jitter_urad",
        "level 2: the platform's jitter (RMS in roll, pitch, yaw), above the gyros' band: "
        "every control point and every line have their own (SPOT's emulated 0.3, 0.3, 0.1 "
        "µrad amplitudes)",
        _URAD,
        0.0,
        100.0,
    )
    robust_loss: RobustLoss = option(
        RobustLoss.SOFT_L1,
        "robust_loss",
        "level 2: loss of the first fit, before blunders are rejected",
    )
    blunder_threshold: float = option(
        4.0,
        "blunder_threshold",
        "level 2: normalised residual beyond which a control point is a blunder",
        1.0,
        2.0,
        100.0,
    )
    fit_confidence: float = option(
        0.999,
        "fit_confidence",
        "level 2: confidence of the χ² test of the fit (σ0 against its a priori 1): a fit "
        "beyond it is refused, not made into products",
        1.0,
        0.5,
        0.999999,
    )
    dem_path: str = option(
        "",
        "dem_path",
        "level 3: the DEM (any GDAL raster: GeoTIFF, SRTM .hgt, DTED), relative to the "
        "scenario or options file; empty: the scenario's [dem] export, or <name>.dem.tif "
        "beside the L0 archive",
    )
    dem_vertical: DemVertical = option(
        DemVertical.ELLIPSOID,
        "dem_vertical",
        "level 3: the DEM's heights are above the WGS84 ellipsoid, or the EGM96 geoid "
        "(SRTM, DTED: needs PROJ's us_nga_egm96_15.tif grid)",
    )
    checkpoints_per_side: int = option(
        11, "checkpoints_per_side", "checkpoint lattice of the quality figures", lo=2, hi=101
    )

    def __post_init__(self) -> None:
        if 0 < self.pixel_size_m < MIN_PIXEL_SIZE_M:
            raise OptionsError(
                f"pixel_size_m = {self.pixel_size_m:g}: expected 0 (the nominal pixel) or at "
                f"least {MIN_PIXEL_SIZE_M} m (SPOT's finest is 10 m)"
            )
        if self.overlap_lines and self.scene_lines and self.overlap_lines >= self.scene_lines:
            raise OptionsError(
                f"overlap_lines = {self.overlap_lines} must be less than "
                f"scene_lines = {self.scene_lines}"
            )
        if self.crs not in ("utm", "som"):
            import pyproj

            try:
                pyproj.CRS.from_user_input(self.crs)
            except pyproj.exceptions.CRSError as exc:
                raise OptionsError(
                    f"crs = {self.crs!r}: not a CRS PROJ knows ({exc}); use 'utm', 'som', an "
                    "EPSG code ('EPSG:32721') or a WKT"
                ) from None
        known = level_names()
        bad = [lv for lv in self.levels if lv not in known]
        if bad:
            raise OptionsError(
                f"levels = {list(self.levels)}: {bad[0]!r} is not a level "
                f"this processing centre makes; expected some of {list(known)}"
            )
        # enum fields given as plain strings (in code, not TOML) become their members
        for f in fields(self):
            typ = _ENUM_FIELDS.get(f.name)
            value = getattr(self, f.name)
            if typ is not None and not isinstance(value, typ):
                try:
                    object.__setattr__(self, f.name, typ(value))
                except ValueError:
                    raise OptionsError(
                        f"{f.metadata['key']} = {value!r}: expected one of "
                        f"{', '.join(repr(str(m)) for m in typ)}"
                    ) from None

    @classmethod
    def from_table(
        cls, table: Any, section: str = "processing", error: type[Exception] = OptionsError
    ) -> ProcessingOptions:
        """Options from a parsed ``[processing]`` TOML table (module docstring)."""
        return build_section(cls, section, table, error)


#: The enum-typed fields of :class:`ProcessingOptions` and their enums.
_ENUM_FIELDS: dict[str, type[StrEnum]] = {
    name: typ
    for name, typ in typing.get_type_hints(ProcessingOptions).items()
    if isinstance(typ, type) and issubclass(typ, StrEnum)
}
