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

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

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
    resample_columns,
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


@dataclass(frozen=True, eq=False)
class _Layout:
    """What the file's samples are: the product, their intensity as written (lines ×
    samples), their spacing, and the SR/GR polynomial giving each sample's slant range,
    ``R = Σ srgr[k] g^k`` with ``g`` the sample's distance from the first."""

    product: str
    values: NDArray[np.float64]
    spacing_m: float
    srgr: NDArray[np.float64]

    def slant_range(self, column: ArrayLike) -> NDArray[np.float64]:
        g = np.asarray(column, dtype=np.float64) * self.spacing_m
        return np.asarray(np.polynomial.polynomial.polyval(g, self.srgr), dtype=np.float64)


def _layout(image: SarImage, product: str, ground_range: bool) -> _Layout:
    """The samples of ``product``: the slant-range image as it is (an IMS; an IMP whose
    SR/GR polynomial is the identity), or, ``ground_range``, resampled (cubic) onto ground
    range as ESA's IMPs are: the same number of samples, evenly spaced on the ellipsoid
    along the middle line, the SR/GR polynomial of degree 4 fitted to that line."""
    from pyproj import Geod

    a = image.annotation
    values = np.nan_to_num(np.asarray(image.intensity, dtype=np.float64), nan=0.0)
    near, dr = a.near_range_m, a.range_spacing_m
    if not ground_range:
        return _Layout(product, values, dr, np.array([near, 1.0]))
    n_lines, n = a.shape
    cols = np.arange(n, dtype=np.float64)
    lat, lon = a.ground_of_image(np.full(n, n_lines // 2, dtype=np.float64), cols, 0.0)
    lat_deg, lon_deg = np.degrees(lat), np.degrees(lon)
    _, _, step = Geod(ellps="WGS84").inv(lon_deg[:-1], lat_deg[:-1], lon_deg[1:], lat_deg[1:])
    g = np.concatenate([[0.0], np.cumsum(step)])
    srgr = np.polynomial.polynomial.polyfit(g, near + cols * dr, 4)
    srgr = srgr.astype(np.float32).astype(np.float64)  # as the file holds it
    layout = _Layout(product, values, float(g[-1] / (n - 1)), srgr)
    ground = resample_columns(values, (layout.slant_range(cols) - near) / dr)
    return _Layout(product, np.maximum(ground, 0.0).astype(np.float64), layout.spacing_m, srgr)


def _grid(image: SarImage, layout: _Layout) -> NDArray[np.void]:
    """The geolocation grid's records (module docstring)."""
    a = image.annotation
    n_lines, n_samples = layout.values.shape
    per = max(2, -(-n_lines // _GRANULES))
    firsts = np.arange(0, n_lines, per)
    samples = np.rint(np.linspace(0, n_samples - 1, _TIES)).astype(np.int64)
    rec = np.zeros(firsts.size, dtype=GEOLOCATION_ADSR)
    for side, lines in (("first", firsts), ("last", np.minimum(firsts + per, n_lines) - 1)):
        ln = np.repeat(lines, _TIES).astype(np.float64)
        col = np.tile(samples, lines.size).astype(np.float64)
        r = layout.slant_range(col)
        lat, lon = a.ground_of_image(ln, (r - a.near_range_m) / a.range_spacing_m, 0.0)
        inc = np.degrees(a.incidence(lat, lon, np.zeros_like(lat)))
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


def _is_slc(layout: _Layout) -> bool:
    return layout.product.endswith("IMS_1P")


def _mpp(image: SarImage, layout: _Layout, scale: float) -> NDArray[np.void]:
    a = image.annotation
    c = SPEED_OF_LIGHT_M_PER_S
    m = np.zeros(1, dtype=MPP_ADSR)
    t = a.first_line_s + np.array([0, a.shape[0] - 1]) * a.line_interval_s
    first, last = mjd_of(a.epoch.utc(t))
    m["first_zero_doppler_time"], m["last_zero_doppler_time"] = first, last
    m["swath_id"] = b"IS2"
    m["range_spacing"] = layout.spacing_m
    m["azimuth_spacing"] = a.line_interval_s * 7000.0  # about ERS's ground speed
    m["line_time_interval"] = a.line_interval_s
    m["num_output_lines"], m["num_samples_per_line"] = layout.values.shape
    m["data_type"] = b"SWORD" if _is_slc(layout) else b"UWORD"
    m["srgr_flag"] = 0 if _is_slc(layout) else 1
    m["detected_flag"] = 0 if _is_slc(layout) else 1
    m["range_samp_rate"] = c / (2.0 * a.range_spacing_m)
    m["radar_freq"] = c / a.wavelength_m
    m["num_looks_range"], m["num_look_az"] = 1, max(1, round(a.looks))
    m["ext_cal_fact"] = scale * scale
    m["state_vectors"] = _state_vectors(image)
    return m


def _doppler_and_srgr(
    image: SarImage, layout: _Layout
) -> tuple[NDArray[np.void], NDArray[np.void]]:
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
    srgr["srgr_coeff"] = np.pad(layout.srgr, (0, 5 - layout.srgr.size))
    return dop, srgr


def _samples(image: SarImage, layout: _Layout) -> tuple[NDArray[np.void], float, int]:
    """The MDS1 records, the scale ``S`` and the count of samples clipped: an IMP's
    amplitude ``round(S √I)``, an IMS's ``round(S √I (cos φ, sin φ))`` with a phase drawn
    uniformly (seeded: the same frame, the same file)."""
    a = image.annotation
    values = layout.values
    median = float(np.median(values[values > 0])) if np.any(values > 0) else 1.0
    scale = MEDIAN_DN / np.sqrt(median)
    amplitude = scale * np.sqrt(values)
    n_lines, n_samples = values.shape
    slc = _is_slc(layout)
    if slc:
        phase = np.random.default_rng(0).uniform(0.0, 2 * np.pi, values.shape)
        parts = np.rint(np.stack([amplitude * np.cos(phase), amplitude * np.sin(phase)], -1))
        clipped = int(np.count_nonzero(np.abs(parts) > 32767))
        v = np.clip(parts, -32767, 32767).astype(np.int16).reshape(n_lines, 2 * n_samples)
        sample = (">i2", (2 * n_samples,))
    else:
        dn = np.rint(amplitude)
        clipped = int(np.count_nonzero(dn > 65535))
        v = np.minimum(dn, 65535).astype(np.uint16)
        sample = (">u2", (n_samples,))
    rec = np.zeros(n_lines, dtype=[("time", MJD), ("quality", "u1"), ("line", ">u4"),
                                   ("v", *sample)])  # fmt: skip
    rec["time"] = mjd_of(a.epoch.utc(a.first_line_s + np.arange(n_lines) * a.line_interval_s))
    rec["line"] = np.arange(1, n_lines + 1)
    rec["v"] = v
    assert rec.dtype.itemsize == MDS_PREFIX + (4 if slc else 2) * n_samples
    return rec, float(scale), clipped


def write_envisat(
    path: str | Path,
    image: SarImage,
    *,
    product: str = "SAR_IMP_1P",
    ground_range: bool = False,
    mission: str = "ERS-1",
    station: str = "spot-station",
) -> Path:
    """Write ``image`` as an ENVISAT-format ``product`` at ``path`` (atomically; module
    docstring): ``SAR_IMP_1P`` on slant range (the SR/GR polynomial the identity) or, with
    ``ground_range``, resampled onto ground range as ESA's are; ``SAR_IMS_1P`` complex.
    ``mission``: ``ERS-1`` (``.E1``) or ``ERS-2`` (``.E2``)."""
    a = image.annotation
    if not a.right_looking:
        raise ProductError("the ENVISAT format has no left-looking SAR: ERS and ASAR look right")
    if mission not in ("ERS-1", "ERS-2"):
        raise ProductError(f"mission {mission!r}: ERS-1 or ERS-2")
    if product not in ("SAR_IMP_1P", "SAR_IMS_1P") or (ground_range and product != "SAR_IMP_1P"):
        raise ProductError(
            f"product {product!r}{' on ground range' if ground_range else ''}: SAR_IMP_1P "
            "(slant or ground range) or SAR_IMS_1P (slant range)"
        )
    layout = _layout(image, product, ground_range)
    mds, scale, _ = _samples(image, layout)
    dop, srgr = _doppler_and_srgr(image, layout)
    grid = _grid(image, layout)
    blocks = [
        ("MAIN PROCESSING PARAMS ADS", "A", _mpp(image, layout, scale)),
        ("DOP CENTROID COEFFS ADS", "A", dop),
        *([] if _is_slc(layout) else [("SR GR ADS", "A", srgr)]),
        ("GEOLOCATION GRID ADS", "A", grid),
        ("MDS1", "M", mds),
    ]
    sph_head = _sph(image, layout, grid)
    sph_size = len(sph_head) + DSD_SIZE * len(blocks)
    offset = MPH_SIZE + sph_size
    dsds = []
    for name, kind, rec in blocks:
        dsds.append(_dsd(name, kind, offset, rec.nbytes, rec.size, rec.dtype.itemsize))
        offset += rec.nbytes
    mph = _mph(image, product, mission, station, offset, sph_size, len(blocks))
    target = Path(path)
    with atomic_path(target) as tmp, open(tmp, "wb") as f:
        f.write(mph.encode("ascii"))
        f.write((sph_head + "".join(dsds)).encode("ascii"))
        for _, _, rec in blocks:
            f.write(rec.tobytes())
    return target


def _sph(image: SarImage, layout: _Layout, grid: NDArray[np.void]) -> str:
    a = image.annotation
    slc = _is_slc(layout)
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
            (
                "SPH_DESCRIPTOR",
                '"Image Mode SLC Image       "' if slc else '"Image Mode Precision Image "',
            ),
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
            ("SAMPLE_TYPE", '"COMPLEX "' if slc else '"DETECTED"'),
            ("ALGORITHM", '"RAN/DOP"'),
            ("MDS1_TX_RX_POLAR", '"V/V"'),
            ("MDS2_TX_RX_POLAR", '"   "'),
            ("COMPRESSION", '"NONE    "'),
            ("AZIMUTH_LOOKS", f"{max(1, round(a.looks)):+04d}"),
            ("RANGE_LOOKS", "+001"),
            ("RANGE_SPACING", f"{layout.spacing_m:+.6e}<m>"),
            ("AZIMUTH_SPACING", f"{a.line_interval_s * 7000.0:+.6e}<m>"),
            ("LINE_TIME_INTERVAL", f"{a.line_interval_s:+.9e}<s>"),
            ("LINE_LENGTH", f"{layout.values.shape[1]:+06d}<samples>"),
            ("DATA_TYPE", '"SWORD"' if slc else '"UWORD"'),
        ]
    )
    return text + " " * 50 + "\n"


def _mph(
    image: SarImage, product: str, mission: str, station: str, total: int, sph: int, n: int
) -> str:
    a = image.annotation
    t = a.first_line_s + np.array([0, a.shape[0] - 1]) * a.line_interval_s
    u0, u1 = a.epoch.utc(t)
    start, stop = _utc_text(u0), _utc_text(u1)
    stamp = str(np.datetime64(u0, "s")).replace("-", "").replace(":", "").replace("T", "_")
    seconds = int(np.rint(t[1] - t[0])) + 1
    suffix = ".E1" if mission == "ERS-1" else ".E2"
    name = f"{product}NXXX{stamp}_{seconds:08d}_00000000_00000_00000_0000{suffix}"
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
