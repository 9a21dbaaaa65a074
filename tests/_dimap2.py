"""DIMAP v2 files as SPOT 6/7 deliver them, written from an emulated scene's RPC and model
(no real SPOT 6/7 file is in ../shared/refdata): the RPC file and the DIM that names it."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from levels.geo.rpc import Rpc


def write_rpc_xml(rpc: Rpc, path: Path) -> Path:
    """``rpc`` written as a DIMAP v2 ``RPC_*.XML`` does (Airbus's layout: ground → image
    is the ``Inverse_Model``, offsets in ``RFM_Validity``, pixels counted from 1)."""
    coeffs = "".join(
        f"<{key}_{k + 1}>{float(c)!r}</{key}_{k + 1}>"
        for key, arr in (
            ("SAMP_NUM_COEFF", rpc.samp_num),
            ("SAMP_DEN_COEFF", rpc.samp_den),
            ("LINE_NUM_COEFF", rpc.line_num),
            ("LINE_DEN_COEFF", rpc.line_den),
        )
        for k, c in enumerate(arr)
    )
    box = {
        "LONG_SCALE": rpc.lon_scale,
        "LONG_OFF": rpc.lon_off,
        "LAT_SCALE": rpc.lat_scale,
        "LAT_OFF": rpc.lat_off,
        "HEIGHT_SCALE": rpc.height_scale,
        "HEIGHT_OFF": rpc.height_off,
        "SAMP_SCALE": rpc.samp_scale,
        "SAMP_OFF": rpc.samp_off + 1.0,
        "LINE_SCALE": rpc.line_scale,
        "LINE_OFF": rpc.line_off + 1.0,
    }
    validity = "".join(f"<{k}>{v!r}</{k}>" for k, v in box.items())
    path.write_text(
        '<?xml version="1.0" encoding="UTF-8"?><Dimap_Document><Rational_Function_Model>'
        "<Global_RFM><Direct_Model/><Inverse_Model>" + coeffs + "</Inverse_Model>"
        "<RFM_Validity>" + validity + "</RFM_Validity></Global_RFM>"
        "</Rational_Function_Model></Dimap_Document>"
    )
    return path


def write_dim_xml(
    path: Path,
    rpc_name: str,
    n_rows: int,
    n_cols: int,
    frame: np.ndarray,
    with_heights: bool = True,
) -> Path:
    """A ``DIM_*.XML`` naming ``rpc_name``: ``frame`` rows of (row, col, lat, lon, h), 1-based
    rows and columns, four vertices then the centre (``Dataset_Extent``)."""

    def point(tag: str, r: np.ndarray) -> str:
        row, col, lat, lon, height = (float(x) for x in r)
        h = f"<H>{height!r}</H>" if with_heights else ""
        return (
            f"<{tag}><LON>{lon!r}</LON><LAT>{lat!r}</LAT>{h}"
            f"<COL>{col!r}</COL><ROW>{row!r}</ROW></{tag}>"
        )

    extent = "".join(point("Vertex", r) for r in frame[:4]) + point("Center", frame[4])
    path.write_text(
        '<?xml version="1.0" encoding="UTF-8"?>\n<Dimap_Document>'
        '<Metadata_Identification><METADATA_FORMAT version="2.0">DIMAP</METADATA_FORMAT>'
        "<METADATA_PROFILE>S6_SENSOR</METADATA_PROFILE></Metadata_Identification>"
        "<Dataset_Content><Dataset_Extent><EXTENT_TYPE>Bounding_Box</EXTENT_TYPE>"
        + extent
        + "</Dataset_Extent></Dataset_Content>"
        "<Geoposition><Raster_CRS><RASTER_GEOMETRY>SENSOR</RASTER_GEOMETRY>"
        "<PIXEL_ORIENTATION>CENTER</PIXEL_ORIENTATION><PIXEL_ORIGIN>1</PIXEL_ORIGIN>"
        "</Raster_CRS><Geoposition_Models><Rational_Function_Model><Component>"
        f'<COMPONENT_PATH href="{rpc_name}"/></Component></Rational_Function_Model>'
        "</Geoposition_Models></Geoposition>"
        f"<Raster_Data><Raster_Dimensions><NROWS>{n_rows}</NROWS><NCOLS>{n_cols}</NCOLS>"
        "<NBANDS>1</NBANDS></Raster_Dimensions></Raster_Data>"
        "<Dataset_Sources><Source_Identification><Strip_Source><MISSION>SPOT</MISSION>"
        "<MISSION_INDEX>6</MISSION_INDEX><INSTRUMENT>NAOMI</INSTRUMENT>"
        "<INSTRUMENT_INDEX>1</INSTRUMENT_INDEX></Strip_Source></Source_Identification>"
        "</Dataset_Sources></Dimap_Document>\n"
    )
    return path
