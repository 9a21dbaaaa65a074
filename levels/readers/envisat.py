"""Reader of ERS-1/2 SAR frames in ESA's ENVISAT product format (``SAR_IMP_1P``,
``SAR_IMS_1P``; files ``*.E1``, ``*.E2``): what ESA's reprocessed ERS archive is.

The format (ENVISAT Products Specifications, PX-SP-50-9105, vol. 8 ASAR; the ERS SAR
products in ENVISAT format follow the ASAR image-mode layout) is a main product header (MPH,
1247 bytes of ``KEY=value`` lines), a specific product header (SPH: more ``KEY=value``
lines, then one 280-byte data set descriptor, DSD, per data set), then the data sets: the
annotation data sets (ADS, fixed binary records, big-endian) and the image (MDS1: one
record per line, a 17-byte header then the samples). Read here, per the specification's
record layouts (:data:`MPP_ADSR`, :data:`DOPPLER_ADSR`, :data:`SRGR_ADSR`,
:data:`GEOLOCATION_ADSR`):

- **image** (``MDS1``): ``SAR_IMP_1P`` amplitude (``UWORD``), detected as ``DN² / K`` with
  ``K`` the main processing parameters' ``EXT_CAL_FACT`` (1 where it is 0);
  ``SAR_IMS_1P`` complex (``SWORD`` I, Q), detected as ``I² + Q²``. Not applied: the
  incidence-angle term of ERS's σ⁰ calibration, the antenna pattern, noise subtraction;
  the products say β⁰ as the house frame does;
- **timing**: the first line's zero-Doppler time (the first MDS record's, MJD 2000 to the
  microsecond), the line interval (SPH ``LINE_TIME_INTERVAL``);
- **orbit**: the main processing parameters' five state vectors (ECEF, Earth-fixed
  velocity; 1 cm, 10 µm/s);
- **range**: ``SAR_IMS_1P``: slant range of the first sample from the Doppler ADS's
  two-way slant-range time, samples ``c / (2 RANGE_SAMP_RATE)`` apart; ``SAR_IMP_1P``:
  slant range of each ground-range sample by the SR/GR polynomial (``S0 + S1 (g − g0) +
  …``) of the record nearest the frame's middle; when it is not linear, each line is
  resampled (cubic) onto slant range at the IMS spacing, so that :mod:`levels.sar`'s
  range–Doppler model applies;
- **Doppler**: the centroid's polynomial in two-way slant-range time, as the house
  annotation's polynomial in ``(R − r0) / 1 km``;
- **wavelength** ``c / RADAR_FREQ``; looks ``AZIMUTH_LOOKS × RANGE_LOOKS``; right-looking
  (ERS and ASAR are);
- **geolocation grid** (:class:`GeolocationGrid`): ESA's tie points, for ``station
  locate`` to check the model against (as GDAL's ESAT driver gives them as GCPs).

Refused in one line naming the file: not an ENVISAT product, a product other than ERS or
ASAR image-mode level 1, a header whose sizes disagree with the file, a data set missing.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numba as nb
import numpy as np
from numpy.typing import NDArray

from levels.errors import GeometryError, ProductError
from levels.geometry.times import Epoch
from levels.readers.bounded import begins_with
from levels.readers.sar import ImageFrame
from levels.sar import SarAnnotation, SarImage
from levels.sar.annotation import SPEED_OF_LIGHT_M_PER_S
from levels.threads import over_blocks

__all__ = [
    "DOPPLER_ADSR",
    "ENVISAT_SUFFIXES",
    "GEOLOCATION_ADSR",
    "MDS_PREFIX",
    "MJD",
    "MPH_SIZE",
    "MPP_ADSR",
    "SRGR_ADSR",
    "EnvisatFrame",
    "GeolocationGrid",
    "is_envisat",
    "mjd_of",
    "read_envisat",
    "resample_columns",
]

#: Size of the main product header (bytes).
MPH_SIZE = 1247
#: Slant-range samples a ground-range sample may become at most (ERS: about 1.2, at the far
#: edge 1.6): a bound on the image an SR/GR polynomial resamples to.
_SLANT_PER_GROUND = 4
#: Size of one data set descriptor in the SPH (bytes).
DSD_SIZE = 280
#: Bytes before the samples in each image record: zero-Doppler time, quality, line number.
MDS_PREFIX = 17
#: MJD 2000: days since 2000-01-01T00:00 UTC, seconds, microseconds (big-endian).
MJD = np.dtype([("days", ">i4"), ("seconds", ">u4"), ("microseconds", ">u4")])
_MJD0 = np.datetime64("2000-01-01T00:00:00", "ns")
_STATE = np.dtype(
    [
        ("time", MJD),
        ("x", ">i4"),
        ("y", ">i4"),
        ("z", ">i4"),
        ("vx", ">i4"),
        ("vy", ">i4"),
        ("vz", ">i4"),
    ]
)


def _record(itemsize: int, fields: list[tuple[str, Any, int]]) -> np.dtype:
    names, formats, offsets = zip(*[(n, f, o) for n, f, o in fields], strict=True)
    return np.dtype(
        {
            "names": list(names),
            "formats": list(formats),
            "offsets": list(offsets),
            "itemsize": itemsize,
        }
    )


#: Main processing parameters ADSR (2009 bytes): the fields read and written here.
MPP_ADSR = _record(
    2009,
    [
        ("first_zero_doppler_time", MJD, 0),
        ("last_zero_doppler_time", MJD, 13),
        ("swath_id", "S3", 41),
        ("range_spacing", ">f4", 44),
        ("azimuth_spacing", ">f4", 48),
        ("line_time_interval", ">f4", 52),
        ("num_output_lines", ">u4", 56),
        ("num_samples_per_line", ">u4", 60),
        ("data_type", "S5", 64),
        ("srgr_flag", "u1", 123),
        ("detected_flag", "u1", 127),
        ("range_samp_rate", ">f4", 983),
        ("radar_freq", ">f4", 987),
        ("num_looks_range", ">u2", 991),
        ("num_look_az", ">u2", 1268),
        ("ext_cal_fact", ">f4", 1381),
        ("state_vectors", (_STATE, 5), 1765),
    ],
)
#: Doppler centroid coefficients ADSR (55 bytes): two-way slant-range time origin (ns) and
#: the centroid's polynomial in (τ − τ0) (Hz, Hz/s, …).
DOPPLER_ADSR = _record(
    55,
    [
        ("zero_doppler_time", MJD, 0),
        ("slant_range_time", ">f4", 13),
        ("dop_coef", (">f4", 5), 17),
        ("dop_conf", ">f4", 37),
    ],
)
#: Slant range to ground range ADSR (55 bytes): slant range (m) = Σ S_k (g − g0)^k.
SRGR_ADSR = _record(
    55,
    [
        ("zero_doppler_time", MJD, 0),
        ("slant_range_time", ">f4", 13),
        ("ground_range_origin", ">f4", 17),
        ("srgr_coeff", (">f4", 5), 21),
    ],
)
_TIES = np.dtype(
    [
        ("samp_numbers", (">u4", 11)),
        ("slant_range_times", (">f4", 11)),
        ("angles", (">f4", 11)),
        ("lats", (">i4", 11)),
        ("longs", (">i4", 11)),
    ]
)
#: Geolocation grid ADSR (521 bytes): a granule's first and last line, 11 tie points
#: across each (1-based samples, two-way slant-range time in ns, incidence in degrees,
#: latitude and longitude in 1e-6 degrees).
GEOLOCATION_ADSR = _record(
    521,
    [
        ("first_zero_doppler_time", MJD, 0),
        ("attach_flag", "u1", 12),
        ("line_num", ">u4", 13),
        ("num_lines", ">u4", 17),
        ("sub_sat_track", ">f4", 21),
        ("first", _TIES, 25),
        ("last_zero_doppler_time", MJD, 267),
        ("last", _TIES, 279),
    ],
)


def mjd_of(utc: NDArray[np.datetime64]) -> NDArray[np.void]:
    """UTC instants as MJD 2000 records, rounded to the microsecond."""
    us = (np.asarray(utc, dtype="datetime64[ns]") - _MJD0).astype(np.int64)
    us = (us + 500) // 1000
    day_us = 86_400_000_000
    out = np.zeros(np.shape(us), dtype=MJD)
    out["days"] = us // day_us
    rest = us % day_us
    out["seconds"] = rest // 1_000_000
    out["microseconds"] = rest % 1_000_000
    return out


#: The MJD 2000 days a frame's times may fall on: 1970 to 2100 (ERS-1 flew from 1991, the
#: format from 2002); beyond, a damaged field, refused before it overflows a datetime.
_MJD_DAYS = (-10_957, 36_524)


def _utc_of(mjd: NDArray[np.void], where: Path | None = None) -> NDArray[np.datetime64]:
    days = mjd["days"].astype(np.int64)
    if days.size and not (
        _MJD_DAYS[0] <= days.min()
        and days.max() <= _MJD_DAYS[1]
        and mjd["seconds"].max() < 86_401
        and mjd["microseconds"].max() < 1_000_000
    ):
        raise ProductError(
            f"{where or 'an ENVISAT product'}: an MJD 2000 time of day {int(days.min())}…"
            f"{int(days.max())}, seconds up to {int(mjd['seconds'].max())}: expected "
            "1970–2100 and a time of day; damaged?"
        )
    us = (
        mjd["days"].astype(np.int64) * 86_400_000_000
        + mjd["seconds"].astype(np.int64) * 1_000_000
        + mjd["microseconds"].astype(np.int64)
    )
    return _MJD0 + (us * 1000).astype("timedelta64[ns]")


def _pairs(text: str) -> dict[str, str]:
    """``KEY=value<unit>`` lines as a dictionary: quotes and units removed."""
    out = {}
    for line in text.splitlines():
        key, eq, value = line.partition("=")
        if not eq:
            continue
        value = value.strip()
        if value.startswith('"'):
            value = value[1:].partition('"')[0]
        else:
            value = value.partition("<")[0]
        out[key.strip()] = value.strip()
    return out


@dataclass(frozen=True)
class _Dataset:
    name: str
    kind: str
    offset: int
    size: int
    num_dsr: int
    dsr_size: int


@dataclass(frozen=True)
class GeolocationGrid:
    """ESA's tie points: 0-based line and column (pixel centres) of the file's samples,
    the column of the reader's slant-range image (:meth:`EnvisatFrame.image`; the file's
    own but for a ground-range IMP), latitude and longitude (degrees, on the ellipsoid),
    incidence (degrees), two-way slant-range time (ns)."""

    line: NDArray[np.float64]
    column: NDArray[np.float64]
    slant_column: NDArray[np.float64]
    lat_deg: NDArray[np.float64]
    lon_deg: NDArray[np.float64]
    incidence_deg: NDArray[np.float64]
    slant_range_time_ns: NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class EnvisatFrame(ImageFrame):
    """An ERS (or ASAR image-mode) level-1 frame of ESA's format: the reader's
    :class:`~levels.readers.sar.SarFrame` (module docstring)."""

    name: str
    instrument: str
    sar: SarImage
    grid: GeolocationGrid
    mph: dict[str, str]
    sph: dict[str, str]
    path: Path | None = None

    @property
    def product_type(self) -> str:
        return self.mph.get("PRODUCT", "")[:10]


#: The names ENVISAT-format products of ERS-1, ERS-2 and ENVISAT end in.
ENVISAT_SUFFIXES = (".e1", ".e2", ".n1")


def is_envisat(path: str | Path) -> bool:
    """Whether ``path`` is meant as an ENVISAT-format product: its first bytes
    ``PRODUCT=``, or its name ``.E1``, ``.E2``, ``.N1`` (an empty or damaged one is then
    :func:`read_envisat`'s to refuse, saying what it is not, rather than another reader's)."""
    p = Path(path)
    return (p.suffix.lower() in ENVISAT_SUFFIXES and p.is_file()) or begins_with(p, b"PRODUCT=")


def _count(where: Path, pairs: dict[str, str], key: str, lo: int, hi: int, what: str) -> int:
    """The integer field ``key`` of a header, refused unless within ``lo … hi``: every count,
    size and offset is bounded by what the file can hold before it is used."""
    text = pairs.get(key)
    try:
        value = int(text)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise ProductError(f"{where}: {what} {key}={text!r}: expected an integer") from None
    if not lo <= value <= hi:
        raise ProductError(
            f"{where}: {what} {key}={value}: expected {lo}…{hi} for a file of "
            f"{_file_bytes(where)} bytes; truncated, damaged or not an ENVISAT product"
        )
    return value


def _file_bytes(where: Path) -> int:
    try:
        return where.stat().st_size
    except OSError:
        return 0


def _headers(where: Path, raw: bytes) -> tuple[dict, dict, dict[str, _Dataset]]:
    """The MPH, the SPH and the data sets by name; every size, count and offset checked
    against the file's size before it is used (a descriptor claiming a billion data sets
    or records is refused, not looped over)."""
    if raw[:8] != b"PRODUCT=":
        raise ProductError(f"{where}: not an ENVISAT-format product (no PRODUCT= header)")
    if len(raw) < MPH_SIZE:
        raise ProductError(f"{where}: {len(raw)} bytes, shorter than its MPH: truncated?")
    mph = _pairs(raw[:MPH_SIZE].decode("ascii", "replace"))
    for key in ("SPH_SIZE", "NUM_DSD"):
        if key not in mph:
            raise ProductError(f"{where}: its MPH has no {key}")
    sph_size = _count(where, mph, "SPH_SIZE", 0, len(raw) - MPH_SIZE, "MPH")
    dsd_size = _count(
        where,
        {"DSD_SIZE": mph.get("DSD_SIZE", str(DSD_SIZE))},
        "DSD_SIZE",
        1,
        max(sph_size, 1),
        "MPH",
    )
    sph_text = raw[MPH_SIZE : MPH_SIZE + sph_size].decode("ascii", "replace")
    first_dsd = sph_text.find("DS_NAME=")
    room = (sph_size - first_dsd) // dsd_size if first_dsd >= 0 else 0
    num_dsd = _count(where, mph, "NUM_DSD", 0, room, "MPH")
    sph = _pairs(sph_text[:first_dsd] if first_dsd >= 0 else sph_text)
    datasets = {}
    for k in range(num_dsd):
        d = _pairs(sph_text[first_dsd + k * dsd_size : first_dsd + (k + 1) * dsd_size])
        if not d.get("DS_NAME"):
            continue
        where_ds = f"data set {d['DS_NAME']!r}:"
        fields = {key: d.get(key, "0") for key in ("DS_OFFSET", "DS_SIZE", "NUM_DSR", "DSR_SIZE")}
        offset = _count(where, fields, "DS_OFFSET", 0, len(raw), where_ds)
        size = _count(where, fields, "DS_SIZE", 0, 2**62, where_ds)
        if offset and offset + size > len(raw):
            raise ProductError(
                f"{where}: data set {d['DS_NAME']!r} ends at byte {offset + size}, the file "
                f"has {len(raw)}: truncated?"
            )
        dsr_size = _count(where, fields, "DSR_SIZE", -1, max(size, 0), where_ds)
        most = size // dsr_size if dsr_size > 0 else 2**31
        num_dsr = _count(where, fields, "NUM_DSR", 0, most if offset else 2**31, where_ds)
        datasets[d["DS_NAME"]] = _Dataset(
            d["DS_NAME"], d.get("DS_TYPE", ""), offset, size, num_dsr, dsr_size
        )
    return mph, sph, datasets


def _records(where: Path, raw: bytes, ds: dict[str, _Dataset], name: str, dtype: np.dtype):
    d = ds.get(name)
    if d is None or d.num_dsr < 1 or d.offset == 0:
        raise ProductError(f"{where}: no {name!r} data set; cannot model the frame")
    if d.dsr_size != dtype.itemsize:
        raise ProductError(
            f"{where}: {name!r} records of {d.dsr_size} bytes, the specification's are "
            f"{dtype.itemsize}"
        )
    return np.frombuffer(raw, dtype=dtype, count=d.num_dsr, offset=d.offset)


def read_envisat(path: str | Path) -> EnvisatFrame:
    """Read an ERS (or ASAR image-mode) level-1 frame of ESA's format (module docstring);
    :class:`ProductError` naming the file and what is wrong."""
    where = Path(path)
    if not where.is_file():
        raise ProductError(f"{where}: no such file")
    raw = where.read_bytes()
    mph, sph, ds = _headers(where, raw)
    product = mph.get("PRODUCT", "")
    kind = product[:10]
    if kind[4:] not in ("IMP_1P", "IMS_1P") or kind[:4] not in ("SAR_", "ASA_"):
        raise ProductError(
            f"{where}: product {kind!r}: this reads ERS SAR_IMP_1P and SAR_IMS_1P (and ASAR "
            "ASA_IMP_1P, ASA_IMS_1P) frames"
        )
    mpp = _records(where, raw, ds, "MAIN PROCESSING PARAMS ADS", MPP_ADSR)[0]
    dop = _records(where, raw, ds, "DOP CENTROID COEFFS ADS", DOPPLER_ADSR)
    geo = _records(where, raw, ds, "GEOLOCATION GRID ADS", GEOLOCATION_ADSR)
    image, first_utc = _image(where, raw, ds, sph, kind, mpp)
    epoch = Epoch(first_utc, name="the frame's first line")
    ann, image, slant_column = _annotation(where, raw, ds, sph, kind, mpp, dop, epoch, image)
    return EnvisatFrame(
        name=where.stem,
        instrument=_instrument(mph, kind),
        sar=SarImage(ann, image),
        grid=_grid(geo, slant_column),
        mph=mph,
        sph=sph,
        path=where,
    )


def _instrument(mph: dict[str, str], kind: str) -> str:
    if kind.startswith("ASA_"):
        return "ENVISAT ASAR"
    mission = "ERS-2" if mph.get("PRODUCT", "").upper().endswith(".E2") else "ERS-1"
    return f"{mission} AMI SAR"


def _image(
    where: Path, raw: bytes, ds: dict[str, _Dataset], sph: dict, kind: str, mpp: Any
) -> tuple[NDArray[np.float32], np.datetime64]:
    """The detected image (lines × samples, float32) and the first line's UTC."""
    d = ds.get("MDS1")
    if d is None or d.num_dsr < 2:
        raise ProductError(f"{where}: no MDS1 image data set of 2 lines or more")
    try:
        n = int(sph["LINE_LENGTH"])
    except (KeyError, ValueError):
        raise ProductError(f"{where}: its SPH has no LINE_LENGTH") from None
    complex_ = kind.endswith("IMS_1P")
    sample = np.dtype(">i2") if complex_ else np.dtype(">u2")
    per = 2 if complex_ else 1
    if d.dsr_size != MDS_PREFIX + per * sample.itemsize * n:
        raise ProductError(
            f"{where}: MDS1 records of {d.dsr_size} bytes for LINE_LENGTH {n} "
            f"{'complex ' if complex_ else ''}samples of {sample.itemsize} bytes"
        )
    rec = np.dtype([("time", MJD), ("quality", "u1"), ("line", ">u4"), ("v", sample, (n * per,))])
    lines = np.frombuffer(raw, dtype=rec, count=d.num_dsr, offset=d.offset)
    v = lines["v"].astype(np.float32)
    k = float(mpp["ext_cal_fact"])
    power = v[:, 0::2] ** 2 + v[:, 1::2] ** 2 if complex_ else v * v
    image = power / (k if math.isfinite(k) and k > 0 else 1.0)
    first = np.datetime64(_utc_of(lines["time"][:1], where)[0], "ns")
    return np.ascontiguousarray(image, dtype=np.float32), first


def _annotation(
    where: Path,
    raw: bytes,
    ds: dict,
    sph: dict,
    kind: str,
    mpp: Any,
    dop: Any,
    epoch: Epoch,
    image: NDArray[np.float32],
) -> tuple[SarAnnotation, NDArray[np.float32], Any]:
    """The range–Doppler annotation of the frame, its image on slant range, and the map
    from the file's columns to that image's."""
    c = SPEED_OF_LIGHT_M_PER_S
    sv = mpp["state_vectors"]
    t_sv = epoch.seconds(_utc_of(sv["time"], where))
    r = np.stack([sv["x"], sv["y"], sv["z"]], axis=1).astype(np.float64) * 1e-2
    v = np.stack([sv["vx"], sv["vy"], sv["vz"]], axis=1).astype(np.float64) * 1e-5
    spacing = c / (2.0 * _positive(where, mpp, "range_samp_rate"))
    tau0 = 1e-9 * float(dop["slant_range_time"][len(dop) // 2])
    near = c * tau0 / 2.0
    slant_column: Any = _same  # an IMS: its own columns
    if kind.endswith("IMP_1P"):
        records = _records(where, raw, ds, "SR GR ADS", SRGR_ADSR)
        rg = _srgr(records[len(records) // 2], _positive(where, mpp, "range_spacing"))
        near, spacing, image = _on_slant_range(where, rg, image, spacing)

        def slant_column(column: Any) -> Any:
            return (rg(column) - near) / spacing

    # the centroid in (τ − τ0) s → in (R − r0) km about the image's near range
    coef = np.asarray(dop["dop_coef"][len(dop) // 2], dtype=np.float64)
    per_km = 2000.0 / c  # two-way seconds per km of slant range
    shift = (2.0 * near / c) - tau0
    poly = np.polynomial.Polynomial(coef)(np.polynomial.Polynomial([shift, per_km]))
    try:
        looks = float(int(sph.get("AZIMUTH_LOOKS", "1")) * int(sph.get("RANGE_LOOKS", "1")))
        interval = float(sph["LINE_TIME_INTERVAL"])
    except (KeyError, ValueError):
        raise ProductError(f"{where}: its SPH has no LINE_TIME_INTERVAL or looks") from None
    if not looks >= 1:
        raise ProductError(f"{where}: AZIMUTH_LOOKS × RANGE_LOOKS = {looks:g}: expected ≥ 1")
    try:
        ann = SarAnnotation(
            epoch=epoch,
            state_t_s=t_sv,
            state_r_m=r,
            state_v_m_per_s=v,
            first_line_s=0.0,
            line_interval_s=interval,
            near_range_m=near,
            range_spacing_m=spacing,
            wavelength_m=c / _positive(where, mpp, "radar_freq"),
            doppler_hz=tuple(
                float(x) for x in np.pad(poly.coef, (0, max(0, 5 - poly.coef.size)))[:5]
            ),
            shape=image.shape,
            looks=looks,
            right_looking=True,
        )
    except GeometryError as exc:  # the annotation's own checks, naming the file
        raise ProductError(f"{where}: {exc}") from None
    return ann, image, slant_column


def _positive(where: Path, record: Any, name: str) -> float:
    """A record's field that must be a finite, positive number (a rate, a frequency, a
    spacing), refused naming it otherwise."""
    value = float(record[name])
    if not (math.isfinite(value) and value > 0):
        raise ProductError(f"{where}: main processing parameters' {name} {value!r}: expected > 0")
    return value


def _same(column: Any) -> Any:
    return column


def _srgr(srgr: Any, ground_spacing: float) -> Any:
    """The slant range (m) of a ground-range IMP's columns: ``R = Σ S_k (g − g0)^k``, ``g``
    the column's ground range (``column × RANGE_SPACING``)."""
    s = np.asarray(srgr["srgr_coeff"], dtype=np.float64)
    g0 = float(srgr["ground_range_origin"])

    def slant_range(column: Any) -> Any:
        return np.polynomial.polynomial.polyval(np.asarray(column) * ground_spacing - g0, s)

    slant_range.linear = not np.any(s[2:])  # type: ignore[attr-defined]
    return slant_range


def _on_slant_range(
    where: Path, rg: Any, image: NDArray[np.float32], slant_spacing: float
) -> tuple[float, float, NDArray[np.float32]]:
    """A ground-range image's near range, spacing and samples on slant range (``rg``: the
    slant range of each column): linear (the emulator's, or a slant-range image said as
    ground range), its own spacing and the image as it is; otherwise each line resampled
    (cubic) at ``slant_spacing`` from the near range."""
    n = image.shape[1]
    if rg.linear:  # slant range at each sample as it is
        return float(rg(0.0)), float(rg(1.0) - rg(0.0)), image
    r = rg(np.arange(n, dtype=np.float64))
    near, far = float(r[0]), float(r[-1])
    if not (np.all(np.isfinite(r)) and np.all(np.diff(r) > 0)):
        raise ProductError(
            f"{where}: its SR/GR polynomial does not give a slant range increasing across the "
            "line: damaged?"
        )
    m = int(np.floor((far - near) / slant_spacing)) + 1
    if m > _SLANT_PER_GROUND * n:  # ERS: about 1.2 slant samples a ground sample
        raise ProductError(
            f"{where}: its SR/GR polynomial spans {far - near:.0f} m of slant range over {n} "
            f"samples ({m} at {slant_spacing:.2f} m): more than {_SLANT_PER_GROUND} a sample"
        )
    wanted = near + np.arange(m) * slant_spacing
    column = np.interp(wanted, r, np.arange(n, dtype=np.float64))  # R(g) is monotonic
    return near, slant_spacing, np.maximum(resample_columns(image, column), 0.0)


def resample_columns(
    image: NDArray[np.floating], column: NDArray[np.float64]
) -> NDArray[np.float32]:
    """Every line of ``image`` sampled at fractional ``column`` s (the same for all lines)
    by cubic convolution (Keys, a = −0.5; edges repeated), lines on threads (a full ERS
    frame's 8300 × 5000 in about 0.1 s)."""
    n = image.shape[1]
    i0 = np.floor(column).astype(np.int64)
    f = column - i0
    taps = np.empty((4, column.size), dtype=np.float32)
    for k in range(-1, 3):  # the four weights of each output sample
        x = np.abs(f - k)
        taps[k + 1] = np.where(
            x <= 1.0,
            (1.5 * x - 2.5) * x * x + 1.0,
            np.where(x < 2.0, ((-0.5 * x + 2.5) * x - 4.0) * x + 2.0, 0.0),
        )
    index = np.clip(i0[None, :] + np.arange(-1, 3)[:, None], 0, n - 1)
    out = np.empty((image.shape[0], column.size), dtype=np.float32)
    src = np.ascontiguousarray(image, dtype=np.float32)
    over_blocks(_kernel_columns, image.shape[0], src, index, taps, out, grain=64)
    return out


@nb.njit(cache=True, nogil=True)
def _kernel_columns(lo, hi, src, index, taps, out):
    """Lines ``lo … hi − 1`` of :func:`resample_columns`."""
    for i in range(lo, hi):
        for j in range(out.shape[1]):
            v = 0.0
            for k in range(4):
                v += taps[k, j] * src[i, index[k, j]]
            out[i, j] = v


def _grid(geo: Any, slant_column: Any) -> GeolocationGrid:
    """ESA's tie points of every granule's first line, and of the last granule's last;
    ``slant_column`` maps the file's columns to the slant-range image's."""
    parts = [(geo["line_num"], geo["first"])]
    last = geo[-1:]
    parts.append((last["line_num"] + last["num_lines"] - 1, last["last"]))
    line = np.concatenate([np.repeat(num, 11) for num, _ in parts]).astype(np.float64) - 1.0
    ties = np.concatenate([t for _, t in parts])

    def flat(key: str, scale: float = 1.0) -> NDArray[np.float64]:
        return ties[key].astype(np.float64).ravel() * scale

    return GeolocationGrid(
        line=line,
        column=flat("samp_numbers") - 1.0,
        slant_column=slant_column(flat("samp_numbers") - 1.0),
        lat_deg=flat("lats", 1e-6),
        lon_deg=flat("longs", 1e-6),
        incidence_deg=flat("angles"),
        slant_range_time_ns=flat("slant_range_times"),
    )
