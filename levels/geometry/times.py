"""Time: UTC instants and seconds since a named epoch.

Instants are ``numpy.datetime64[ns]`` in UTC (no leap second is ever inside a pass; a
product's epoch is within minutes of its data). Computation uses ``t_s``: float seconds since
an :class:`Epoch`, which keeps 1 ns resolution over ±100 days. UT1 is taken equal to
UTC + ``dut1_s`` (|UT1 − UTC| < 0.9 s), by default 0: the emulator and the model use the same
value, so the Earth rotation they see is identical.

References
----------
IERS Conventions (2010), eq. (5.15): ERA(Tu) = 2π (0.7790572732640 + 1.00273781191135448 Tu),
Tu = Julian UT1 date − 2451545.0.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from levels.errors import GeometryError

__all__ = ["J2000_UTC", "Epoch", "earth_rotation_angle_rad", "gmst_rad", "parse_utc"]

#: 2000-01-01T12:00:00 (JD 2451545.0), treated as UTC.
J2000_UTC = np.datetime64("2000-01-01T12:00:00", "ns")

_NS_PER_S = 1_000_000_000


def parse_utc(iso: str | Sequence[str] | NDArray) -> Any:
    """UTC instants from ISO 8601 strings (``YYYY-MM-DDTHH:MM:SS[.ffffff][Z]``).

    Returns ``datetime64[ns]`` (a 0-d array for one string). A trailing ``Z`` is accepted;
    any other zone designator is rejected, so a local time is never taken for UTC.
    """
    scalar = isinstance(iso, str)
    items = [iso] if scalar else list(iso)
    cleaned = []
    for s in items:
        text = str(s).strip()
        if text.endswith("Z"):
            text = text[:-1]
        if "+" in text[10:] or text[10:].count("-") > 0:
            raise GeometryError(
                f"time {s!r} has a zone offset; give UTC, e.g. 2005-03-13T05:21:07.33"
            )
        cleaned.append(text)
    try:
        out = np.array(cleaned, dtype="datetime64[ns]")
    except ValueError as exc:
        raise GeometryError(f"not an ISO 8601 UTC time: {items!r} ({exc})") from None
    return out[0] if scalar else out


@dataclass(frozen=True)
class Epoch:
    """A named origin of time: ``t_s`` counts SI seconds from ``t0_utc``.

    Parameters
    ----------
    t0_utc
        The origin, ``datetime64`` (any unit) or an ISO string.
    name
        What the origin is (``"scene centre"``, ``"first ephemeris point"``), for reports.
    """

    t0_utc: np.datetime64
    name: str = "epoch"

    def __post_init__(self) -> None:
        t0: Any = self.t0_utc  # a string, a datetime64 or a 0-d array of one
        t0 = parse_utc(t0) if isinstance(t0, str) else np.datetime64(t0, "ns")
        if np.isnat(t0):
            raise GeometryError("epoch t0_utc is NaT; give a UTC instant")
        object.__setattr__(self, "t0_utc", t0)

    def seconds(self, t_utc: ArrayLike) -> NDArray[np.float64]:
        """Seconds since the epoch of UTC instants (datetime64 or ISO strings)."""
        t = np.asarray(t_utc)
        if t.dtype.kind in "US":
            t = parse_utc(t.tolist()) if t.ndim else parse_utc(str(t))
        delta_ns = (np.asarray(t, dtype="datetime64[ns]") - self.t0_utc).astype(np.int64)
        return delta_ns / _NS_PER_S

    def utc(self, t_s: ArrayLike) -> NDArray[np.datetime64]:
        """UTC instants (``datetime64[ns]``) of seconds since the epoch, rounded to 1 ns."""
        ns = np.rint(np.asarray(t_s, dtype=np.float64) * _NS_PER_S).astype(np.int64)
        return self.t0_utc + ns.astype("timedelta64[ns]")

    def days_since_j2000(self, t_s: ArrayLike) -> NDArray[np.float64]:
        """Days since J2000 (UTC) of ``t_s`` seconds since the epoch."""
        days0 = (self.t0_utc - J2000_UTC).astype(np.int64) / (_NS_PER_S * 86400.0)
        return days0 + np.asarray(t_s, dtype=np.float64) / 86400.0

    def gmst_rad(self, t_s: ArrayLike, dut1_s: float = 0.0) -> NDArray[np.float64]:
        """Greenwich mean sidereal time (IAU 1982) at ``t_s`` seconds since the epoch."""
        return gmst_rad(self.days_since_j2000(np.asarray(t_s, dtype=np.float64) + dut1_s))

    def era_rad(self, t_s: ArrayLike, dut1_s: float = 0.0) -> NDArray[np.float64]:
        """Earth rotation angle at ``t_s`` seconds since the epoch (see module docstring)."""
        days0 = (self.t0_utc - J2000_UTC).astype(np.int64) / (_NS_PER_S * 86400.0)
        return earth_rotation_angle_rad(
            days0, (np.asarray(t_s, dtype=np.float64) + dut1_s) / 86400.0
        )


def earth_rotation_angle_rad(
    tu_days: ArrayLike, extra_days: ArrayLike = 0.0
) -> NDArray[np.float64]:
    """Earth rotation angle in [0, 2π) for UT1 days since J2000 (``tu_days + extra_days``).

    The argument is split in two so that a large day count and a small offset keep full
    precision: the integer day turns are removed before the fraction is scaled.

    References
    ----------
    IERS Conventions (2010), eq. (5.15).
    """
    tu = np.asarray(tu_days, dtype=np.float64)
    dt = np.asarray(extra_days, dtype=np.float64)
    whole = np.floor(tu)
    frac = (tu - whole) + dt
    # ERA = 2π (0.7790572732640 + 0.00273781191135448 Tu + frac(Tu))   IERS (5.15), rearranged
    turns = 0.7790572732640 + 0.00273781191135448 * (whole + frac) + frac
    return 2.0 * np.pi * np.mod(turns, 1.0)


def gmst_rad(tu_days: ArrayLike) -> NDArray[np.float64]:
    """Greenwich mean sidereal time (IAU 1982) in [0, 2π) for UT1 days since J2000.

    Needed where a frame is defined on the mean equinox rather than the CIO: the TEME frame
    of two-line elements (``ecef = R3(GMST) teme``), and the right ascension of the mean Sun.

    References
    ----------
    Aoki et al. (1982); Vallado, *Fundamentals of Astrodynamics*, 4th ed., eq. (3-47):
    GMST = 67310.54841 s + (876600 h + 8640184.812866 s) T + 0.093104 T² − 6.2e-6 T³.
    """
    tu = np.asarray(tu_days, dtype=np.float64)
    t = tu / 36525.0
    whole = np.floor(tu)
    seconds = (
        67310.54841
        + 86400.0 * (tu - whole)  # 876600 h · T is one turn per UT1 day: keep its fraction
        + 8640184.812866 * t
        + 0.093104 * t**2
        - 6.2e-6 * t**3
    )
    return 2.0 * np.pi * np.mod(seconds / 86400.0, 1.0)
