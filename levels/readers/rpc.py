"""RPCs as other producers write them: RPC00B read from GDAL's metadata, ``_RPC.TXT``,
``.RPB``, GeoTIFF RPC tags (any GDAL dataset) and SPOT 6/7 / Pléiades DIMAP v2
``RPC_*.XML``, into :class:`levels.geo.rpc.Rpc`.

Pixel origins, the one thing the formats disagree on (our :class:`~levels.geo.rpc.Rpc`
puts (line, sample) = (0, 0) at the centre of the first pixel):

- GDAL's ``RPC`` metadata domain, ``_RPC.TXT`` (GeoEye/Ikonos), ``.RPB`` (DigitalGlobe)
  and the GeoTIFF RPC tag follow RPC00B (NITF STDI-0002): (0, 0) is the centre of the
  first pixel; taken as they are. (GDAL's own pixel/line are half a pixel off: its
  transformer adds 0.5 to put (0, 0) at the first pixel's corner.)
- DIMAP v2 (``RPC_*.XML`` of SPOT 6/7 and Pléiades) counts from 1: the first pixel's
  centre is (1, 1), so ``LINE_OFF`` and ``SAMP_OFF`` are one less here (as GDAL's DIMAP
  reader and s2p do). Its ground → image model is the one named ``Inverse_Model``; the
  validity box (``RFM_Validity``) holds the offsets and scales.

The fit's error is not in these files (``ERR_BIAS``/``ERR_RAND`` are a producer's claims
in metres): ``fit_error_px`` is left empty.
"""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from collections.abc import Mapping
from dataclasses import replace
from pathlib import Path

import numpy as np

from levels.errors import GeometryError
from levels.geo.rpc import Rpc
from levels.readers.bounded import MAX_METADATA_BYTES, read_capped

__all__ = [
    "read_dimap2_rpc",
    "read_gdal_rpc",
    "read_rpb",
    "read_rpc",
    "read_rpc_txt",
    "rpc_from_gdal",
]

_SCALARS = {
    "LINE_OFF": "line_off",
    "SAMP_OFF": "samp_off",
    "LAT_OFF": "lat_off",
    "LONG_OFF": "lon_off",
    "HEIGHT_OFF": "height_off",
    "LINE_SCALE": "line_scale",
    "SAMP_SCALE": "samp_scale",
    "LAT_SCALE": "lat_scale",
    "LONG_SCALE": "lon_scale",
    "HEIGHT_SCALE": "height_scale",
}
_SCALE_NAMES = tuple(n for k, n in _SCALARS.items() if k.endswith("SCALE"))
_COEFFS = {
    "LINE_NUM_COEFF": "line_num",
    "LINE_DEN_COEFF": "line_den",
    "SAMP_NUM_COEFF": "samp_num",
    "SAMP_DEN_COEFF": "samp_den",
}
#: DigitalGlobe's ``.RPB`` keywords for the same values.
_RPB = {
    "lineOffset": "LINE_OFF",
    "sampOffset": "SAMP_OFF",
    "latOffset": "LAT_OFF",
    "longOffset": "LONG_OFF",
    "heightOffset": "HEIGHT_OFF",
    "lineScale": "LINE_SCALE",
    "sampScale": "SAMP_SCALE",
    "latScale": "LAT_SCALE",
    "longScale": "LONG_SCALE",
    "heightScale": "HEIGHT_SCALE",
    "lineNumCoef": "LINE_NUM_COEFF",
    "lineDenCoef": "LINE_DEN_COEFF",
    "sampNumCoef": "SAMP_NUM_COEFF",
    "sampDenCoef": "SAMP_DEN_COEFF",
}


def rpc_from_gdal(md: Mapping[str, str], where: str = "RPC metadata") -> Rpc:
    """An RPC from GDAL's ``RPC`` metadata domain (RPC00B pixel origin, as ours):
    ten scalars and four lists of 20 coefficients (space-separated);
    :class:`GeometryError` naming what is missing or not a number."""
    fields: dict[str, object] = {}
    try:
        for key, name in _SCALARS.items():
            fields[name] = float(str(md[key]).split()[0])
        for key, name in _COEFFS.items():
            c = np.array(str(md[key]).replace(",", " ").split(), dtype=np.float64)
            if c.size != 20:
                raise GeometryError(f"{where}: {key} has {c.size} coefficients, not 20")
            fields[name] = c
    except KeyError as exc:
        raise GeometryError(f"{where}: {exc.args[0]} is missing; not an RPC00B") from None
    except (ValueError, IndexError):
        raise GeometryError(f"{where}: a value is not a number") from None
    scalars = np.array([fields[n] for n in _SCALARS.values()], dtype=np.float64)
    if not np.all(np.isfinite(scalars)) or 0.0 in [fields[n] for n in _SCALE_NAMES]:
        raise GeometryError(f"{where}: offsets and scales must be finite, scales non-zero")
    return Rpc(**fields, fit_error_px={})  # type: ignore[arg-type]


def read_rpc_txt(path: str | Path) -> Rpc:
    """An ``_RPC.TXT`` sidecar (``KEY: value [unit]``, coefficients ``LINE_NUM_COEFF_1``
    to ``_20``), as :meth:`Rpc.rpc_txt` and GeoEye write it."""
    p = Path(path)
    md: dict[str, str] = {}
    coeffs: dict[str, list[tuple[int, str]]] = {k: [] for k in _COEFFS}
    for line in _text(p).splitlines():
        key, sep, value = line.partition(":")
        if not sep or not value.split():
            continue
        key = key.strip().upper()
        m = re.fullmatch(r"(LINE|SAMP)_(NUM|DEN)_COEFF_(\d+)", key)
        if m:
            coeffs[f"{m[1]}_{m[2]}_COEFF"].append((int(m[3]), value.split()[0]))
        else:
            md[key] = value.split()[0]
    for key, items in coeffs.items():
        if items:
            md[key] = " ".join(v for _, v in sorted(items))
    return rpc_from_gdal(md, str(p))


def read_rpb(path: str | Path) -> Rpc:
    """A DigitalGlobe ``.RPB`` keyword file (``lineOffset = …;``, ``lineNumCoef = (…);``)."""
    p = Path(path)
    text = _text(p)
    md: dict[str, str] = {}
    for key, gdal in _RPB.items():
        m = re.search(rf"\b{key}\s*=\s*\(?([^;]*?)\)?\s*;", text, re.DOTALL)
        if m:
            md[gdal] = " ".join(m[1].replace(",", " ").split())
    return rpc_from_gdal(md, str(p))


def read_dimap2_rpc(path: str | Path) -> Rpc:
    """A DIMAP v2 ``RPC_*.XML`` (SPOT 6/7, Pléiades): the ``Inverse_Model`` (ground →
    image) coefficients and the ``RFM_Validity`` offsets and scales, the 1-based pixel
    origin taken back to ours (module docstring)."""
    p = Path(path)
    try:
        root = ET.fromstring(_text(p))
    except ET.ParseError as exc:
        raise GeometryError(f"{p}: not XML ({exc})") from None
    inverse = root.find(".//Inverse_Model")
    validity = root.find(".//RFM_Validity")
    if inverse is None or validity is None:
        raise GeometryError(
            f"{p}: no Inverse_Model and RFM_Validity: not a DIMAP v2 RPC file (RPC_*.XML)"
        )
    md: dict[str, str] = {}
    for key in _SCALARS:
        node = validity.find(f".//{key}")
        if node is not None and node.text:
            md[key] = node.text
    for key in _COEFFS:
        values = [inverse.findtext(f"{key}_{k}") for k in range(1, 21)]
        if all(v is not None for v in values):
            md[key] = " ".join(str(v) for v in values)
    rpc = rpc_from_gdal(md, str(p))
    return replace(rpc, line_off=rpc.line_off - 1.0, samp_off=rpc.samp_off - 1.0)


def read_gdal_rpc(spec: str | Path) -> Rpc:
    """The RPCs GDAL finds on a dataset (a GeoTIFF's RPC tags, a NITF, a product with its
    sidecar, ``HDF5:"f.h5"://P``): its ``RPC`` metadata domain."""
    import warnings

    import rasterio
    from rasterio.errors import RasterioIOError

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            with rasterio.open(str(spec)) as ds:
                rpcs = ds.rpcs
    except RasterioIOError as exc:
        raise GeometryError(f"{spec}: GDAL cannot open it ({exc})") from None
    if rpcs is None:
        raise GeometryError(f"{spec}: GDAL finds no RPCs on it")
    return rpc_from_gdal(rpcs.to_gdal(), str(spec))


def read_rpc(path: str | Path) -> Rpc:
    """RPCs from any of the files above, by their name: ``*_RPC.TXT`` or ``.txt``,
    ``.RPB``, ``RPC_*.XML`` (DIMAP v2), else what GDAL finds on the dataset."""
    p = Path(path)
    suffix = p.suffix.lower()
    if suffix == ".txt":
        return read_rpc_txt(p)
    if suffix == ".rpb":
        return read_rpb(p)
    if suffix == ".xml":
        return read_dimap2_rpc(p)
    return read_gdal_rpc(p)


def _text(p: Path) -> str:
    try:
        data = read_capped(p, MAX_METADATA_BYTES, "RPC file", GeometryError)
        return data.decode("utf-8", errors="replace")
    except FileNotFoundError:
        raise GeometryError(f"RPC file {p} not found") from None
    except IsADirectoryError:
        raise GeometryError(f"{p} is a directory, not an RPC file") from None
