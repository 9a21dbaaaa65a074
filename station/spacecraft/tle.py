"""Two-line element sets: read, checked, and turned into a state to integrate.

The TLE's Brouwer mean motion is turned into a semi-major axis (Hoots & Roehrich,
    Spacetrack Report No. 3, "un-Kozai"), its elements into a state in TEME, and TEME into
    ECI by a rotation about z of ERA − GMST (both frames share the pole to within
    nutation, < 20 m at this altitude). The mean elements are used as osculating ones: the
    truth then differs from SGP4's by a few kilometres, which does not matter — the truth is
    what we integrate, the TLE only places it.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from levels.geometry.frames import rot_z
from levels.geometry.times import Epoch
from station.errors import OrbitError
from station.spacecraft.orbit import GM_M3_PER_S2, J2, RE_M, state_from_elements

__all__ = ["Tle", "read_tle", "tle_state_eci"]


@dataclass(frozen=True)
class Tle:
    """One two-line element set (TEME, Brouwer mean motion)."""

    name: str
    epoch_utc: np.datetime64
    i_rad: float
    raan_rad: float
    e: float
    argp_rad: float
    mean_anomaly_rad: float
    mean_motion_rad_per_s: float

    def semi_major_axis_m(self) -> float:
        """Un-Kozai'd semi-major axis (Spacetrack Report No. 3, SGP4 initialisation)."""
        ke = np.sqrt(GM_M3_PER_S2 / RE_M**3)  # per second, in Earth radii
        n0 = self.mean_motion_rad_per_s
        a1 = (ke / n0) ** (2 / 3)
        c = 0.75 * J2 * (3 * np.cos(self.i_rad) ** 2 - 1) / (1 - self.e**2) ** 1.5
        d1 = c / a1**2
        a0 = a1 * (1 - d1 / 3 - d1**2 - 134 / 81 * d1**3)
        d0 = c / a0**2
        return float(a0 / (1 - d0) * RE_M)


def _tle_checksum_ok(line: str) -> bool:
    total = sum(int(c) if c.isdigit() else (1 if c == "-" else 0) for c in line[:68])
    return len(line) >= 69 and line[68].isdigit() and total % 10 == int(line[68])


def read_tle(path: str | Path) -> list[Tle]:
    """Every element set of a TLE file (2- or 3-line records); checksums are verified."""
    p = Path(path)
    try:
        lines = [ln.rstrip() for ln in p.read_text().splitlines() if ln.strip()]
    except FileNotFoundError:
        raise OrbitError(f"TLE file {p} not found") from None
    except (UnicodeDecodeError, IsADirectoryError):
        raise OrbitError(f"{p}: not a TLE file (text of 2- or 3-line records)") from None
    out = []
    name = ""
    k = 0
    while k < len(lines):
        ln = lines[k]
        if ln.startswith("1 ") and k + 1 < len(lines) and lines[k + 1].startswith("2 "):
            l1, l2 = ln, lines[k + 1]
            for number, text in ((1, l1), (2, l2)):
                if not _tle_checksum_ok(text):
                    raise OrbitError(f"{p}: line {number} of TLE {name!r} fails its checksum")
            try:
                yy = int(l1[18:20])
                year = 1900 + yy if yy >= 57 else 2000 + yy
                doy = float(l1[20:32])
                epoch = np.datetime64(f"{year}-01-01", "ns") + np.timedelta64(
                    round((doy - 1) * 86400e9), "ns"
                )
                out.append(
                    Tle(
                        name=name or l1[2:7].strip(),
                        epoch_utc=epoch,
                        i_rad=np.radians(float(l2[8:16])),
                        raan_rad=np.radians(float(l2[17:25])),
                        e=float("0." + l2[26:33].strip()),
                        argp_rad=np.radians(float(l2[34:42])),
                        mean_anomaly_rad=np.radians(float(l2[43:51])),
                        mean_motion_rad_per_s=float(l2[52:63]) * 2 * np.pi / 86400.0,
                    )
                )
            except ValueError as exc:
                raise OrbitError(f"{p}: TLE {name!r} has a malformed field ({exc})") from None
            name = ""
            k += 2
        else:
            name = ln[2:].strip() if ln.startswith("0 ") else ln.strip()
            k += 1
    if not out:
        raise OrbitError(f"{p}: no two-line element set found")
    return out


def tle_state_eci(tle: Tle, epoch: Epoch) -> tuple[float, NDArray, NDArray]:
    """Time (s since ``epoch``), position and velocity in ECI of a TLE's elements."""
    r_teme, v_teme = state_from_elements(
        tle.semi_major_axis_m(),
        tle.e,
        tle.i_rad,
        tle.raan_rad,
        tle.argp_rad,
        tle.mean_anomaly_rad,
    )
    t = float(epoch.seconds(tle.epoch_utc))
    turn = rot_z(epoch.era_rad(t) - epoch.gmst_rad(t))  # TEME → ECI (module docstring)
    return t, turn @ r_teme, turn @ v_teme
