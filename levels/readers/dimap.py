"""Reader of SPOT 1–5 level-1A DIMAP v1 metadata (``METADATA.DIM``).

It turns the XML into the geometry core's model objects: an :class:`~levels.geometry.ephemeris.
Ephemeris`, attitudes, a :class:`~levels.geometry.sensor.LookAngleTable` and a
:class:`~levels.geometry.model.LineClock`, exactly what the emulated station builds from its
own L0 data, so that a real scene and an emulated one are located by the same code.

Conventions of the files (SPOT Geometry Handbook S-NT-73-12-SI, and
``../shared/refdata/README.md``): rows and columns 1-based; a line's time is
``SCENE_CENTER_TIME + (row − SCENE_CENTER_LINE) · LINE_PERIOD`` (UTC); ``PSI_Y`` includes
the mirror; the Dataset_Frame corners lie on the ellipsoid (height 0). The reader converts
rows and columns to the 0-based convention of ``levels.geometry.model`` once, here.

Attitude: which one reproduces the producer's own scene location
    SPOT 5 files carry ``Corrected_Attitudes`` (star-tracker corrected yaw, pitch, roll):
    with them the frame corners are reproduced to centimetres. SPOT 1–4 files carry two
    absolute AOCS angle samples and gyro angular speeds every 0.125 s. Their frame corners
    are reproduced to 0.4–2.5 m with the *null* attitude, and are made worse by applying the
    AOCS angles, alone or carried on by the integrated rates (up to 24 m on the SPOT 4
    scene), or the rates integrated from a null attitude and zeroed at scene centre, INPE's
    rule (up to 10 m): the producer located SPOT 1–4 level-1A frames from the
    ephemeris and the look angles alone, the gyro data serving the relative (1B) geometry.
    Hence ``attitude="auto"`` selects the corrected attitude when present and otherwise,
    of the null attitude and INPE's integrated rates, the one that reproduces the file's
    own frame (:attr:`DimapScene.auto_attitude`): the null attitude for the real files, the
    rates for a scene this project wrote from an emulated product (they reproduce its
    attitude, ``levels.writers.dimap``); every other choice stays available.
"""

from __future__ import annotations

import io
import math
import xml.etree.ElementTree as ET
import zipfile
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path, PurePosixPath
from typing import IO, Literal

import numpy as np
from numpy.typing import NDArray

from levels.errors import DimapError, GeometryError
from levels.geometry.attitude import (
    Attitude,
    ConstantAttitude,
    SampledAttitude,
    integrate_rates,
)
from levels.geometry.ephemeris import Ephemeris
from levels.geometry.model import LineClock, PushbroomModel
from levels.geometry.sensor import LookAngleTable
from levels.geometry.times import Epoch, parse_utc
from levels.readers.bounded import MAX_METADATA_BYTES, read_capped, read_member, refuse_broken_zip

__all__ = [
    "MAX_DIMAP_SIDE",
    "AttitudeChoice",
    "BandCalibration",
    "DimapScene",
    "dimap_member",
    "read_dimap",
]

AttitudeChoice = Literal["auto", "corrected", "none", "aocs", "integrated", "integrated_zeroed"]
_ATTITUDE_CHOICES = ("auto", "corrected", "none", "aocs", "integrated", "integrated_zeroed")

_STRIP = "Data_Strip"
_EPHEMERIS_POINTS = f"{_STRIP}/Ephemeris/Points/Point"
_AOCS = f"{_STRIP}/Satellite_Attitudes/Raw_Attitudes/Aocs_Attitude"
_CORRECTED = f"{_STRIP}/Satellite_Attitudes/Corrected_Attitudes/Corrected_Attitude/Angles"
_TIME_STAMP = f"{_STRIP}/Sensor_Configuration/Time_Stamp"
_LOOK_ANGLES = f"{_STRIP}/Sensor_Configuration/Instrument_Look_Angles_List/Instrument_Look_Angles"
_MIRROR = f"{_STRIP}/Sensor_Configuration/Mirror_Position/STEP_COUNT"
_SOURCE = "Dataset_Sources/Source_Information/Scene_Source"
_CALIBRATION = f"{_STRIP}/Sensor_Calibration/Calibration/Band_Parameters"


@dataclass(frozen=True, eq=False)
class BandCalibration:
    """One band's radiometric calibration as a level-1A file gives it.

    ``physical_gain``: counts per unit of radiance (``Spectral_Band_Info/PHYSICAL_GAIN``,
    ``X = gain · L + bias``), ``physical_bias``; ``analog_gain``: the instrument's gain
    setting (``GAIN_ANALOG_VALUE``); ``detector_gain`` and ``dark_current``: each detector's
    relative gain ``G`` and dark signal (``Cells/Cell``), the table the 1A normalisation
    used; empty arrays when the file has none.
    """

    physical_gain: float | None
    physical_bias: float | None
    analog_gain: float | None
    detector_gain: NDArray[np.float64]
    dark_current: NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class DimapScene:
    """What a level-1A DIMAP file says about the geometry of its scene.

    Rows and columns of the frame are kept 1-based as in the file (``frame_row``,
    ``frame_col``); everything handed to the model is 0-based. Elements absent from the file
    are ``None`` (a frame-only file has no ephemeris); :meth:`model` says what it lacks.
    Angles are radians; ``frame_lat_deg``/``frame_lon_deg`` degrees as in the file.
    """

    path: Path
    mission: str
    mission_index: int | None
    instrument: str
    instrument_index: int | None
    sensor_code: str
    n_rows: int
    n_cols: int
    frame_row: NDArray[np.int64]
    frame_col: NDArray[np.int64]
    frame_lat_deg: NDArray[np.float64]
    frame_lon_deg: NDArray[np.float64]
    center_row: int
    center_col: int
    center_lat_deg: float
    center_lon_deg: float
    epoch: Epoch | None
    line_period_s: float | None
    scene_center_line: float | None
    scene_center_col: float | None
    ephemeris: Ephemeris | None
    aocs_attitude: SampledAttitude | None
    angular_speeds_t_s: NDArray[np.float64] | None
    angular_speeds_rad_per_s: NDArray[np.float64] | None
    corrected_attitude: SampledAttitude | None
    look_angles: dict[int, LookAngleTable]
    mirror_step: int | None
    calibration: dict[int, BandCalibration] = field(default_factory=dict)
    processing_level: str = "1A"
    image_file: str = "IMAGERY.TIF"
    n_bands: int = 1
    imaging_date: str = ""
    dataset_name: str = ""
    band_descriptions: dict[int, str] = field(default_factory=dict)

    @property
    def name(self) -> str:
        idx = "" if self.mission_index is None else str(self.mission_index)
        ins = "" if self.instrument_index is None else str(self.instrument_index)
        return f"{self.mission} {idx} {self.instrument}{ins} {self.sensor_code}".strip()

    def attitude(self, choice: AttitudeChoice = "auto") -> Attitude:
        """The attitude model of ``choice`` (see the module docstring for ``"auto"``).

        ``"corrected"``: SPOT 5 corrected attitudes; ``"none"``: null attitude; ``"aocs"``:
        the absolute AOCS samples interpolated; ``"integrated"``: gyro rates integrated
        from the first AOCS sample; ``"integrated_zeroed"``: rates integrated from a null
        attitude and zeroed at scene-centre time (INPE's rule, paper ``004_…`` §2.1).
        """
        if choice not in _ATTITUDE_CHOICES:
            raise DimapError(f"attitude choice {choice!r}: expected one of {_ATTITUDE_CHOICES}")
        if choice == "auto":
            choice = self.auto_attitude
        if choice == "none":
            return ConstantAttitude()
        if choice == "corrected":
            return self._need(self.corrected_attitude, "Corrected_Attitudes", choice)
        if choice == "aocs":
            return self._need(self.aocs_attitude, "Raw_Attitudes/Aocs_Attitude/Angles_List", choice)
        rates = self._need(self.angular_speeds_rad_per_s, "Angular_Speeds_List", choice)
        t = self.angular_speeds_t_s
        assert t is not None  # read with the rates
        if choice == "integrated":
            aocs = self._need(self.aocs_attitude, "Raw_Attitudes/Aocs_Attitude/Angles_List", choice)
            return integrate_rates(
                t, rates, start_t_s=float(aocs.t_s[0]), start_angles_rad=aocs.angles_rad_samples[0]
            )
        return integrate_rates(t, rates).zeroed_at(0.0)

    @cached_property
    def auto_attitude(self) -> AttitudeChoice:
        """What ``"auto"`` means for this file: the corrected attitude when it has one (SPOT
        5); otherwise, of the null attitude and the gyro rates integrated and zeroed at the
        scene centre (INPE's rule), the one whose model puts the file's own frame (corners
        and centre, on the ellipsoid) closer to where the producer says it is. Real SPOT 1–4
        scenes take the null attitude that way (0.5–2.5 m against 3–10 m: their producer
        located the frame without the gyros); a scene written from an emulated product
        takes the rates its writer made to reproduce the product's attitude (0 m)."""
        if self.corrected_attitude is not None:
            return "corrected"
        if self.angular_speeds_rad_per_s is None or self.epoch is None or not self.look_angles:
            return "none"
        none = float(np.max(self.frame_error_m("none")))
        rates = float(np.max(self.frame_error_m("integrated_zeroed")))
        return "integrated_zeroed" if rates < none else "none"

    def frame_error_m(self, attitude: AttitudeChoice = "auto") -> NDArray[np.float64]:
        """How far the model (with ``attitude``) puts the frame's four corners and centre,
        on the ellipsoid, from the file's coordinates (m, in the file's order)."""
        from pyproj import Geod

        rows = np.append(self.frame_row, self.center_row) - 1.0
        cols = np.append(self.frame_col, self.center_col) - 1.0
        g = self.model(attitude=attitude).image_to_ground(rows, cols, 0.0)
        lat = np.append(self.frame_lat_deg, self.center_lat_deg)
        lon = np.append(self.frame_lon_deg, self.center_lon_deg)
        _, _, dist = Geod(ellps="WGS84").inv(lon, lat, np.degrees(g.lon_rad), np.degrees(g.lat_rad))
        return np.where(g.ok, np.asarray(dist, dtype=np.float64), np.inf)

    def _need(self, value, element: str, what: str):
        if value is None:
            raise DimapError(f"{self.path}: no {element} element, needed for {what!r} attitude")
        return value

    def model(
        self, *, band: int | None = None, attitude: AttitudeChoice = "auto"
    ) -> PushbroomModel:
        """The rigorous model of the scene (band ``band``, default the first tabulated)."""
        missing = [
            name
            for name, value in (
                ("Ephemeris/Points", self.ephemeris),
                ("Sensor_Configuration/Time_Stamp", self.epoch),
                ("Instrument_Look_Angles", self.look_angles or None),
            )
            if value is None
        ]
        if missing:
            raise DimapError(
                f"{self.path}: cannot build a geometric model, missing {', '.join(missing)} "
                "(a frame-only DIMAP file has corners but no model)"
            )
        if band is None:
            band = min(self.look_angles)
        if band not in self.look_angles:
            raise DimapError(
                f"{self.path}: band {band} has no look angles; bands: {sorted(self.look_angles)}"
            )
        assert self.epoch is not None and self.ephemeris is not None
        assert self.scene_center_line is not None and self.line_period_s is not None
        clock = LineClock(0.0, self.scene_center_line - 1.0, self.line_period_s)
        return PushbroomModel(
            epoch=self.epoch,
            clock=clock,
            ephemeris=self.ephemeris,
            attitude=self.attitude(attitude),
            look_angles=self.look_angles[band],
            n_lines=self.n_rows,
        )


def _find(root: ET.Element, path: str, source: Path) -> ET.Element:
    elem = root.find(path)
    if elem is None:
        raise DimapError(f"{source}: missing element {path}")
    return elem


def _text(root: ET.Element, path: str, source: Path) -> str:
    text = _find(root, path, source).text
    if text is None or not text.strip():
        raise DimapError(f"{source}: element {path} is empty")
    return text.strip()


def _number(root: ET.Element, path: str, source: Path, kind: type = float):
    """The element's number, refused (naming it) unless finite: a DIMAP number never is
    ``nan`` or ``inf``, and one would travel into the model as NaN products."""
    text = _text(root, path, source)
    try:
        value = float(text)
    except ValueError:
        raise DimapError(f"{source}: element {path} = {text!r} is not a number") from None
    if not math.isfinite(value):
        raise DimapError(f"{source}: element {path} = {text!r} is not a finite number")
    return int(value) if kind is int else kind(text)


def _optional(root: ET.Element, path: str, kind: type = str, source: Path | None = None):
    """The element's text (``kind`` str) or number (:func:`_number`'s checks), None where
    the document has none."""
    text = root.findtext(path)
    if text is None or not text.strip():
        return None
    if kind is str:
        return text.strip()
    return _number(root, path, source or Path("METADATA.DIM"), kind)


def _frame_point(elem: ET.Element, where: str, source: Path) -> tuple[int, int, float, float]:
    try:
        return (
            _number(elem, "FRAME_ROW", source, int),
            _number(elem, "FRAME_COL", source, int),
            _number(elem, "FRAME_LAT", source),
            _number(elem, "FRAME_LON", source),
        )
    except DimapError as exc:
        raise DimapError(f"{exc} (in Dataset_Frame/{where})") from None


def _times(elems: list[ET.Element], tag: str, epoch: Epoch, where: str, source: Path) -> NDArray:
    try:
        return epoch.seconds(parse_utc([_text(e, tag, source) for e in elems]))
    except GeometryError as exc:
        raise DimapError(f"{source}: {where}: {exc}") from None


def _angles(elems: list[ET.Element], source: Path) -> NDArray[np.float64]:
    """(n, 3) roll, pitch, yaw from elements holding YAW, PITCH, ROLL."""
    return np.array(
        [[_number(e, k, source) for k in ("ROLL", "PITCH", "YAW")] for e in elems], dtype=np.float64
    )


def _dimap_v1_root(source: Path, stream: IO[bytes] | None = None) -> ET.Element:
    """The root of a SPOT 1–5 DIMAP v1 document (read from ``stream`` when given, a zip's
    member), refused in one line (naming the file) when it is not XML, not DIMAP, or DIMAP
    v2."""
    try:
        root = ET.parse(stream if stream is not None else source).getroot()
    except ET.ParseError as exc:
        raise DimapError(
            f"{source}: not an XML document ({exc}); expected a DIMAP METADATA.DIM"
        ) from None
    fmt = root.findtext("Metadata_Id/METADATA_FORMAT")
    v2 = root.find("Metadata_Identification/METADATA_FORMAT")
    if root.tag == "Dimap_Document" and v2 is not None:
        version = v2.get("version", "2")
        raise DimapError(
            f"{source}: DIMAP v{version} (SPOT 6/7, Pléiades), not the SPOT 1–5 DIMAP v1 this "
            "reads: levels.readers.dimap2.read_dimap2 reads it (its model is the RPC_*.XML "
            "it names), as station locate does"
        )
    if root.tag != "Dimap_Document":
        raise DimapError(
            f"{source}: not a DIMAP document (root <{root.tag}>, expected <Dimap_Document>)"
        )
    if (fmt or "").strip() != "DIMAP":
        raise DimapError(
            f"{source}: <Dimap_Document> without Metadata_Id/METADATA_FORMAT DIMAP "
            f"(found {fmt!r}): not a SPOT 1–5 DIMAP v1 METADATA.DIM"
        )
    return root


def read_dimap(path: str | Path) -> DimapScene:
    """Read a SPOT level-1A ``METADATA.DIM`` (DIMAP v1): the file itself, the scene
    directory holding it, or the zip SPOT World Heritage delivers (read in place,
    :func:`dimap_member`).

    Raises
    ------
    DimapError
        If the file is not XML, not a DIMAP document, lacks a needed element, or has
        inconsistent sizes; the message names the file and the element.
    FileNotFoundError
        If ``path`` does not exist.
    """
    source = Path(path)
    if source.is_dir():
        source = source / "METADATA.DIM"
        if not source.is_file():
            raise DimapError(f"{path}: a directory without METADATA.DIM: not a DIMAP scene")
    if zipfile.is_zipfile(source):
        member = dimap_member(source)
        data = read_member(source, member, MAX_METADATA_BYTES, "METADATA.DIM", DimapError)
        return _read(source / member, _dimap_v1_root(source / member, io.BytesIO(data)))
    refuse_broken_zip(source, DimapError)
    data = read_capped(source, MAX_METADATA_BYTES, "METADATA.DIM", DimapError)
    return _read(source, _dimap_v1_root(source, io.BytesIO(data)))


def dimap_member(zip_path: Path) -> str:
    """The ``METADATA.DIM`` inside a scene's zip (at any depth, as SWH's zips nest it in a
    scene folder): exactly one, or the zip is refused naming what it holds."""
    with zipfile.ZipFile(zip_path) as z:
        names = [n for n in z.namelist() if PurePosixPath(n).name.upper() == "METADATA.DIM"]
        if len(names) != 1:
            some = ", ".join(z.namelist()[:5]) or "nothing"
            raise DimapError(
                f"{zip_path}: a zip with {len(names)} METADATA.DIM (holds {some}…): expected "
                "one DIMAP scene, as SPOT World Heritage delivers it"
            )
    return names[0]


def _read(source: Path, root: ET.Element) -> DimapScene:
    """The scene of a parsed DIMAP v1 document (:func:`read_dimap`)."""
    n_cols = _number(root, "Raster_Dimensions/NCOLS", source, int)
    n_rows = _number(root, "Raster_Dimensions/NROWS", source, int)
    vertices = root.findall("Dataset_Frame/Vertex")
    if len(vertices) != 4:
        raise DimapError(f"{source}: Dataset_Frame has {len(vertices)} Vertex elements, expected 4")
    frame = np.array([_frame_point(v, f"Vertex[{i + 1}]", source) for i, v in enumerate(vertices)])
    center = _frame_point(_find(root, "Dataset_Frame/Scene_Center", source), "Scene_Center", source)

    epoch, line_period, center_line, center_col = _time_stamp(root, source)
    ephemeris = _ephemeris(root, epoch, source)
    aocs = speeds_t = speeds = corrected = None
    if epoch is not None:
        aocs, speeds_t, speeds, corrected = _attitudes(root, epoch, source)
    look_angles = {}
    for block in root.findall(_LOOK_ANGLES):
        band = _number(block, "BAND_INDEX", source, int)
        look_angles[band] = _look_angles(block, band, n_cols, source)
    _check_frame(source, n_rows, n_cols, np.vstack([frame, center]))

    return DimapScene(
        path=source,
        mission=(root.findtext(f"{_SOURCE}/MISSION") or "").strip(),
        mission_index=_optional(root, f"{_SOURCE}/MISSION_INDEX", int, source),
        instrument=(root.findtext(f"{_SOURCE}/INSTRUMENT") or "").strip(),
        instrument_index=_optional(root, f"{_SOURCE}/INSTRUMENT_INDEX", int, source),
        sensor_code=(root.findtext(f"{_SOURCE}/SENSOR_CODE") or "").strip(),
        n_rows=n_rows,
        n_cols=n_cols,
        frame_row=frame[:, 0].astype(np.int64),
        frame_col=frame[:, 1].astype(np.int64),
        frame_lat_deg=frame[:, 2],
        frame_lon_deg=frame[:, 3],
        center_row=int(center[0]),
        center_col=int(center[1]),
        center_lat_deg=center[2],
        center_lon_deg=center[3],
        epoch=epoch,
        line_period_s=line_period,
        scene_center_line=center_line,
        scene_center_col=center_col,
        ephemeris=ephemeris,
        aocs_attitude=aocs,
        angular_speeds_t_s=speeds_t,
        angular_speeds_rad_per_s=speeds,
        corrected_attitude=corrected,
        look_angles=look_angles,
        mirror_step=_optional(root, _MIRROR, int, source),
        calibration=_calibration(root, source),
        processing_level=(
            root.findtext("Data_Processing/PROCESSING_LEVEL")
            or root.findtext(f"{_SOURCE}/SCENE_PROCESSING_LEVEL")
            or ""
        ).strip(),
        image_file=_image_file(root),
        n_bands=_bands(root, source),
        imaging_date=(root.findtext(f"{_SOURCE}/IMAGING_DATE") or "").strip(),
        dataset_name=(root.findtext("Dataset_Id/DATASET_NAME") or "").strip(),
        band_descriptions={
            _number(e, "BAND_INDEX", source, int): (e.findtext("BAND_DESCRIPTION") or "").strip()
            for e in root.findall("Image_Interpretation/Spectral_Band_Info")
        },
    )


#: The largest side of an image a DIMAP v1 document may declare (pixels): SPOT 5's 2.5 m
#: scenes have 24 000 columns; a strip of ten 60 km scenes at 2.5 m, 240 000 rows.
MAX_DIMAP_SIDE = 240_000


def _check_frame(source: Path, n_rows: int, n_cols: int, points: NDArray) -> None:
    """Refuse sizes out of any SPOT scene's range, and a frame (corners, centre: rows,
    columns, 1-based) off the image the document declares: one of the two is wrong, and a
    model checked against it would say so as a miss of kilometres."""
    if not (1 <= n_rows <= MAX_DIMAP_SIDE and 1 <= n_cols <= MAX_DIMAP_SIDE):
        raise DimapError(
            f"{source}: Raster_Dimensions {n_rows} rows × {n_cols} columns: expected 1 to "
            f"{MAX_DIMAP_SIDE} each (a SPOT scene); damaged?"
        )
    rows, cols = points[:, 0], points[:, 1]
    off = (rows < 0) | (rows > n_rows + 1) | (cols < 0) | (cols > n_cols + 1)
    if np.any(off):
        k = int(np.argmax(off))
        what = f"Vertex[{k + 1}]" if k < 4 else "Scene_Center"
        raise DimapError(
            f"{source}: Dataset_Frame/{what} at row {rows[k]:.0f}, column {cols[k]:.0f}, off "
            f"the {n_rows} × {n_cols} image its Raster_Dimensions declare: the frame and the "
            "sizes contradict each other"
        )


#: The bands a SPOT 1–5 scene has at most (SPOT 4's XI, SPOT 5's XS: four).
MAX_DIMAP_BANDS = 4


def _bands(root: ET.Element, source: Path) -> int:
    """``Raster_Dimensions/NBANDS`` (1 when absent), refused beyond a SPOT scene's."""
    n = _optional(root, "Raster_Dimensions/NBANDS", int, source) or 1
    if not 1 <= n <= MAX_DIMAP_BANDS:
        raise DimapError(
            f"{source}: Raster_Dimensions/NBANDS = {n}: a SPOT 1–5 scene has 1 to "
            f"{MAX_DIMAP_BANDS} bands"
        )
    return n


def _image_file(root: ET.Element) -> str:
    """The image the document describes (``Data_File/DATA_FILE_PATH``'s ``href``)."""
    elem = root.find("Data_Access/Data_File/DATA_FILE_PATH")
    href = elem.get("href", "") if elem is not None else ""
    return href.strip() or "IMAGERY.TIF"


def _calibration(root: ET.Element, source: Path) -> dict[int, BandCalibration]:
    """Each band's ``Spectral_Band_Info`` gains and ``Sensor_Calibration`` cells."""
    info = {
        _number(e, "BAND_INDEX", source, int): e
        for e in root.findall("Image_Interpretation/Spectral_Band_Info")
    }
    cells = {_number(e, "BAND_INDEX", source, int): e for e in root.findall(_CALIBRATION)}
    out = {}
    for band in sorted(set(info) | set(cells)):
        i, c = info.get(band), cells.get(band)
        cell = [] if c is None else c.findall("Gain_Section/Pixel_Parameters/Cells/Cell")
        out[band] = BandCalibration(
            physical_gain=None if i is None else _optional(i, "PHYSICAL_GAIN", float, source),
            physical_bias=None if i is None else _optional(i, "PHYSICAL_BIAS", float, source),
            analog_gain=None
            if c is None
            else _optional(c, "Gain_Section/GAIN_ANALOG_VALUE", float, source),
            detector_gain=np.array([_number(e, "G", source) for e in cell], dtype=np.float64),
            dark_current=np.array(
                [_number(e, "DARK_CURRENT", source) for e in cell], dtype=np.float64
            ),
        )
    return out


def _time_stamp(
    root: ET.Element, source: Path
) -> tuple[Epoch | None, float | None, float | None, float | None]:
    """The scene's dating (``Time_Stamp``): its centre instant as the epoch, the line
    period, the centre line and column; all None when the document has none."""
    if root.find(_TIME_STAMP) is None:
        return None, None, None, None
    ts = _find(root, _TIME_STAMP, source)
    try:
        epoch = Epoch(parse_utc(_text(ts, "SCENE_CENTER_TIME", source)), name="SCENE_CENTER_TIME")
    except GeometryError as exc:
        raise DimapError(f"{source}: SCENE_CENTER_TIME: {exc}") from None
    line_period = _number(ts, "LINE_PERIOD", source)
    center_line = _number(ts, "SCENE_CENTER_LINE", source)
    center_col = _number(ts, "SCENE_CENTER_COL", source)
    if not line_period > 0:
        raise DimapError(f"{source}: LINE_PERIOD = {line_period}: must be > 0 (seconds)")
    return epoch, line_period, center_line, center_col


def _ephemeris(root: ET.Element, epoch: Epoch | None, source: Path) -> Ephemeris | None:
    """The ephemeris points, dated on the scene's epoch; None without any."""
    points = root.findall(_EPHEMERIS_POINTS)
    if not points:
        return None
    if epoch is None:
        raise DimapError(f"{source}: ephemeris present but no Time_Stamp to date the lines")
    t = _times(points, "TIME", epoch, "Ephemeris", source)
    pos = np.array([[_number(p, f"Location/{k}", source) for k in "XYZ"] for p in points])
    vel = np.array([[_number(p, f"Velocity/{k}", source) for k in "XYZ"] for p in points])
    try:
        return Ephemeris(t, pos, vel)
    except GeometryError as exc:
        raise DimapError(f"{source}: Ephemeris: {exc}") from None


def _attitudes(
    root: ET.Element, epoch: Epoch, source: Path
) -> tuple[
    SampledAttitude | None,
    NDArray[np.float64] | None,
    NDArray[np.float64] | None,
    SampledAttitude | None,
]:
    """The AOCS attitude angles, the angular speeds (their times and values) and the
    corrected attitudes, each None when the document lacks it."""
    aocs = speeds_t = speeds = corrected = None
    aocs_angles = root.findall(f"{_AOCS}/Angles_List/Angles")
    if len(aocs_angles) >= 2:
        aocs = _sampled(aocs_angles, epoch, "Aocs_Attitude/Angles_List", source)
    speed_elems = root.findall(f"{_AOCS}/Angular_Speeds_List/Angular_Speeds")
    if speed_elems:
        speeds_t = _times(speed_elems, "TIME", epoch, "Angular_Speeds_List", source)
        speeds = _angles(speed_elems, source)
        if np.any(np.diff(speeds_t) <= 0):
            raise DimapError(f"{source}: Angular_Speeds_List times do not increase strictly")
    corrected_elems = root.findall(_CORRECTED)
    if corrected_elems:
        corrected = _sampled(corrected_elems, epoch, "Corrected_Attitudes", source)
    return aocs, speeds_t, speeds, corrected


def _look_angles(block: ET.Element, band: int, n_cols: int, source: Path) -> LookAngleTable:
    """One band's look-angle table: two entries (first and last detector) or one per
    detector."""
    entries = block.findall("Look_Angles_List/Look_Angles")
    det = np.array([_number(e, "DETECTOR_ID", source, int) for e in entries])
    psi_x = np.array([_number(e, "PSI_X", source) for e in entries])
    psi_y = np.array([_number(e, "PSI_Y", source) for e in entries])
    if det.size < 2:
        raise DimapError(f"{source}: band {band} has {det.size} look angles, need at least 2")
    if det.min() < 1 or det.max() > n_cols:
        raise DimapError(
            f"{source}: band {band} look angles for detectors {det.min()}..{det.max()}, "
            f"but NCOLS = {n_cols}"
        )
    if det.size > 2 and det.size != n_cols:
        raise DimapError(
            f"{source}: band {band} has {det.size} look angles: expected 2 (first and last "
            f"detector) or one per detector ({n_cols})"
        )
    try:
        return LookAngleTable(det - 1.0, psi_x, psi_y, n_cols)
    except GeometryError as exc:
        raise DimapError(f"{source}: band {band} look angles: {exc}") from None


def _sampled(elems: list[ET.Element], epoch: Epoch, where: str, source: Path) -> SampledAttitude:
    t = _times(elems, "TIME", epoch, where, source)
    try:
        return SampledAttitude(t, _angles(elems, source))
    except GeometryError as exc:
        raise DimapError(f"{source}: {where}: {exc}") from None
