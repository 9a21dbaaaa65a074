"""The recorder: a decoded pass and what came with it → the L0 pass archive (HDF5).

The layout is the contract between the station and the processing centre, documented in
``docs/l0.md`` and read back by :func:`levels.readers.l0.read_l0`. The file is written
through :func:`levels.files.atomic_path` (a temporary name beside the target, renamed into
place once complete), so that a reader never sees half an archive.
Nothing depends on the clock: the same pass gives the same bytes of data.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import h5py
import numpy as np
from numpy.typing import NDArray

from levels.geometry.ephemeris import Ephemeris
from levels.geometry.sensor import LookAngleTable
from levels.hdf5 import checksummed, deflated_dataset, new_hdf5_on_disk
from levels.readers.l0 import L0_BAND_DATASETS, L0_DATASETS, L0_FORMAT, L0_VERSION, L0Field
from station import __version__
from station.srrs.assembler import SpooledColumn
from station.srrs.receiver import STATUS_NAMES, DecodedPass

__all__ = ["BandAncillary", "write_l0"]

_CHUNK_LINES = 256


@dataclass(frozen=True, eq=False)
class BandAncillary:
    """What the station is handed for one band besides telemetry: the nominal look-angle
    table and the calibration table (gains, dark offsets in counts), per detector."""

    name: str
    look: LookAngleTable
    gain: NDArray[np.float64]
    offset_counts: NDArray[np.float64]


def _described(ds: h5py.Dataset, units: str, long_name: str) -> h5py.Dataset:
    ds.attrs["units"] = units
    ds.attrs["long_name"] = long_name
    return ds


def _field(group: h5py.Group, name: str) -> L0Field:
    """The L0 format's entry for dataset ``name`` of ``group`` (the reader's table)."""
    path = f"{group.name.strip('/')}/{name}"
    if path in L0_DATASETS:
        return L0_DATASETS[path]
    _, band, rest = path.split("/", 2)  # bands/<band>/<dataset>
    entry = L0_BAND_DATASETS[rest]
    return replace(entry, long_name=entry.long_name.format(band=band))


def _dataset(
    group: h5py.Group, name: str, data: np.ndarray | SpooledColumn, **kwargs: Any
) -> h5py.Dataset:
    """Dataset ``name`` of ``group``, checksummed, described as the L0 format's table says;
    a front end's spooled column written a block of chunks at a time (the same bytes)."""
    entry = _field(group, name)
    if isinstance(data, SpooledColumn):
        opts = {**({"fletcher32": True} if data.size else {}), **kwargs}
        ds = group.create_dataset(name, shape=data.shape, dtype=data.dtype, **opts)
        step = (ds.chunks or data.shape)[0] * max(1, (1 << 16) // (ds.chunks or data.shape)[0])
        for a in range(0, data.size, step):
            ds[a : a + step] = data[a : a + step]
    else:
        ds = group.create_dataset(name, data=data, **{**checksummed(data), **kwargs})
    return _described(ds, entry.units, entry.long_name)


def write_l0(
    path: str | Path,
    decoded: DecodedPass,
    bulletins: Ephemeris,
    bulletin_epoch_utc: np.datetime64,
    ancillary: list[BandAncillary],
    scenario_name: str = "",
    provenance: dict | None = None,
    scene_cut: dict[str, int] | None = None,
    live: dict[str, object] | None = None,
) -> Path:
    """Write the L0 archive of a pass atomically; returns the path written.

    ``live``: the archive of a pass still arriving (or cut) at a front end
    (:mod:`station.live.frontend`), what it holds so far: kept as the ``live`` attribute
    (JSON); a whole pass's archive has none.

    ``scene_cut``: how the station cuts the pass into scenes (``scene_lines``,
    ``overlap_lines``), which a reprocessing takes unless told otherwise.

    ``bulletins`` carry times in seconds since ``bulletin_epoch_utc``; they are stored on
    the archive's own epoch (00:00 UTC of the pass day, ``decoded.epoch_utc``), with the
    velocity they carry (``Ephemeris.reference_velocity``: inertial for SPOT 1–4,
    Earth-fixed for SPOT 5; ``docs/l0.md``).
    """
    path = Path(path)
    names = [a.name for a in ancillary]
    if len(names) != len(decoded.images):
        raise ValueError(f"{len(decoded.images)} bands decoded but ancillary for {names}")
    shift_s = (
        float(
            (
                np.asarray(bulletin_epoch_utc).astype("datetime64[ns]")
                - np.asarray(decoded.epoch_utc).astype("datetime64[ns]")
            ).astype(np.int64)
        )
        / 1e9
    )
    # written straight to disk (not built in memory, twice its size, as the products are):
    # a whole pass's archive is gigabytes; its room checked first, an upper bound of it
    need = (
        sum(int(np.prod(img.shape)) for img in decoded.images)
        + 40 * int(decoded.frame_status.size)
        + (16 << 20)
    )
    with new_hdf5_on_disk(path, need) as f:
        _write(f, decoded, bulletins, shift_s, ancillary, scenario_name, provenance or {})
        if scene_cut:
            f.attrs["scene_cut"] = json.dumps(scene_cut, sort_keys=True)
        if live is not None:
            f.attrs["live"] = json.dumps(live, sort_keys=True)
    return path


def _write(
    f: h5py.File,
    d: DecodedPass,
    bulletins: Ephemeris,
    shift_s: float,
    ancillary: list[BandAncillary],
    scenario_name: str,
    provenance: dict,
) -> None:
    n_lines, n_det = d.images[0].shape
    a = f.attrs
    a["format"] = L0_FORMAT
    a["format_version"] = L0_VERSION
    a["epoch_utc"] = str(np.asarray(d.epoch_utc).astype("datetime64[ms]"))
    a["hrv"] = d.hrv
    a["mode"] = d.mode
    a["mirror_step"] = d.mirror_step
    a["twin"] = d.twin
    a["first_line_counter"] = d.first_line_counter
    a["n_lines"] = n_lines
    a["n_detectors"] = n_det
    a["band_names"] = json.dumps([b.name for b in ancillary])
    a["scenario"] = scenario_name
    a["software"] = f"spot-station {__version__}"
    a["provenance"] = json.dumps(provenance, sort_keys=True)

    _write_bands(f.create_group("bands"), d, ancillary)

    lines = f.create_group("lines")
    _dataset(lines, "line_counter", d.line_counter)
    t = _dataset(lines, "t_s", d.line_t_s)
    t.attrs["line_period_s"] = d.line_period_s
    t.attrs["uncertainty_s"] = d.line_clock_uncertainty_s
    t.attrs["fit_records"] = int(d.aux.size)

    aux = f.create_group("aux")
    _dataset(aux, "time_ms", d.aux["time_ms"].astype(np.int64))
    _dataset(aux, "t_s", d.aux_t_s)
    _dataset(aux, "line_counter", d.aux["line"].astype(np.int64))
    _dataset(aux, "line_time_ms", d.aux["line_time_ms"].astype(np.int64))
    _dataset(aux, "gyro_rates_rad_per_s", d.gyro_rates_rad_per_s)
    _dataset(aux, "mirror_step", d.aux["mirror_step"].astype(np.int64))
    _dataset(aux, "status", d.aux["status"].astype(np.int64))

    eph = f.create_group("ephemeris")
    if bulletins.reference_velocity:
        eph.attrs["reference_velocity"] = bulletins.reference_velocity
    eph.attrs["source"] = "ephemeris bulletins handed to the station"
    _dataset(eph, "t_s", bulletins.t_s + shift_s)
    _dataset(eph, "r_ecef_m", bulletins.r_ecef_m)
    _dataset(eph, "v_ecef_m_per_s", bulletins.v_ecef_m_per_s)

    _write_decode(f.create_group("decode"), d)


def _write_bands(bands: h5py.Group, d: DecodedPass, ancillary: list[BandAncillary]) -> None:
    """Each band's counts (deflated, chunked by lines), valid segments, look angles and
    calibration."""
    n_lines, n_det = d.images[0].shape
    _dataset(bands, "segment_first_detector", d.segment_first_detector)
    chunks = (min(_CHUNK_LINES, n_lines), n_det)
    for anc, img, ok in zip(ancillary, d.images, d.valid, strict=True):
        g = bands.create_group(anc.name)
        # deflated by ISA-L on every core, as the products are: a full P scene in 0.2 s,
        # not h5py's 1.2 s through zlib on one (5 % larger)
        counts = deflated_dataset(g, "counts", img, chunks, shuffle=True)
        entry = _field(g, "counts")
        _described(counts, entry.units, entry.long_name)
        _dataset(g, "valid", ok, compression="gzip")
        look = g.create_group("look_angles")
        look.attrs["n_columns"] = anc.look.n_columns
        _dataset(look, "column", anc.look.column)
        _dataset(look, "psi_x_rad", anc.look.psi_x_rad)
        _dataset(look, "psi_y_rad", anc.look.psi_y_rad)
        cal = g.create_group("calibration")
        _dataset(cal, "gain", anc.gain)
        _dataset(cal, "offset_counts", anc.offset_counts)


def _write_decode(dec: h5py.Group, d: DecodedPass) -> None:
    """The decoder's account: its counts, each frame's status, each channel's ledger."""
    dec.attrs["status_names"] = json.dumps(list(STATUS_NAMES))
    dec.attrs["bits_in"] = d.bits_in
    dec.attrs["bits_searched"] = d.bits_searched
    dec.attrs["sync_losses"] = d.sync_losses
    dec.attrs["packets"] = json.dumps(d.packets, sort_keys=True)
    dec.attrs["status_counts"] = json.dumps(d.status_counts)
    fr = dec.create_group("frames")
    _dataset(fr, "bit_offset", d.frame_bit_offset)
    _dataset(fr, "status", d.frame_status)
    _dataset(fr, "vc", d.frame_vc)
    _dataset(fr, "count", d.frame_count)
    _dataset(fr, "symbols_corrected", d.frame_symbols_corrected)
    ch = dec.create_group("channels")
    for vc, acc in sorted(d.accounts.items()):
        g = ch.create_group(f"vc{vc:02d}")
        for k, v in acc.as_dict().items():
            g.attrs[k] = v
