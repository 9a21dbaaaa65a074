"""Writer of SPOT level-1A DIMAP v1 scenes (``METADATA.DIM`` + ``IMAGERY.TIF``).

The inverse of :func:`levels.readers.dimap.read_dimap`: what that reader takes from a file,
this writes, element for element and in the real files' order and number formats
(``+d.dddddddddde±xx``, times to the microsecond), so that

* a real SPOT 1–5 ``METADATA.DIM`` read and written back reads again unchanged (its
  ephemeris, attitudes, angular speeds, look angles, mirror step, dating, frame and
  calibration; the elements this project does not read are not carried);
* an emulated level-1A product (:func:`dimap_scene_of`) becomes a scene that a tool reading
  real SPOT 1–4 scenes reads as one: the GDAL DIMAP driver (its Tie_Points as GCPs), OTB or
  OSSIM's SPOT model, the Ames Stereo Pipeline.

Conventions written (SPOT Geometry Handbook S-NT-73-12-SI; ``../shared/refdata/README.md``):
rows and columns 1-based, pixel centres (``Raster_CS/PIXEL_ORIGIN`` 1); a row's time is
``SCENE_CENTER_TIME + (row − SCENE_CENTER_LINE) · LINE_PERIOD``; frame corners on the WGS84
ellipsoid (height 0); attitude angles in the files' frame (the geometry core's own, so they
are written as the model holds them); ephemeris velocities as the product carries them
(inertial in ECEF axes for SPOT 1–4 scenarios, the default; Earth-fixed for SPOT 5 ones).
"""

from __future__ import annotations

import warnings
import xml.etree.ElementTree as ET
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from levels.choices import Level
from levels.errors import DimapError, ProductError
from levels.geometry.attitude import SampledAttitude
from levels.geometry.times import Epoch
from levels.readers.dimap import BandCalibration, DimapScene

if TYPE_CHECKING:
    from levels.geometry.model import PushbroomModel
    from levels.product import Product

__all__ = [
    "BAND_INDEX",
    "dimap_scene_of",
    "rates_reproducing",
    "write_dimap",
    "write_dimap_xml",
]

#: DIMAP band index of each product band (P alone; XS1–XS3 as bands 1–3).
BAND_INDEX = {"P": 1, "XS1": 1, "XS2": 2, "XS3": 3}
#: SENSOR_CODE of each mode in SPOT 1–3 files.
_SENSOR_CODE = {"P": "P", "XS": "X"}
_BAND_DESCRIPTION = {"P": "PAN", "XS1": "XS1", "XS2": "XS2", "XS3": "XS3"}


def _num(x: float) -> str:
    """A number as the real files write it: sign, 11 significant digits, exponent."""
    return f"{float(x):+.10e}"


def _utc(epoch: Epoch, t_s: Any) -> list[str]:
    """UTC strings to the microsecond (rounded) of instants ``t_s`` after ``epoch``."""
    ns = np.atleast_1d(epoch.utc(np.atleast_1d(np.asarray(t_s, dtype=np.float64))))
    us = (ns.astype("datetime64[ns]") + np.timedelta64(500, "ns")).astype("datetime64[us]")
    return [str(u) for u in np.datetime_as_string(us, unit="us")]


def _sub(parent: ET.Element, tag: str, text: Any = None, **attrib: str) -> ET.Element:
    e = ET.SubElement(parent, tag, attrib)
    if text is not None:
        e.text = str(text)
    return e


def _point(parent: ET.Element, tag: str, row: int, col: int, lat: float, lon: float) -> None:
    p = _sub(parent, tag)
    _sub(p, "FRAME_LON", _num(lon))
    _sub(p, "FRAME_LAT", _num(lat))
    _sub(p, "FRAME_ROW", row)
    _sub(p, "FRAME_COL", col)


def _angles(parent: ET.Element, tag: str, epoch: Epoch, t_s: NDArray, rpy: NDArray) -> None:
    for utc, (roll, pitch, yaw) in zip(_utc(epoch, t_s), rpy, strict=True):
        a = _sub(parent, tag)
        _sub(a, "TIME", utc)
        _sub(a, "YAW", _num(yaw))
        _sub(a, "PITCH", _num(pitch))
        _sub(a, "ROLL", _num(roll))
        _sub(a, "OUT_OF_RANGE", "N")


def write_dimap_xml(
    scene: DimapScene,
    path: str | Path,
    *,
    image_file: str | None = None,
    band_names: dict[int, str] | None = None,
    production: dict[str, str] | None = None,
) -> Path:
    """Write ``scene`` as a DIMAP v1 ``METADATA.DIM`` at ``path`` (atomically).

    ``band_names``: each band index's ``BAND_DESCRIPTION``; ``production``: the
    ``Production`` element's fields (``DATASET_PRODUCER_NAME``, ``SOFTWARE_NAME``, …).
    """
    from levels.files import write_text

    root = ET.Element(
        "Dimap_Document",
        {
            "xmlns:xsi": "http://www.w3.org/2001/XMLSchema-instance",
            "xsi:noNamespaceSchemaLocation": "Spot_Scene.xsd",
            "name": "METADATA.DIM",
        },
    )
    bands = sorted(set(scene.look_angles) | set(scene.calibration)) or [1]
    _identity_and_frame(root, scene)
    _production_and_source(root, scene, production or {})
    _raster(root, scene, len(bands), image_file or scene.image_file)
    _interpretation(root, scene, bands, band_names or {})
    strip = _sub(root, "Data_Strip")
    _data_strip(strip, scene, bands)
    ET.indent(root, space="  ")
    text = ET.tostring(root, encoding="unicode")
    return write_text(Path(path), '<?xml version="1.0" encoding="UTF-8"?>\n' + text + "\n")


def _identity_and_frame(root: ET.Element, scene: DimapScene) -> None:
    """``Metadata_Id`` to ``Geoposition``: what the file is, the scene's frame (its four
    vertices and centre), its CRS, and the frame's corners as tie points (what GDAL's DIMAP
    driver reads as GCPs)."""
    mid = _sub(root, "Metadata_Id")
    _sub(mid, "METADATA_FORMAT", "DIMAP", version="1.1")
    _sub(mid, "METADATA_PROFILE", "SPOTSCENE_1A")
    _sub(_sub(root, "Dataset_Id"), "DATASET_NAME", scene.dataset_name or f"SCENE {scene.name}")
    frame = _sub(root, "Dataset_Frame")
    for k in range(4):
        _point(
            frame,
            "Vertex",
            int(scene.frame_row[k]),
            int(scene.frame_col[k]),
            float(scene.frame_lat_deg[k]),
            float(scene.frame_lon_deg[k]),
        )
    _point(
        frame,
        "Scene_Center",
        scene.center_row,
        scene.center_col,
        scene.center_lat_deg,
        scene.center_lon_deg,
    )
    crs = _sub(_sub(root, "Coordinate_Reference_System"), "Horizontal_CS")
    _sub(crs, "HORIZONTAL_CS_CODE", "epsg:4326")
    _sub(crs, "HORIZONTAL_CS_TYPE", "GEOGRAPHIC")
    _sub(crs, "HORIZONTAL_CS_NAME", "WGS 84")
    rcs = _sub(root, "Raster_CS")
    _sub(rcs, "RASTER_CS_TYPE", "POINT")
    _sub(rcs, "PIXEL_ORIGIN", 1)
    gp = _sub(_sub(root, "Geoposition"), "Geoposition_Points")
    for k in range(4):
        tp = _sub(gp, "Tie_Point")
        _sub(tp, "TIE_POINT_CRS_X", _num(scene.frame_lon_deg[k]))
        _sub(tp, "TIE_POINT_CRS_Y", _num(scene.frame_lat_deg[k]))
        _sub(tp, "TIE_POINT_CRS_Z", _num(0.0))
        _sub(tp, "TIE_POINT_DATA_X", _num(scene.frame_col[k]))
        _sub(tp, "TIE_POINT_DATA_Y", _num(scene.frame_row[k]))


def _production_and_source(root: ET.Element, scene: DimapScene, production: dict) -> None:
    """``Production`` (its fields as given) and the ``Scene_Source``: date, time, mission,
    instrument, sensor."""
    prod = _sub(root, "Production")
    _sub(prod, "PRODUCT_TYPE", "SCENE1A")
    for key, value in production.items():
        _sub(prod, key, value)
    src = _sub(_sub(_sub(root, "Dataset_Sources"), "Source_Information"), "Scene_Source")
    if scene.epoch is not None:
        day, _, time = str(scene.epoch.t0_utc.astype("datetime64[s]")).partition("T")
        _sub(src, "IMAGING_DATE", scene.imaging_date or day)
        _sub(src, "IMAGING_TIME", time)
    elif scene.imaging_date:
        _sub(src, "IMAGING_DATE", scene.imaging_date)
    _sub(src, "MISSION", scene.mission)
    if scene.mission_index is not None:
        _sub(src, "MISSION_INDEX", scene.mission_index)
    _sub(src, "INSTRUMENT", scene.instrument)
    if scene.instrument_index is not None:
        _sub(src, "INSTRUMENT_INDEX", scene.instrument_index)
    _sub(src, "SENSOR_CODE", scene.sensor_code)
    _sub(src, "SCENE_PROCESSING_LEVEL", scene.processing_level or "1A")


def _raster(root: ET.Element, scene: DimapScene, n_bands: int, image_file: str) -> None:
    """``Raster_Dimensions`` to ``Data_Processing``: the image's size, encoding, file and
    processing (8-bit band-composite GeoTIFF, raw geometry, system radiometry)."""
    dims = _sub(root, "Raster_Dimensions")
    _sub(dims, "NCOLS", scene.n_cols)
    _sub(dims, "NROWS", scene.n_rows)
    _sub(dims, "NBANDS", n_bands)
    enc = _sub(root, "Raster_Encoding")
    _sub(enc, "NBITS", 8)
    _sub(enc, "DATA_TYPE", "UNSIGNED")
    _sub(enc, "BYTEORDER", "I")
    _sub(enc, "COMPRESSION_NAME", "NONE")
    acc = _sub(root, "Data_Access")
    _sub(acc, "DATA_FILE_ORGANISATION", "BAND_COMPOSITE")
    _sub(acc, "DATA_FILE_FORMAT", "GEOTIFF", version="1.0")
    _sub(_sub(acc, "Data_File"), "DATA_FILE_PATH", href=image_file)
    proc = _sub(root, "Data_Processing")
    _sub(proc, "PROCESSING_LEVEL", scene.processing_level or "1A")
    _sub(proc, "GEOMETRIC_PROCESSING", "RAW")
    _sub(proc, "RADIOMETRIC_PROCESSING", "SYSTEM")


def _interpretation(
    root: ET.Element, scene: DimapScene, bands: list[int], band_names: dict[int, str]
) -> None:
    """``Image_Interpretation``: each band's index, description and physical gain."""
    interp = _sub(root, "Image_Interpretation")
    for band in bands:
        cal = scene.calibration.get(band)
        info = _sub(interp, "Spectral_Band_Info")
        _sub(info, "BAND_INDEX", band)
        described = band_names.get(band) or scene.band_descriptions.get(band) or f"BAND{band}"
        _sub(info, "BAND_DESCRIPTION", described)
        if cal is not None and cal.physical_gain is not None:
            _sub(info, "PHYSICAL_BIAS", _num(cal.physical_bias or 0.0))
            _sub(info, "PHYSICAL_GAIN", _num(cal.physical_gain))


def _data_strip(strip: ET.Element, scene: DimapScene, bands: list[int]) -> None:
    epoch = scene.epoch
    if scene.ephemeris is not None and epoch is not None:
        eph = scene.ephemeris
        points = _sub(_sub(strip, "Ephemeris"), "Points")
        for utc, r, v in zip(_utc(epoch, eph.t_s), eph.r_ecef_m, eph.v_ecef_m_per_s, strict=True):
            p = _sub(points, "Point")
            _sub(p, "TIME", utc)
            loc, vel = _sub(p, "Location"), _sub(p, "Velocity")
            for k, axis in enumerate("XYZ"):
                _sub(loc, axis, _num(r[k]))
                _sub(vel, axis, _num(v[k]))
    if epoch is not None:
        atts = _sub(strip, "Satellite_Attitudes")
        if scene.aocs_attitude is not None or scene.angular_speeds_rad_per_s is not None:
            aocs = _sub(_sub(atts, "Raw_Attitudes"), "Aocs_Attitude")
            if scene.aocs_attitude is not None:
                att = scene.aocs_attitude
                _angles(_sub(aocs, "Angles_List"), "Angles", epoch, att.t_s, att.angles_rad_samples)
            if scene.angular_speeds_rad_per_s is not None:
                assert scene.angular_speeds_t_s is not None
                _angles(
                    _sub(aocs, "Angular_Speeds_List"),
                    "Angular_Speeds",
                    epoch,
                    scene.angular_speeds_t_s,
                    scene.angular_speeds_rad_per_s,
                )
        if scene.corrected_attitude is not None:
            att = scene.corrected_attitude
            corrected = _sub(_sub(atts, "Corrected_Attitudes"), "Corrected_Attitude")
            _angles(corrected, "Angles", epoch, att.t_s, att.angles_rad_samples)
    config = _sub(strip, "Sensor_Configuration")
    if epoch is not None:
        assert scene.line_period_s is not None
        ts = _sub(config, "Time_Stamp")
        _sub(ts, "LINE_PERIOD", _num(scene.line_period_s))
        _sub(ts, "SCENE_CENTER_TIME", _utc(epoch, 0.0)[0])
        _sub(ts, "SCENE_CENTER_LINE", _whole(scene.scene_center_line))
        _sub(ts, "SCENE_CENTER_COL", _whole(scene.scene_center_col))
    if scene.look_angles:
        looks = _sub(config, "Instrument_Look_Angles_List")
        for band, table in sorted(scene.look_angles.items()):
            block = _sub(looks, "Instrument_Look_Angles")
            _sub(block, "BAND_INDEX", band)
            entries = _sub(block, "Look_Angles_List")
            for col, px, py in zip(table.column, table.psi_x_rad, table.psi_y_rad, strict=True):
                e = _sub(entries, "Look_Angles")
                _sub(e, "DETECTOR_ID", round(float(col)) + 1)
                _sub(e, "PSI_X", _num(px))
                _sub(e, "PSI_Y", _num(py))
    if scene.mirror_step is not None:
        _sub(_sub(config, "Mirror_Position"), "STEP_COUNT", scene.mirror_step)
    cells = [b for b in bands if b in scene.calibration and scene.calibration[b].detector_gain.size]
    if cells:
        cal_el = _sub(_sub(strip, "Sensor_Calibration"), "Calibration")
        for band in cells:
            cal = scene.calibration[band]
            bp = _sub(cal_el, "Band_Parameters")
            _sub(bp, "BAND_INDEX", band)
            section = _sub(bp, "Gain_Section")
            if cal.analog_gain is not None:
                _sub(section, "GAIN_ANALOG_VALUE", _num(cal.analog_gain))
            cell_list = _sub(_sub(section, "Pixel_Parameters"), "Cells")
            for g, dc in zip(cal.detector_gain, cal.dark_current, strict=True):
                c = _sub(cell_list, "Cell")
                _sub(c, "G", _num(g))
                _sub(c, "DARK_CURRENT", _num(dc))


def _whole(x: float | None) -> str:
    """A line or column number: an integer as the files write it, else the number."""
    assert x is not None
    return str(int(x)) if float(x).is_integer() else _num(x)


def write_dimap(
    scene: DimapScene,
    directory: str | Path,
    image: NDArray[np.uint8] | None = None,
    *,
    band_names: dict[int, str] | None = None,
    production: dict[str, str] | None = None,
) -> Path:
    """Write a DIMAP v1 scene directory: ``METADATA.DIM`` and, given ``image`` (bands,
    rows, cols; uint8), ``IMAGERY.TIF`` (GeoTIFF with no georeferencing, as the 1A files
    are: GDAL's DIMAP driver puts the frame's GCPs on it). Returns the directory."""
    import rasterio
    from rasterio.errors import NotGeoreferencedWarning

    from levels.files import atomic_path

    out = Path(directory)
    out.mkdir(parents=True, exist_ok=True)
    if image is not None:
        im = np.asarray(image)
        if im.ndim != 3 or im.shape[1:] != (scene.n_rows, scene.n_cols) or im.dtype != np.uint8:
            raise DimapError(
                f"image of shape {im.shape} ({im.dtype}): expected (bands, {scene.n_rows}, "
                f"{scene.n_cols}) uint8"
            )
        profile = {
            "driver": "GTiff",
            "width": scene.n_cols,
            "height": scene.n_rows,
            "count": im.shape[0],
            "dtype": "uint8",
            "photometric": "MINISBLACK",
        }
        with warnings.catch_warnings():
            # a raw 1A has no georeferencing: GDAL's DIMAP driver gives it the frame's GCPs
            warnings.simplefilter("ignore", NotGeoreferencedWarning)
            with atomic_path(out / "IMAGERY.TIF") as tmp, rasterio.open(tmp, "w", **profile) as ds:
                ds.write(im)
    write_dimap_xml(scene, out / "METADATA.DIM", band_names=band_names, production=production)
    return out


def rates_reproducing(
    t_s: NDArray[np.float64], angles_rad: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Angular rates (n, 3) whose trapezoid integral (the reader's, and GEO's,
    :func:`~levels.geometry.attitude.integrate_rates`) gives back the sampled ``angles_rad``
    exactly: ``(w_k + w_k+1) Δt_k / 2 = ΔA_k``. Those equations leave one free alternating
    component ``c (−1)^k``; ``c`` is chosen so that the rates lie closest, in least squares,
    to the central differences of the angles (the smooth rates)."""
    t = np.asarray(t_s, dtype=np.float64)
    a = np.asarray(angles_rad, dtype=np.float64)
    n = t.size
    twice_slope = 2.0 * np.diff(a, axis=0) / np.diff(t)[:, None]
    sign = (-1.0) ** np.arange(n)
    # w_k = (−1)^k Σ_{m<k} (−1)^(m+1) · 2ΔA_m/Δt_m  is a particular solution with w_0 = 0
    w = np.zeros_like(a)
    w[1:] = sign[1:, None] * np.cumsum(-sign[:-1, None] * twice_slope, axis=0)
    smooth = np.gradient(a, t, axis=0)
    c = ((smooth - w) * sign[:, None]).sum(axis=0) / n
    return w + c * sign[:, None]


def dimap_scene_of(
    product: Product,
    *,
    mission_index: int | None = None,
    calibration: dict[str, tuple[NDArray, NDArray]] | None = None,
    counts_per_radiance: float | None = None,
) -> DimapScene:
    """The DIMAP v1 scene of a level-1A product: its rigorous model as the SPOT 1–4 files
    carry one (module docstring).

    - Dating: ``SCENE_CENTER_LINE`` the middle row (1-based ``n_rows // 2``, as the real
      files), ``SCENE_CENTER_TIME`` its time (rounded to the microsecond: 0.0005 line).
    - Ephemeris: the bulletin points the product was located with.
    - Attitude: the angular speeds whose trapezoid integral, zeroed at the scene centre
      (INPE's rule, the reader's ``attitude="integrated_zeroed"``), is the product's own
      attitude (:func:`rates_reproducing`); the two AOCS samples are that attitude at the
      ends of the records, **relative** (the station never knows the absolute attitude).
    - Look angles per detector as the product tabulates them; mirror step; frame corners
      and centre located by the model on the ellipsoid.
    - ``calibration``: each band's detector gains and dark offsets (the L0 archive's
      table); ``counts_per_radiance``: the physical gain."""
    from levels.geo.scenes import models_of_tree

    if product.level != Level.L1A:
        raise ProductError(f"level {product.level}: a DIMAP v1 scene is made from a 1A product")
    epoch0, models = models_of_tree(product.geometry)
    model = next(iter(models.values()))
    n_rows, n_cols = model.n_lines, model.n_columns
    t_c = float(model.clock.time_s(n_rows // 2 - 1.0))  # the centre row, 1-based
    centre_utc = _utc(epoch0, t_c)[0]
    epoch = Epoch(np.datetime64(centre_utc, "ns"), name="SCENE_CENTER_TIME")
    shift = float(epoch0.seconds(epoch.t0_utc))  # product seconds of the new epoch
    eph = model.ephemeris
    eph = replace(eph, t_s=eph.t_s - shift)
    att: SampledAttitude = model.attitude  # type: ignore[assignment]
    t_att = att.t_s - shift
    rates = rates_reproducing(t_att, att.angles_rad_samples)
    ends = np.array([0, t_att.size - 1])
    aocs = SampledAttitude(t_att[ends], att.angles_rad_samples[ends])
    rows, cols, lat, lon = _frame(model)
    a = product.attrs
    bands = {BAND_INDEX.get(name, k + 1): name for k, name in enumerate(models)}
    return DimapScene(
        path=Path("METADATA.DIM"),
        mission="SPOT",
        mission_index=mission_index,
        instrument="HRV",
        instrument_index=int(a["hrv"]) if "hrv" in a else None,
        sensor_code=_SENSOR_CODE.get(str(a.get("mode", "P")), str(a.get("mode", ""))),
        n_rows=n_rows,
        n_cols=n_cols,
        frame_row=rows[:4].astype(np.int64),
        frame_col=cols[:4].astype(np.int64),
        frame_lat_deg=lat[:4],
        frame_lon_deg=lon[:4],
        center_row=int(rows[4]),
        center_col=int(cols[4]),
        center_lat_deg=float(lat[4]),
        center_lon_deg=float(lon[4]),
        epoch=epoch,
        line_period_s=model.clock.period_s,
        scene_center_line=float(rows[4]),
        scene_center_col=float(cols[4]),
        ephemeris=eph,
        aocs_attitude=aocs,
        angular_speeds_t_s=t_att,
        angular_speeds_rad_per_s=rates,
        corrected_attitude=None,
        look_angles={index: _look_table(models[name], n_cols) for index, name in bands.items()},
        mirror_step=int(a["mirror_step"]) if "mirror_step" in a else None,
        calibration={
            index: _band_calibration(
                (calibration or {}).get(name, (np.empty(0), np.empty(0))), counts_per_radiance
            )
            for index, name in bands.items()
        },
        n_bands=len(bands),
        imaging_date=centre_utc.partition("T")[0],
        band_descriptions=band_descriptions(product),
    )


def _frame(model: PushbroomModel) -> tuple[NDArray, NDArray, NDArray, NDArray]:
    """The frame's four corners and its centre (1-based rows and columns, the centre
    ``n // 2`` as the real files) located by the model on the ellipsoid (degrees)."""
    n_rows, n_cols = model.n_lines, model.n_columns
    rows = np.array([1, 1, n_rows, n_rows, n_rows // 2])
    cols = np.array([1, n_cols, n_cols, 1, n_cols // 2])
    g = model.image_to_ground(rows - 1.0, cols - 1.0, 0.0)
    if not np.all(g.ok):
        raise ProductError("the product's model does not locate its corners on the ellipsoid")
    return rows, cols, np.degrees(g.lat_rad), np.degrees(g.lon_rad)


def _look_table(model: PushbroomModel, n_cols: int) -> Any:
    """A model's look angles as a DIMAP file tabulates them (one per detector)."""
    from levels.geometry.sensor import LookAngleTable

    la = model.look_angles
    return LookAngleTable(la.column, la.psi_x_rad, la.psi_y_rad, n_cols)


def _band_calibration(
    gains_dark: tuple[NDArray, NDArray], counts_per_radiance: float | None
) -> BandCalibration:
    """A band's calibration as DIMAP carries it: the physical gain (no bias), the
    detectors' gains and dark offsets (the L0 archive's table; empty: none)."""
    gains, dark = gains_dark
    return BandCalibration(
        physical_gain=counts_per_radiance,
        physical_bias=0.0 if counts_per_radiance is not None else None,
        analog_gain=None,
        detector_gain=np.asarray(gains, dtype=np.float64),
        dark_current=np.asarray(dark, dtype=np.float64),
    )


def band_descriptions(product: Product) -> dict[int, str]:
    """Each DIMAP band index's ``BAND_DESCRIPTION`` for a product's bands."""
    return {
        BAND_INDEX.get(name, k + 1): _BAND_DESCRIPTION.get(name, name)
        for k, name in enumerate(product.bands)
    }
