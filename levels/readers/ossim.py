"""Reader of OSSIM's SPOT 5 keyword lists (``ossimSpot5Model`` ``.geom`` files), the form in
which OTB and OSSIM hand a SPOT 5 scene's geometry around (``../shared/refdata/dimap/``).

The keyword list is OSSIM's digest of the scene's DIMAP: ``support_data.*`` holds the
ephemeris (ECEF positions and velocities), the attitude samples, the look angles of every
detector (``pixel_lookat_angle_x``, ``_y``: ψx, ψy in radians), the line period and the time
of a reference line; times count seconds on OSSIM's own scale, and ``image_date`` is the UTC
instant of the reference line, which dates them. :func:`read_ossim_geom` turns it into the
project's :class:`~levels.geometry.model.PushbroomModel`, so that a scene OSSIM knows can be
located, checked against OSSIM's own localisation, and given RPCs.

The attitude samples are OSSIM's "corrected attitude" triples; their order in the triple
(``ATTITUDE_ORDER``: pitch, roll, yaw) was established against the 36 points OSSIM itself
located in the same scene (``otb_spot5_hrg2_20030723_teheran_ossim.gcp``): of the 48 orders
and signs, this one alone puts them where OSSIM does, within 0.3 mm, once OSSIM's image
coordinates are ours: OSSIM's (line, sample) is our (line + 0.5, column + 1), the model
here keeping the keyword list's reference line and detector index as given (as
:mod:`levels.readers.dimap` keeps DIMAP's).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from levels.errors import DimapError, GeometryError
from levels.geometry.attitude import SampledAttitude
from levels.geometry.ephemeris import Ephemeris
from levels.geometry.model import LineClock, PushbroomModel
from levels.geometry.sensor import LookAngleTable
from levels.geometry.times import Epoch, parse_utc
from levels.readers.bounded import MAX_METADATA_BYTES, read_capped

__all__ = ["ATTITUDE_ORDER", "OssimScene", "read_ossim_gcps", "read_ossim_geom"]

#: Where roll, pitch and yaw sit in each ``attitude_samples`` triple (module docstring).
ATTITUDE_ORDER = (1, 0, 2)
_LINE = re.compile(r"^\s*([A-Za-z0-9_.]+):\s*(.*?)\s*$")


@dataclass(frozen=True, eq=False)
class OssimScene:
    """A SPOT 5 scene as OSSIM's keyword list describes it."""

    path: Path
    sensor: str
    n_lines: int
    n_samples: int
    model: PushbroomModel


def _keywords(path: Path) -> dict[str, str]:
    try:
        text = read_capped(path, MAX_METADATA_BYTES, "OSSIM keyword list", DimapError).decode()
    except UnicodeDecodeError:
        raise DimapError(f"{path}: not a text keyword list") from None
    out = {}
    for line in text.splitlines():
        m = _LINE.match(line)
        if m:
            out[m.group(1)] = m.group(2).strip('"').strip()
    return out


def _numbers(kw: dict[str, str], key: str, path: Path) -> NDArray[np.float64]:
    if key not in kw:
        raise DimapError(f"{path}: missing keyword {key}")
    try:
        return np.array([float(x) for x in kw[key].split()], dtype=np.float64)
    except ValueError:
        raise DimapError(f"{path}: keyword {key} is not a list of numbers") from None


def read_ossim_geom(path: str | Path) -> OssimScene:
    """Read an ``ossimSpot5Model`` keyword list into a rigorous model (module docstring).

    Raises
    ------
    DimapError
        If the file is not such a keyword list or lacks a keyword the model needs.
    """
    source = Path(path)
    if not source.is_file():
        raise DimapError(f"{source}: not found")
    kw = _keywords(source)
    if kw.get("type") != "ossimSpot5Model":
        raise DimapError(
            f"{source}: not an OSSIM SPOT 5 keyword list (type {kw.get('type')!r}, "
            "expected ossimSpot5Model)"
        )
    n_lines, n_samples = (int(v) for v in _numbers(kw, "support_data.image_size", source))
    t_ref = float(_numbers(kw, "support_data.reference_line_time", source)[0])
    line_ref = float(_numbers(kw, "support_data.reference_line_time_line", source)[0])
    period = float(_numbers(kw, "support_data.line_sampling_period", source)[0])
    try:
        epoch = Epoch(parse_utc(kw["support_data.image_date"]), name="reference line")
        t_eph = _numbers(kw, "support_data.ephemeris_sample_times", source) - t_ref
        pos = _numbers(kw, "support_data.position_ecf_samples", source).reshape(-1, 3)
        vel = _numbers(kw, "support_data.velocity_ecf_samples", source).reshape(-1, 3)
        ephemeris = Ephemeris(t_eph, pos, vel)
        t_att = _numbers(kw, "support_data.attitude_sample_times", source) - t_ref
        triples = _numbers(kw, "support_data.attitude_samples", source).reshape(-1, 3)
        attitude = SampledAttitude(t_att, triples[:, list(ATTITUDE_ORDER)])
        psi_x = _numbers(kw, "support_data.pixel_lookat_angle_x", source)
        psi_y = _numbers(kw, "support_data.pixel_lookat_angle_y", source)
        look = LookAngleTable(np.arange(float(psi_x.size)), psi_x, psi_y, n_samples)
        model = PushbroomModel(
            epoch=epoch,
            clock=LineClock(0.0, line_ref, period),
            ephemeris=ephemeris,
            attitude=attitude,
            look_angles=look,
            n_lines=n_lines,
        )
    except KeyError as exc:
        raise DimapError(f"{source}: missing keyword {exc.args[0]}") from None
    except (GeometryError, ValueError) as exc:
        raise DimapError(f"{source}: {exc}") from None
    return OssimScene(source, kw.get("sensor", ""), n_lines, n_samples, model)


def read_ossim_gcps(path: str | Path) -> dict[str, NDArray[np.float64]]:
    """OTB's ``.gcp`` companion of a keyword list: per row ``sample line lon lat height``
    (then lon, lat again), the points OSSIM located in the scene: sample, line, lat, lon
    (degrees) and height (m)."""
    source = Path(path)
    try:
        rows = np.loadtxt(source, ndmin=2)
    except (OSError, ValueError) as exc:
        raise DimapError(f"{source}: not an OSSIM point list ({exc})") from None
    if rows.shape[1] < 5:
        raise DimapError(f"{source}: {rows.shape[1]} columns, expected sample line lon lat h")
    return {
        "sample": rows[:, 0],
        "line": rows[:, 1],
        "lon_deg": rows[:, 2],
        "lat_deg": rows[:, 3],
        "height_m": rows[:, 4],
    }
