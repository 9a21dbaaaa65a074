"""An ERS SAR frame written in ESA's ENVISAT product format, as ``SAR_IMP_1P`` (the
inverse of :mod:`levels.readers.envisat`; GDAL's ESAT driver opens it).

What is written (PX-SP-50-9105's layouts, big-endian): the MPH and SPH (product name,
times, orbit, first and last lines' near, middle and far corners, swath, pass, looks,
spacing, line interval, line length, ``UWORD``), five data set descriptors and their
data sets:

- ``MAIN PROCESSING PARAMS ADS``: the first and last zero-Doppler times, spacings, line
  interval, size, range sampling rate (``c / (2 × the slant spacing)``), radar frequency,
  looks, the calibration constant ``EXT_CAL_FACT`` = ``S²`` and five state vectors spanning
  the frame and 10 s beyond either end (Lagrange-interpolated from the annotation's; 1 cm,
  10 µm/s);
- ``DOP CENTROID COEFFS ADS``: the centroid's polynomial in two-way slant-range time;
- ``SR GR ADS``: the emulator's image is detected on **slant** range; its "ground range"
  axis is then said as the identity, ``R = S0 + 1 · g`` (g the sample's distance from the
  first, at the slant spacing), which a reader of real, ground-range IMPs applies as it
  applies their polynomial;
- ``GEOLOCATION GRID ADS``: granules of about a twentieth of the frame (at least 2 lines),
  11 tie points across each granule's first and last line: sample, two-way slant-range
  time, incidence, latitude and longitude on the ellipsoid (1e-6°), located by the
  annotation's own range–Doppler model (:meth:`levels.sar.SarAnnotation.ground_of_image`);
- ``MDS1``: one record per line: its zero-Doppler time, quality 0, line number, then the
  amplitude ``round(S √I)`` as unsigned 16-bit, ``S`` putting the median at 1000 counts
  (bright pixels clipped at 65535, counted in the result).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from levels.errors import ProductError
from levels.files import atomic_path
from levels.geometry.ephemeris import Ephemeris
from levels.readers.envisat import (
    DOPPLER_ADSR,
    DSD_SIZE,
    GEOLOCATION_ADSR,
    MDS_PREFIX,
    MJD,
    MPH_SIZE,
    MPP_ADSR,
    SRGR_ADSR,
    mjd_of,
)
from levels.sar import SarImage
from levels.sar.annotation import SPEED_OF_LIGHT_M_PER_S

__all__ = ["MEDIAN_DN", "write_envisat"]

#: The amplitude the frame's median intensity is written at (counts).
MEDIAN_DN = 1000.0
#: Tie points across a line, and granules of the geolocation grid.
_TIES, _GRANULES = 11, 20


def _utc_text(utc: Any) -> str:
    """``DD-MMM-YYYY HH:MM:SS.uuuuuu``: the headers' time format."""
    s = str(np.asarray(utc).astype("datetime64[us]"))
    day, _, clock = s.partition("T")
    y, m, d = day.split("-")
    months = "JAN FEB MAR APR MAY JUN JUL AUG SEP OCT NOV DEC".split()
    return f"{d}-{months[int(m) - 1]}-{y} {clock}"


def _lines(pairs: list[tuple[str, str]]) -> str:
    return "".join(f"{k}={v}\n" for k, v in pairs)


def _dsd(name: str, kind: str, offset: int, size: int, num: int, rec: int) -> str:
    text = (
        f'DS_NAME="{name:<28}"\nDS_TYPE={kind}\nFILENAME="{"":<62}"\n'
        f"DS_OFFSET={offset:+021d}<bytes>\nDS_SIZE={size:+021d}<bytes>\n"
        f"NUM_DSR={num:+011d}\nDSR_SIZE={rec:+011d}<bytes>\n"
    )
    text += " " * (DSD_SIZE - 1 - len(text)) + "\n"
    assert len(text) == DSD_SIZE
    return text


def _state_vectors(image: SarImage) -> NDArray[np.void]:
    """Five state vectors from 10 s before the first line to 10 s after the last."""
    a = image.annotation
    t_end = a.first_line_s + (a.shape[0] - 1) * a.line_interval_s
    t = np.linspace(a.first_line_s - 10.0, t_end + 10.0, 5)
    r, v = Ephemeris(a.state_t_s, a.state_r_m, a.state_v_m_per_s).interpolate(t)
    out = np.zeros(5, dtype=MPP_ADSR["state_vectors"].base)
    out["time"] = mjd_of(a.epoch.utc(t))
    for k, axis in enumerate("xyz"):
        out[axis] = np.rint(r[:, k] * 1e2).astype(np.int64)
        out[f"v{axis}"] = np.rint(v[:, k] * 1e5).astype(np.int64)
    return out


def _grid(image: SarImage) -> NDArray[np.void]:
    """The geolocation grid's records (module docstring)."""
    a = image.annotation
    n_lines, n_samples = a.shape
    per = max(2, -(-n_lines // _GRANULES))
    firsts = np.arange(0, n_lines, per)
    samples = np.rint(np.linspace(0, n_samples - 1, _TIES)).astype(np.int64)
    rec = np.zeros(firsts.size, dtype=GEOLOCATION_ADSR)
    for side, lines in (("first", firsts), ("last", np.minimum(firsts + per, n_lines) - 1)):
        ln = np.repeat(lines, _TIES).astype(np.float64)
        col = np.tile(samples, lines.size).astype(np.float64)
        lat, lon = a.ground_of_image(ln, col, 0.0)
        inc = np.degrees(a.incidence(lat, lon, np.zeros_like(lat)))
        r = a.near_range_m + col * a.range_spacing_m
        ties = rec[side]
        ties["samp_numbers"] = (col + 1).reshape(-1, _TIES)
        ties["slant_range_times"] = (2e9 * r / SPEED_OF_LIGHT_M_PER_S).reshape(-1, _TIES)
        ties["angles"] = inc.reshape(-1, _TIES)
        ties["lats"] = np.rint(np.degrees(lat) * 1e6).reshape(-1, _TIES)
        ties["longs"] = np.rint(np.degrees(lon) * 1e6).reshape(-1, _TIES)
        key = "first_zero_doppler_time" if side == "first" else "last_zero_doppler_time"
        rec[key] = mjd_of(a.epoch.utc(a.first_line_s + lines * a.line_interval_s))
    rec["line_num"] = firsts + 1
    rec["num_lines"] = np.minimum(firsts + per, n_lines) - firsts
    return rec


def _mpp(image: SarImage, scale: float) -> NDArray[np.void]:
    a = image.annotation
    c = SPEED_OF_LIGHT_M_PER_S
    m = np.zeros(1, dtype=MPP_ADSR)
    t = a.first_line_s + np.array([0, a.shape[0] - 1]) * a.line_interval_s
    first, last = mjd_of(a.epoch.utc(t))
    m["first_zero_doppler_time"], m["last_zero_doppler_time"] = first, last
    m["swath_id"] = b"IS2"
    m["range_spacing"] = a.range_spacing_m
    m["azimuth_spacing"] = a.line_interval_s * 7000.0  # about ERS's ground speed
    m["line_time_interval"] = a.line_interval_s
    m["num_output_lines"], m["num_samples_per_line"] = a.shape
    m["data_type"] = b"UWORD"
    m["srgr_flag"], m["detected_flag"] = 1, 1
    m["range_samp_rate"] = c / (2.0 * a.range_spacing_m)
    m["radar_freq"] = c / a.wavelength_m
    m["num_looks_range"], m["num_look_az"] = 1, max(1, round(a.looks))
    m["ext_cal_fact"] = scale * scale
    m["state_vectors"] = _state_vectors(image)
    return m


def _doppler_and_srgr(image: SarImage) -> tuple[NDArray[np.void], NDArray[np.void]]:
    a = image.annotation
    c = SPEED_OF_LIGHT_M_PER_S
    mid = mjd_of(a.epoch.utc(np.array([a.first_line_s + 0.5 * a.shape[0] * a.line_interval_s])))
    tau0 = 2.0 * a.near_range_m / c
    km_per_s = c / 2000.0  # km of slant range per second of two-way time
    dop = np.zeros(1, dtype=DOPPLER_ADSR)
    dop["zero_doppler_time"], dop["slant_range_time"] = mid, tau0 * 1e9
    coef = np.zeros(5)
    for k, ck in enumerate(a.doppler_hz[:5]):
        coef[k] = ck * km_per_s**k
    dop["dop_coef"], dop["dop_conf"] = coef, 1.0
    srgr = np.zeros(1, dtype=SRGR_ADSR)
    srgr["zero_doppler_time"], srgr["slant_range_time"] = mid, tau0 * 1e9
    srgr["srgr_coeff"] = [a.near_range_m, 1.0, 0.0, 0.0, 0.0]
    return dop, srgr


def _amplitude(image: SarImage) -> tuple[NDArray[np.void], float, int]:
    """The MDS1 records, the scale ``S`` and the count of samples clipped."""
    a = image.annotation
    intensity = np.nan_to_num(np.asarray(image.intensity, dtype=np.float64), nan=0.0)
    median = float(np.median(intensity[intensity > 0])) if np.any(intensity > 0) else 1.0
    scale = MEDIAN_DN / np.sqrt(median)
    dn = np.rint(scale * np.sqrt(np.maximum(intensity, 0.0)))
    clipped = int(np.count_nonzero(dn > 65535))
    n_lines, n_samples = a.shape
    rec = np.zeros(
        n_lines,
        dtype=[("time", MJD), ("quality", "u1"), ("line", ">u4"), ("v", ">u2", (n_samples,))],
    )
    rec["time"] = mjd_of(a.epoch.utc(a.first_line_s + np.arange(n_lines) * a.line_interval_s))
    rec["line"] = np.arange(1, n_lines + 1)
    rec["v"] = np.minimum(dn, 65535).astype(np.uint16)
    assert rec.dtype.itemsize == MDS_PREFIX + 2 * n_samples
    return rec, float(scale), clipped


def write_envisat(
    path: str | Path, image: SarImage, *, mission: str = "ERS-1", station: str = "spot-station"
) -> Path:
    """Write ``image`` as an ENVISAT-format ``SAR_IMP_1P`` at ``path`` (atomically; module
    docstring). ``mission``: ``ERS-1`` (``.E1``) or ``ERS-2`` (``.E2``)."""
    a = image.annotation
    if not a.right_looking:
        raise ProductError("the ENVISAT format has no left-looking SAR: ERS and ASAR look right")
    if mission not in ("ERS-1", "ERS-2"):
        raise ProductError(f"mission {mission!r}: ERS-1 or ERS-2")
    mpp = _mpp(image, 1.0)
    mds, scale, _ = _amplitude(image)
    mpp["ext_cal_fact"] = scale * scale
    dop, srgr = _doppler_and_srgr(image)
    grid = _grid(image)
    blocks = [
        ("MAIN PROCESSING PARAMS ADS", "A", mpp),
        ("DOP CENTROID COEFFS ADS", "A", dop),
        ("SR GR ADS", "A", srgr),
        ("GEOLOCATION GRID ADS", "A", grid),
        ("MDS1", "M", mds),
    ]
    sph_head = _sph(image, grid)
    sph_size = len(sph_head) + DSD_SIZE * len(blocks)
    offset = MPH_SIZE + sph_size
    dsds = []
    for name, kind, rec in blocks:
        dsds.append(_dsd(name, kind, offset, rec.nbytes, rec.size, rec.dtype.itemsize))
        offset += rec.nbytes
    mph = _mph(image, mission, station, offset, sph_size, len(blocks))
    target = Path(path)
    with atomic_path(target) as tmp, open(tmp, "wb") as f:
        f.write(mph.encode("ascii"))
        f.write((sph_head + "".join(dsds)).encode("ascii"))
        for _, _, rec in blocks:
            f.write(rec.tobytes())
    return target


def _sph(image: SarImage, grid: NDArray[np.void]) -> str:
    a = image.annotation
    first, last = grid[0]["first"], grid[-1]["last"]
    t = a.first_line_s + np.array([0, a.shape[0] - 1]) * a.line_interval_s
    t0, t1 = (_utc_text(u) for u in a.epoch.utc(t))
    corners = []
    for name, ties in (("FIRST", first), ("LAST", last)):
        for where, k in (("NEAR", 0), ("MID", 5), ("FAR", 10)):
            corners.append((f"{name}_{where}_LAT", f"{int(ties['lats'][k]):+011d}<10-6degN>"))
            corners.append((f"{name}_{where}_LONG", f"{int(ties['longs'][k]):+011d}<10-6degE>"))
    descending = bool(a.state_v_m_per_s[len(a.state_v_m_per_s) // 2, 2] < 0)
    text = _lines(
        [
            ("SPH_DESCRIPTOR", '"Image Mode Precision Image "'),
            ("STRIPLINE_CONTINUITY_INDICATOR", "+000"),
            ("SLICE_POSITION", "+001"),
            ("NUM_SLICES", "+001"),
            ("FIRST_LINE_TIME", f'"{t0}"'),
            ("LAST_LINE_TIME", f'"{t1}"'),
            *corners,
        ]
    )
    text += " " * 34 + "\n"
    text += _lines(
        [
            ("SWATH", '"IS2"'),
            ("PASS", '"DESCENDING"' if descending else '"ASCENDING "'),
            ("SAMPLE_TYPE", '"DETECTED"'),
            ("ALGORITHM", '"RAN/DOP"'),
            ("MDS1_TX_RX_POLAR", '"V/V"'),
            ("MDS2_TX_RX_POLAR", '"   "'),
            ("COMPRESSION", '"NONE    "'),
            ("AZIMUTH_LOOKS", f"{max(1, round(a.looks)):+04d}"),
            ("RANGE_LOOKS", "+001"),
            ("RANGE_SPACING", f"{a.range_spacing_m:+.6e}<m>"),
            ("AZIMUTH_SPACING", f"{a.line_interval_s * 7000.0:+.6e}<m>"),
            ("LINE_TIME_INTERVAL", f"{a.line_interval_s:+.9e}<s>"),
            ("LINE_LENGTH", f"{a.shape[1]:+06d}<samples>"),
            ("DATA_TYPE", '"UWORD"'),
        ]
    )
    return text + " " * 50 + "\n"


def _mph(image: SarImage, mission: str, station: str, total: int, sph: int, n: int) -> str:
    a = image.annotation
    t = a.first_line_s + np.array([0, a.shape[0] - 1]) * a.line_interval_s
    u0, u1 = a.epoch.utc(t)
    start, stop = _utc_text(u0), _utc_text(u1)
    stamp = str(np.datetime64(u0, "s")).replace("-", "").replace(":", "").replace("T", "_")
    seconds = int(np.rint(t[1] - t[0])) + 1
    suffix = ".E1" if mission == "ERS-1" else ".E2"
    name = f"SAR_IMP_1PNXXX{stamp}_{seconds:08d}_00000000_00000_00000_0000{suffix}"
    sv = _state_vectors(image)[2]
    text = _lines(
        [
            ("PRODUCT", f'"{name:<62}"'),
            ("PROC_STAGE", "N"),
            ("REF_DOC", f'"{"PX-SP-50-9105 3/1":<23}"'),
        ]
    )
    text += " " * 40 + "\n"
    text += _lines(
        [
            ("ACQUISITION_STATION", f'"{station[:20]:<20}"'),
            ("PROC_CENTER", f'"{"EMUL":<6}"'),
            ("PROC_TIME", f'"{start}"'),
            ("SOFTWARE_VER", f'"{"spot-station":<14}"'),
        ]
    )
    text += " " * 40 + "\n"
    text += _lines([("SENSING_START", f'"{start}"'), ("SENSING_STOP", f'"{stop}"')])
    text += " " * 40 + "\n"
    text += _lines(
        [
            ("PHASE", "X"),
            ("CYCLE", "+000"),
            ("REL_ORBIT", "+00000"),
            ("ABS_ORBIT", "+00000"),
            ("STATE_VECTOR_TIME", f'"{_utc_text(a.epoch.utc(np.array([0.0]))[0])}"'),
            ("DELTA_UT1", "+.000000<s>"),
            ("X_POSITION", f"{sv['x'] / 100:+012.3f}<m>"),
            ("Y_POSITION", f"{sv['y'] / 100:+012.3f}<m>"),
            ("Z_POSITION", f"{sv['z'] / 100:+012.3f}<m>"),
            ("X_VELOCITY", f"{sv['vx'] / 1e5:+012.6f}<m/s>"),
            ("Y_VELOCITY", f"{sv['vy'] / 1e5:+012.6f}<m/s>"),
            ("Z_VELOCITY", f"{sv['vz'] / 1e5:+012.6f}<m/s>"),
            ("VECTOR_SOURCE", '"FP"'),
        ]
    )
    text += " " * 40 + "\n"
    text += _lines(
        [
            ("PRODUCT_ERR", "0"),
            ("TOT_SIZE", f"{total:+021d}<bytes>"),
            ("SPH_SIZE", f"{sph:+011d}<bytes>"),
            ("NUM_DSD", f"{n:+011d}"),
            ("DSD_SIZE", f"{DSD_SIZE:+011d}<bytes>"),
            ("NUM_DATA_SETS", f"{n:+011d}"),
        ]
    )
    if len(text) > MPH_SIZE - 1:
        raise AssertionError(f"MPH of {len(text)} bytes")
    return text + " " * (MPH_SIZE - 1 - len(text)) + "\n"
