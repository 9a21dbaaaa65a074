"""Reader of the L0 pass archive: the contract between the station and the processing centre.

The layout is documented in ``docs/l0.md``. :func:`read_l0` checks, before handing
anything over, that the file is an HDF5 L0 archive of a version it knows, that every
dataset the processing needs is there, and that their shapes agree with each other and with
the root attributes; anything else is an :class:`~levels.errors.L0Error` that says what is
wrong. A truncated file fails to open and is reported as such.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import h5py
import numpy as np
from numpy.typing import NDArray

from levels.errors import L0Error
from levels.geometry.ephemeris import Ephemeris
from levels.geometry.frames import REFERENCE_VELOCITIES
from levels.geometry.sensor import LookAngleTable
from levels.geometry.times import Epoch
from levels.hdf5 import ATTRS_DIGEST, check_attrs_digest, damage_as, hdf5_damage

__all__ = [
    "L0_BAND_DATASETS",
    "L0_DATASETS",
    "L0_FORMAT",
    "L0_VERSION",
    "L0Archive",
    "L0Band",
    "L0Field",
    "L0Rows",
    "l0_scenario",
    "pixel_mask",
    "read_l0",
]

L0_FORMAT = "SPOT-L0"
L0_VERSION = 1


def pixel_mask(
    valid: NDArray[np.bool_], segment_first_detector: NDArray[np.int64], n_detectors: int
) -> NDArray[np.bool_]:
    """A (lines, segments) validity mask expanded to every pixel (lines, detectors), in C
    order (``valid[:, seg]`` comes out in Fortran order: every pass over it by lines then
    paid a transposition, 0.4 s for a full P scene)."""
    seg = np.searchsorted(segment_first_detector, np.arange(n_detectors), side="right") - 1
    return np.take(valid, seg, axis=1)


@dataclass(frozen=True)
class L0Rows:
    """A band's counts left in the archive, read by rows when sliced (``rows[a:b]``): what
    a scene task holds instead of the whole pass (:func:`read_l0` with ``lazy=True``). It
    names the file and the dataset only, so it travels to another process as a few bytes;
    the file is opened for each read, and a damaged chunk is an :class:`L0Error`."""

    path: Path
    dataset: str
    shape: tuple[int, int]
    dtype: np.dtype = field(default=np.dtype(np.uint8))

    @property
    def ndim(self) -> int:
        return 2

    def __getitem__(self, rows: slice) -> NDArray[np.uint8]:
        if not isinstance(rows, slice):
            raise TypeError(f"L0 counts are read by rows: a slice, not {rows!r}")
        with damage_as(L0Error, self.path):
            try:
                with h5py.File(self.path, "r") as f:
                    return f[self.dataset][rows]
            except (OSError, RuntimeError) as exc:
                raise L0Error(
                    f"{self.path}: dataset '{self.dataset}' rows {rows.start}:{rows.stop} "
                    f"cannot be read: {hdf5_damage(exc)}"
                ) from None

    def __array__(self, dtype: Any = None, copy: Any = None) -> NDArray[Any]:
        a = self[:]
        return a if dtype is None else a.astype(dtype)


@dataclass(frozen=True, eq=False)
class L0Band:
    """One band of the pass: counts (lines, detectors; :class:`L0Rows` when read lazily),
    segment validity (lines, segments), the nominal look-angle table and the calibration
    table."""

    name: str
    counts: NDArray[np.uint8] | L0Rows
    valid: NDArray[np.bool_]
    look: LookAngleTable
    gain: NDArray[np.float64]
    offset_counts: NDArray[np.float64]
    segment_first_detector: NDArray[np.int64]

    def pixel_valid(self) -> NDArray[np.bool_]:
        """The segment mask expanded to every pixel (lines, detectors)."""
        return self.pixel_valid_rows(slice(None))

    def pixel_valid_rows(self, rows: slice) -> NDArray[np.bool_]:
        """The segment mask of ``rows`` expanded to every pixel (rows, detectors)."""
        return pixel_mask(self.valid[rows], self.segment_first_detector, self.counts.shape[1])

    @property
    def line_valid(self) -> NDArray[np.bool_]:
        """Lines whose every segment arrived."""
        return np.asarray(self.valid.all(axis=1))


@dataclass(frozen=True, eq=False)
class L0Archive:
    """An L0 pass archive in memory (times in s since ``epoch``), its counts too unless
    read lazily (:class:`L0Rows`)."""

    path: Path
    epoch: Epoch
    hrv: int
    mode: str
    mirror_step: int
    twin: bool
    bands: dict[str, L0Band]
    line_counter: NDArray[np.int64]
    line_t_s: NDArray[np.float64]
    line_period_s: float
    aux_t_s: NDArray[np.float64]
    aux_line_counter: NDArray[np.int64]
    gyro_rates_rad_per_s: NDArray[np.float64]
    ephemeris: Ephemeris
    decode: dict = field(default_factory=dict)
    attrs: dict = field(default_factory=dict)

    @property
    def reference_velocity(self) -> str:
        """The velocity the ephemeris carries, which the attitude's orbital frame follows:
        "inertial" (SPOT 1–4) or "earth_fixed" (SPOT 5); the reader says "earth_fixed" for
        archives that do not say (the emulator's convention before it was recorded)."""
        return self.ephemeris.reference_velocity or "earth_fixed"

    @property
    def provenance(self) -> dict[str, object]:
        """What the station recorded of where the pass came from (scenario, seed …)."""
        try:
            prov = json.loads(str(self.attrs.get("provenance", "{}")))
        except json.JSONDecodeError:
            raise L0Error(f"{self.path}: root attribute 'provenance' is not JSON") from None
        return prov if isinstance(prov, dict) else {}

    @property
    def scene_cut(self) -> dict[str, int]:
        """How the station that recorded the pass cut it into scenes (``scene_lines``,
        ``overlap_lines``; 0 lines: as many as detectors), or {} if it did not say."""
        try:
            cut = json.loads(str(self.attrs.get("scene_cut", "{}")))
        except json.JSONDecodeError:
            raise L0Error(f"{self.path}: root attribute 'scene_cut' is not JSON") from None
        if not isinstance(cut, dict):
            return {}
        return {k: int(cut[k]) for k in ("scene_lines", "overlap_lines") if k in cut}

    @property
    def n_lines(self) -> int:
        return int(self.line_counter.size)

    @property
    def n_columns(self) -> int:
        """Detectors of the first band (the columns control points are measured in)."""
        return int(next(iter(self.bands.values())).counts.shape[1])


@dataclass(frozen=True)
class L0Field:
    """One dataset of the L0 archive: its rank, CF units and meaning, and whether a reader
    needs it (the others are the receiver's records, for people and ``station inspect``)."""

    ndim: int
    units: str
    long_name: str
    required: bool = True


#: Every dataset of an L0 archive but the bands' (``docs/l0.md``): written by the station's
#: recorder through this table, checked by :func:`read_l0` against it.
L0_DATASETS: dict[str, L0Field] = {
    "bands/segment_first_detector": L0Field(
        1, "1", "first detector of each image segment (one packet per band, line, segment)"
    ),
    "lines/line_counter": L0Field(1, "1", "instrument line counter"),
    "lines/t_s": L0Field(1, "s", "line time, s since epoch_utc (fitted)"),
    "aux/time_ms": L0Field(
        1, "ms", "time code of the gyro sample, ms since 1950-01-01 (CNES day 0)", False
    ),
    "aux/t_s": L0Field(1, "s", "time code, s since epoch_utc"),
    "aux/line_counter": L0Field(1, "1", "first line starting at or after the time code"),
    "aux/line_time_ms": L0Field(
        1, "ms", "time code latched at that line's start, ms since 1950-01-01", False
    ),
    "aux/gyro_rates_rad_per_s": L0Field(2, "rad s-1", "gyro rates about roll, pitch, yaw"),
    "aux/mirror_step": L0Field(1, "1", "mirror step", False),
    "aux/status": L0Field(1, "1", "bit 0 imaging, bit 1 twin configuration", False),
    "ephemeris/t_s": L0Field(1, "s", "bulletin time, s since epoch_utc"),
    "ephemeris/r_ecef_m": L0Field(2, "m", "position, ECEF"),
    "ephemeris/v_ecef_m_per_s": L0Field(2, "m s-1", "velocity, ECEF"),
    "decode/frames/bit_offset": L0Field(1, "bit", "start of the CADU in the recording", False),
    "decode/frames/status": L0Field(1, "1", "index into status_names", False),
    "decode/frames/vc": L0Field(1, "1", "virtual channel (−1: unknown)", False),
    "decode/frames/count": L0Field(1, "1", "unwrapped frame count (−1: unknown)", False),
    "decode/frames/symbols_corrected": L0Field(1, "1", "Reed–Solomon symbols corrected", False),
}
#: The datasets of each band, under ``bands/<band>/`` (``{band}`` in a meaning is its name).
L0_BAND_DATASETS: dict[str, L0Field] = {
    "counts": L0Field(2, "1", "raw counts of band {band}"),
    "valid": L0Field(2, "1", "segment received complete (per line, segment)"),
    "look_angles/column": L0Field(1, "1", "detector column of each entry"),
    "look_angles/psi_x_rad": L0Field(1, "rad", "nominal along-track angle"),
    "look_angles/psi_y_rad": L0Field(1, "rad", "nominal across-track angle"),
    "calibration/gain": L0Field(1, "1", "relative gain of each detector (table)"),
    "calibration/offset_counts": L0Field(1, "1", "dark offset of each detector (table), counts"),
}
_REQUIRED = {name: f.ndim for name, f in L0_DATASETS.items() if f.required}
_BAND = {name: f.ndim for name, f in L0_BAND_DATASETS.items() if f.required}


def _dataset(f: h5py.File, name: str, where: Path) -> h5py.Dataset:
    if name not in f or not isinstance(f[name], h5py.Dataset):
        raise L0Error(f"{where}: dataset '{name}' is missing; not a complete L0 archive")
    return f[name]


def _get(f: h5py.File, name: str, ndim: int, where: Path) -> np.ndarray:
    ds = _dataset(f, name, where)
    try:
        data = ds[()]
    except (OSError, RuntimeError) as exc:  # a chunk cut off or damaged
        raise L0Error(f"{where}: dataset '{name}' cannot be read: {hdf5_damage(exc)}") from None
    if np.ndim(data) != ndim:
        raise L0Error(f"{where}: dataset '{name}' has {np.ndim(data)} dimensions, expected {ndim}")
    return data


def _need(cond: bool, where: Path, what: str) -> None:
    if not cond:
        raise L0Error(f"{where}: inconsistent L0 archive: {what}")


def read_l0(path: str | Path, *, lazy: bool = False) -> L0Archive:
    """Read and check an L0 pass archive (module docstring).

    With ``lazy``, the counts stay in the file (:class:`L0Rows`: their shape and type are
    checked, the rows are read when a scene needs them): a whole pass is 2.7 GB of counts
    per band, and a scene task holds only its own. A damaged chunk of counts is then found
    when its scene is made, not here."""
    where = Path(path)
    with damage_as(L0Error, where):
        return _read_l0(where, lazy)


def l0_scenario(path: str | Path) -> str | None:
    """The scenario an L0 archive was recorded from (its ``scenario`` attribute), read from
    its header alone; None for a file that is not an L0 archive."""
    try:
        with h5py.File(path, "r") as f:
            if f.attrs.get("format") != L0_FORMAT:
                return None
            name = f.attrs.get("scenario")
    except OSError:
        return None
    return str(name) if name is not None else None


def _counts(f: h5py.File, name: str, where: Path, lazy: bool) -> NDArray[np.uint8] | L0Rows:
    if not lazy:
        return _get(f, name, 2, where)
    ds = _dataset(f, name, where)
    if ds.ndim != 2 or ds.dtype != np.uint8:
        raise L0Error(
            f"{where}: dataset '{name}' is {ds.dtype} in {ds.ndim} dimensions, expected uint8 in 2"
        )
    return L0Rows(where, name, (int(ds.shape[0]), int(ds.shape[1])))


def _read_l0(where: Path, lazy: bool) -> L0Archive:
    if not where.is_file():
        raise L0Error(f"{where}: no such L0 file")
    try:
        f = h5py.File(where, "r")
    except OSError as exc:
        raise L0Error(f"{where}: not a readable HDF5 file ({exc}); is it truncated?") from None
    with f:
        attrs = dict(f.attrs)
        attrs.pop(ATTRS_DIGEST, None)
        _check_header(attrs, where)
        d = {name: _get(f, name, ndim, where) for name, ndim in _REQUIRED.items()}
        n_lines, n_det = int(attrs["n_lines"]), int(attrs["n_detectors"])
        seg = d["bands/segment_first_detector"].astype(np.int64)
        _check_pass_datasets(d, seg, n_lines, n_det, where)
        try:
            names = json.loads(attrs["band_names"])
        except (TypeError, ValueError):
            raise L0Error(f"{where}: band_names is not a JSON list") from None
        bands = {name: _read_band(f, name, where, lazy, seg, n_lines, n_det) for name in names}
        decode = _read_decode(f)
        t_attrs = dict(f["lines/t_s"].attrs)
        ref_v = str(f["ephemeris"].attrs.get("reference_velocity", "earth_fixed"))
        _need(
            ref_v in REFERENCE_VELOCITIES,
            where,
            f"ephemeris reference_velocity {ref_v!r} is not one of {REFERENCE_VELOCITIES}",
        )
        try:  # last: a missing part is named above; archives before the digest have none
            check_attrs_digest(f, required=False)
        except ValueError as exc:
            raise L0Error(f"{where}: {exc}") from None
    return _archive(where, attrs, d, bands, decode, t_attrs, ref_v)


def _check_header(attrs: dict[str, Any], where: Path) -> None:
    """The root attributes: an L0 archive of the version this reader knows, complete."""
    if attrs.get("format") != L0_FORMAT:
        raise L0Error(
            f"{where}: format attribute is {attrs.get('format')!r}, "
            f"expected {L0_FORMAT!r}; not an L0 archive"
        )
    if int(attrs.get("format_version", -1)) != L0_VERSION:
        raise L0Error(
            f"{where}: L0 format version {attrs.get('format_version')!r}; "
            f"this reader knows version {L0_VERSION}"
        )
    for key in (
        "epoch_utc",
        "hrv",
        "mode",
        "mirror_step",
        "twin",
        "n_lines",
        "n_detectors",
        "band_names",
    ):
        _need(key in attrs, where, f"root attribute '{key}' is missing")


def _check_pass_datasets(
    d: dict[str, np.ndarray], seg: np.ndarray, n_lines: int, n_det: int, where: Path
) -> None:
    """The pass's datasets agree with each other and with the root attributes."""
    _need(
        bool(seg.size >= 1 and seg[0] == 0 and np.all(np.diff(seg) > 0) and seg[-1] < n_det),
        where,
        "segment_first_detector is not increasing from 0",
    )
    _need(
        d["lines/line_counter"].shape == (n_lines,),
        where,
        f"lines/line_counter has {d['lines/line_counter'].shape[0]} entries, n_lines = {n_lines}",
    )
    _need(d["lines/t_s"].shape == (n_lines,), where, "lines/t_s does not match n_lines")
    _need(
        d["aux/gyro_rates_rad_per_s"].shape == (d["aux/t_s"].size, 3),
        where,
        "aux/gyro_rates_rad_per_s is not (records, 3)",
    )
    n_eph = d["ephemeris/t_s"].size
    _need(
        d["ephemeris/r_ecef_m"].shape == (n_eph, 3)
        and d["ephemeris/v_ecef_m_per_s"].shape == (n_eph, 3),
        where,
        "ephemeris arrays are not (points, 3) with one time each",
    )


def _read_band(
    f: h5py.File, name: str, where: Path, lazy: bool, seg: np.ndarray, n_lines: int, n_det: int
) -> L0Band:
    """One band: its counts (read by rows when ``lazy``), segment mask, look angles and
    calibration, checked against the pass's size."""
    b: dict[str, Any] = {
        k: _get(f, f"bands/{name}/{k}", nd, where) for k, nd in _BAND.items() if k != "counts"
    }
    b["counts"] = _counts(f, f"bands/{name}/counts", where, lazy)
    _need(
        b["counts"].shape == (n_lines, n_det),
        where,
        f"bands/{name}/counts is {b['counts'].shape}, expected {(n_lines, n_det)}",
    )
    _need(
        b["valid"].shape == (n_lines, seg.size),
        where,
        f"bands/{name}/valid is {b['valid'].shape}, expected {(n_lines, seg.size)}",
    )
    look = LookAngleTable(
        b["look_angles/column"],
        b["look_angles/psi_x_rad"],
        b["look_angles/psi_y_rad"],
        int(f[f"bands/{name}/look_angles"].attrs["n_columns"]),
    )
    _need(
        b["calibration/gain"].shape == (n_det,),
        where,
        f"bands/{name}/calibration/gain does not have {n_det} entries",
    )
    return L0Band(
        name,
        b["counts"],
        b["valid"].astype(bool),
        look,
        b["calibration/gain"],
        b["calibration/offset_counts"],
        seg,
    )


def _read_decode(f: h5py.File) -> dict[str, Any]:
    """The receiver's decoding statistics, as recorded (none in an archive without)."""
    if "decode" not in f:
        return {}
    dec = f["decode"]
    decode = {
        k: (json.loads(v) if k in ("packets", "status_counts", "status_names") else v)
        for k, v in dec.attrs.items()
    }
    if "channels" in dec:
        decode["channels"] = {
            k: {a: v.item() if hasattr(v, "item") else v for a, v in g.attrs.items()}
            for k, g in dec["channels"].items()
        }
    return decode


def _archive(
    where: Path,
    attrs: dict[str, Any],
    d: dict[str, np.ndarray],
    bands: dict[str, L0Band],
    decode: dict[str, object],
    t_attrs: dict[str, Any],
    ref_v: str,
) -> L0Archive:
    """The archive from what was read and checked."""
    try:
        epoch = Epoch(np.datetime64(str(attrs["epoch_utc"]), "ns"), name="00:00 UTC, pass day")
        ephemeris = Ephemeris(
            d["ephemeris/t_s"],
            d["ephemeris/r_ecef_m"],
            d["ephemeris/v_ecef_m_per_s"],
            reference_velocity=ref_v,
        )
    except ValueError as exc:
        raise L0Error(f"{where}: {exc}") from None
    return L0Archive(
        path=where,
        epoch=epoch,
        hrv=int(attrs["hrv"]),
        mode=str(attrs["mode"]),
        mirror_step=int(attrs["mirror_step"]),
        twin=bool(attrs["twin"]),
        bands=bands,
        line_counter=d["lines/line_counter"].astype(np.int64),
        line_t_s=d["lines/t_s"],
        line_period_s=float(t_attrs.get("line_period_s", np.nan)),
        aux_t_s=d["aux/t_s"],
        aux_line_counter=d["aux/line_counter"].astype(np.int64),
        gyro_rates_rad_per_s=d["aux/gyro_rates_rad_per_s"],
        ephemeris=ephemeris,
        decode=decode,
        attrs={k: (v.item() if hasattr(v, "item") else v) for k, v in attrs.items()},
    )
