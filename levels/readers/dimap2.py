"""Reader of SPOT 6/7 (and Pléiades) DIMAP v2 sensor scenes: ``DIM_*.XML`` and its RPCs.

A DIMAP v2 primary (sensor) product carries no physical model a user can rebuild (no look
angles per detector, ephemeris and attitude live in the strip's own file): its geometry is
the producer's RPC (``RPC_*.XML``, :func:`levels.readers.rpc.read_dimap2_rpc`), which the
producer fitted to its own rigorous model. So the scene's model here is that RPC, behind
the interface of the geometry core's pushbroom model (:class:`RpcModel`): ``station
locate`` checks its frame, its control points and writes it out as it does a SPOT 1–5
scene's.

Conventions of the files (Airbus DS, "SPOT 6 & 7 Imagery User Guide", DIMAP v2):
``Geoposition/Raster_CRS/PIXEL_ORIGIN`` 1 and ``PIXEL_ORIENTATION`` CENTER (rows and
columns 1-based at pixel centres; converted to the core's 0-based convention here, once);
the frame is ``Dataset_Content/Dataset_Extent``: four ``Vertex`` and a ``Center``, each
``LON``, ``LAT``, ``ROW``, ``COL`` and, in recent products, ``H`` (the height the producer
located it at). Where ``H`` is absent the frame is taken at the RPC's height offset, the
scene's mean height.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from levels.errors import DimapError, GeometryError
from levels.geo.rpc import Rpc
from levels.geometry.model import GroundPoints, ImagePoints
from levels.readers.bounded import MAX_METADATA_BYTES, read_capped

__all__ = ["Dimap2Scene", "RpcModel", "is_dimap2", "read_dimap2"]


def is_dimap2(path: str | Path) -> bool:
    """Whether ``path`` is a DIMAP v2 document (``Metadata_Identification`` with format
    version 2), read from its first few kilobytes."""
    try:
        with open(path, "rb") as f:
            head = f.read(8192)
    except OSError:
        return False
    return b"<Metadata_Identification>" in head and b'version="2' in head


@dataclass(frozen=True, eq=False)
class RpcModel:
    """An RPC behind the pushbroom model's interface (0-based lines and columns, radians):
    what ``station locate`` asks of a scene's model."""

    rpc: Rpc
    n_lines: int
    n_columns: int

    def image_to_ground(
        self, line: ArrayLike, column: ArrayLike, height_m: ArrayLike = 0.0
    ) -> GroundPoints:
        ln, col, h = (
            a.ravel()
            for a in np.broadcast_arrays(
                *(np.atleast_1d(np.asarray(x, dtype=np.float64)) for x in (line, column, height_m))
            )
        )
        lat, lon = self.rpc.ground_of(ln, col, h)
        ok = np.isfinite(lat) & np.isfinite(lon)
        return GroundPoints(np.radians(lat), np.radians(lon), h.copy(), ok)

    def ground_to_image(
        self,
        lat_rad: ArrayLike,
        lon_rad: ArrayLike,
        height_m: ArrayLike = 0.0,
        first_line: ArrayLike | None = None,
    ) -> ImagePoints:
        """``first_line`` (the rigorous model's starting guess) is not needed: the RPC's
        ground → image is direct."""
        line, col = self.rpc.image_of(np.degrees(lat_rad), np.degrees(lon_rad), height_m)
        line, col = np.atleast_1d(line).ravel(), np.atleast_1d(col).ravel()
        ok = np.isfinite(line) & np.isfinite(col)
        return ImagePoints(line, col, ok, np.zeros(line.shape, dtype=np.int64))


@dataclass(frozen=True, eq=False)
class Dimap2Scene:
    """What a DIMAP v2 sensor product says about its scene's geometry. Frame rows and
    columns as in the file (1-based); ``frame_h_m`` the height of each frame point (the
    file's ``H``, else the RPC's height offset)."""

    path: Path
    mission: str
    mission_index: str
    instrument: str
    instrument_index: str
    n_rows: int
    n_cols: int
    frame_row: NDArray[np.float64]  # 4 corners then the centre
    frame_col: NDArray[np.float64]
    frame_lat_deg: NDArray[np.float64]
    frame_lon_deg: NDArray[np.float64]
    frame_h_m: NDArray[np.float64]
    rpc: Rpc
    rpc_path: Path

    @property
    def name(self) -> str:
        return f"{self.mission} {self.mission_index} {self.instrument}".strip()

    def model(self, **_ignored: object) -> RpcModel:
        """The scene's model: the producer's RPC (attitude choices do not apply)."""
        return RpcModel(self.rpc, self.n_rows, self.n_cols)


def _need(root: ET.Element, path: str, source: Path) -> str:
    text = root.findtext(path)
    if text is None or not text.strip():
        raise DimapError(f"{source}: missing element {path}")
    return text.strip()


def _number(elem: ET.Element, tag: str, source: Path, where: str) -> float:
    text = _need(elem, tag, source)
    try:
        return float(text)
    except ValueError:
        raise DimapError(f"{source}: {where}/{tag} = {text!r} is not a number") from None


def _rpc_of(root: ET.Element, source: Path) -> tuple[Path, Rpc]:
    """The RPC file a DIMAP v2 document names (its last ``Rational_Function_Model``
    component) and its model."""
    from levels.readers.rpc import read_dimap2_rpc

    href = None
    for comp in root.iterfind(".//Rational_Function_Model/Component/COMPONENT_PATH"):
        href = comp.get("href")
    if not href:
        raise DimapError(
            f"{source}: no Geoposition_Models/Rational_Function_Model/Component/"
            "COMPONENT_PATH: the scene's RPC file is not named"
        )
    rpc_path = source.parent / href
    if not rpc_path.is_file():
        raise DimapError(f"{source}: its RPC file {rpc_path} is not there")
    try:
        return rpc_path, read_dimap2_rpc(rpc_path)
    except GeometryError as exc:
        raise DimapError(str(exc)) from None


def read_dimap2(path: str | Path) -> Dimap2Scene:
    """Read a DIMAP v2 ``DIM_*.XML`` and the ``RPC_*.XML`` it names.

    Raises
    ------
    DimapError
        Not a DIMAP v2 document, a needed element missing or not a number, the RPC file
        absent or not one; the message names the file and the element.
    """
    source = Path(path)
    data = read_capped(source, MAX_METADATA_BYTES, "DIMAP v2 DIM_*.XML", DimapError)
    try:
        root = ET.fromstring(data)
    except ET.ParseError as exc:
        raise DimapError(f"{source}: not an XML document ({exc})") from None
    fmt = root.find("Metadata_Identification/METADATA_FORMAT")
    if root.tag != "Dimap_Document" or fmt is None or not fmt.get("version", "").startswith("2"):
        raise DimapError(
            f"{source}: not a DIMAP v2 document (no Metadata_Identification/METADATA_FORMAT "
            'version="2…"): a SPOT 6/7 or Pléiades DIM_*.XML is expected'
        )
    origin = root.findtext("Geoposition/Raster_CRS/PIXEL_ORIGIN")
    if origin is not None and origin.strip() not in ("1", "1.0"):
        raise DimapError(f"{source}: PIXEL_ORIGIN {origin.strip()}: this reads 1-based scenes")
    n_rows = int(_number(root, "Raster_Data/Raster_Dimensions/NROWS", source, ""))
    n_cols = int(_number(root, "Raster_Data/Raster_Dimensions/NCOLS", source, ""))
    extent = root.find("Dataset_Content/Dataset_Extent")
    if extent is None:
        raise DimapError(f"{source}: missing element Dataset_Content/Dataset_Extent")
    points = [*extent.findall("Vertex"), *extent.findall("Center")]
    if len(points) != 5:
        raise DimapError(
            f"{source}: Dataset_Extent has {len(points)} Vertex and Center elements, "
            "expected 4 and 1"
        )
    frame = np.array(
        [
            [_number(p, k, source, f"Dataset_Extent/{p.tag}") for k in ("ROW", "COL", "LAT", "LON")]
            for p in points
        ]
    )
    rpc_path, rpc = _rpc_of(root, source)
    heights = np.array(
        [
            _number(p, "H", source, f"Dataset_Extent/{p.tag}")
            if (p.findtext("H") or "").strip()
            else rpc.height_off
            for p in points
        ]
    )
    strip = root.find("Dataset_Sources/Source_Identification/Strip_Source")

    def text(tag: str) -> str:
        return "" if strip is None else (strip.findtext(tag) or "").strip()

    return Dimap2Scene(
        path=source,
        mission=text("MISSION"),
        mission_index=text("MISSION_INDEX"),
        instrument=text("INSTRUMENT"),
        instrument_index=text("INSTRUMENT_INDEX"),
        n_rows=n_rows,
        n_cols=n_cols,
        frame_row=frame[:, 0],
        frame_col=frame[:, 1],
        frame_lat_deg=frame[:, 2],
        frame_lon_deg=frame[:, 3],
        frame_h_m=heights,
        rpc=rpc,
        rpc_path=rpc_path,
    )
