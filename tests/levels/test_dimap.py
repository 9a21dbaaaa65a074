"""The DIMAP reader and the model against the producer's own numbers in real SPOT metadata.

The files are read in place from ../shared/refdata/dimap (never copied into the repository);
the malformed variants are written to a temporary folder from their text.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from _frames import frame_gcps
from pyproj import Geod

from levels.errors import DimapError
from levels.locate import check_frame
from levels.readers import read_dimap

#: The issue's bar for the Dataset_Frame corners and centre (ellipsoid height 0). SPOT 1–4
#: times are given to 1 ms, i.e. ±3.3 m along track at 6.6 km/s: 3 m is what they allow.
CORNER_TOL_M = 3.0
#: SPOT 5 dates to the microsecond and carries its corrected attitude: 0.1 m (0.02 px at 5 m)
#: is what the producer's rounding of corner coordinates (1e-6° ≈ 0.1 m) allows.
SPOT5_CORNER_TOL_M = 0.1
IMAGE_ROUNDTRIP_TOL_PX = 1e-3
GROUND_ROUNDTRIP_TOL_M = 1e-3

SCENES = {
    "spot5_hrg1_A_20050313_altai_METADATA.DIM": SPOT5_CORNER_TOL_M,
    "spot2_hrv1_P_19980220_izmit_METADATA.DIM": CORNER_TOL_M,
    "spot4_hrvir2_M_20120115_altai_METADATA.DIM": CORNER_TOL_M,
}


@pytest.fixture(scope="module")
def dimap_dir(refdata: Path) -> Path:
    return refdata / "dimap"


@pytest.mark.parametrize(("name", "tol_m"), SCENES.items())
def test_frame_corners_and_centre_are_predicted(dimap_dir: Path, name: str, tol_m: float) -> None:
    check = check_frame(dimap_dir / name)
    assert check.error_m.shape == (5,)
    assert check.error_m.max() < tol_m, check.as_dict()
    assert check.roundtrip_px.max() < IMAGE_ROUNDTRIP_TOL_PX


@pytest.mark.parametrize("name", SCENES)
def test_round_trips_over_the_real_scenes(dimap_dir: Path, name: str) -> None:
    scene = read_dimap(dimap_dir / name)
    model = scene.model()
    lines, cols = np.meshgrid(
        np.linspace(0, scene.n_rows - 1, 21), np.linspace(0, scene.n_cols - 1, 21), indexing="ij"
    )
    for h in (0.0, 2500.0):
        ground = model.image_to_ground(lines.ravel(), cols.ravel(), h)
        back = model.ground_to_image(ground.lat_rad, ground.lon_rad, h)
        assert back.converged.all() and back.iterations.max() <= 5
        assert np.abs(back.line - lines.ravel()).max() < IMAGE_ROUNDTRIP_TOL_PX
        assert np.abs(back.column - cols.ravel()).max() < IMAGE_ROUNDTRIP_TOL_PX
        again = model.image_to_ground(back.line, back.column, h)
        _, _, miss = Geod(ellps="WGS84").inv(
            np.degrees(ground.lon_rad),
            np.degrees(ground.lat_rad),
            np.degrees(again.lon_rad),
            np.degrees(again.lat_rad),
        )
        assert miss.max() < GROUND_ROUNDTRIP_TOL_M


def test_what_the_reader_finds(dimap_dir: Path) -> None:
    spot2 = read_dimap(dimap_dir / "spot2_hrv1_P_19980220_izmit_METADATA.DIM")
    assert (spot2.mission_index, spot2.instrument, spot2.sensor_code) == (2, "HRV", "P")
    assert (spot2.n_rows, spot2.n_cols, spot2.mirror_step) == (6000, 6000, 93)
    assert spot2.line_period_s == pytest.approx(1.504e-3)
    assert spot2.ephemeris.t_s.size == 8
    assert np.diff(spot2.ephemeris.t_s) == pytest.approx(np.full(7, 60.0))
    assert spot2.look_angles[1].column.tolist() == [0.0, 5999.0]
    assert spot2.angular_speeds_rad_per_s.shape[1] == 3 and spot2.corrected_attitude is None
    assert spot2.aocs_attitude.t_s.size == 2
    # SPOT 1-4: PSI_Y includes the mirror, 27° at step 93.
    assert np.degrees(np.mean(spot2.look_angles[1].psi_y_rad)) == pytest.approx(27.0, abs=0.2)

    spot5 = read_dimap(dimap_dir / "spot5_hrg1_A_20050313_altai_METADATA.DIM")
    assert spot5.ephemeris.t_s.size == 11
    assert spot5.look_angles[1].column.size == 12000
    assert spot5.corrected_attitude is not None


@pytest.mark.parametrize(
    ("attitude", "worse_than_m"),
    [("aocs", 10.0), ("integrated", 10.0), ("integrated_zeroed", 5.0)],
)
def test_spot4_frame_is_the_null_attitude_s(
    dimap_dir: Path, attitude: str, worse_than_m: float
) -> None:
    """The finding behind attitude="auto" for SPOT 1–4 (levels.readers.dimap): applying the
    AOCS data moves the SPOT 4 frame metres to tens of metres away from the producer's."""
    check = check_frame(dimap_dir / "spot4_hrvir2_M_20120115_altai_METADATA.DIM", attitude=attitude)
    assert check.error_m.max() > worse_than_m


def test_a_frame_only_file_parses_but_has_no_model(dimap_dir: Path) -> None:
    scene = read_dimap(dimap_dir / "gdal_spot4_hrvir1_M_20011129_frameonly_METADATA.DIM")
    assert scene.frame_lat_deg.shape == (4,) and scene.ephemeris is None
    with pytest.raises(DimapError, match="missing Ephemeris"):
        scene.model()


def _variant(tmp_path: Path, dimap_dir: Path, edit) -> Path:
    text = (dimap_dir / "spot2_hrv1_P_19980220_izmit_METADATA.DIM").read_text()
    out = tmp_path / "METADATA.DIM"
    out.write_text(edit(text))
    return out


@pytest.mark.parametrize(
    ("edit", "match"),
    [
        (lambda t: "not xml at all", "not an XML document"),
        (lambda t: "<?xml version='1.0'?><Landsat/>", "not a DIMAP document"),
        (
            lambda t: (
                "<Dimap_Document><Metadata_Identification><METADATA_FORMAT "
                'version="2.15">DIMAP</METADATA_FORMAT></Metadata_Identification></Dimap_Document>'
            ),
            r"DIMAP v2\.15 \(SPOT 6/7, Pléiades\).*RPC_\*\.XML",
        ),
        (lambda t: re.sub(r"<NCOLS>.*?</NCOLS>", "", t), "missing element Raster_Dimensions/NCOLS"),
        (
            lambda t: t.replace("<LINE_PERIOD>+1.5040000000e-03", "<LINE_PERIOD>-1.5e-3"),
            "LINE_PERIOD",
        ),
        (lambda t: t.replace("<NCOLS>6000</NCOLS>", "<NCOLS>3000</NCOLS>"), "NCOLS = 3000"),
        (lambda t: re.sub(r"<Velocity>\s*<X>[^<]*</X>", "<Velocity>", t, count=1), "Velocity/X"),
        (
            lambda t: t.replace(
                "<TIME>1998-02-20T09:15:00.000000</TIME>", "<TIME>1998-02-20T09:14:00.000000</TIME>"
            ),
            "increase strictly",
        ),
        (
            lambda t: t.replace("<PSI_Y>+5.0470688000e-01</PSI_Y>", "<PSI_Y>abc</PSI_Y>"),
            "not a number",
        ),
        (lambda t: t.replace("<FRAME_ROW>6000</FRAME_ROW>", "", 1), "FRAME_ROW"),
        (lambda t: re.sub(r"<Vertex>.*?</Vertex>", "", t, count=1, flags=re.S), "3 Vertex"),
    ],
    ids=[
        "not-xml",
        "not-dimap",
        "dimap-v2",
        "no-ncols",
        "bad-period",
        "detectors-beyond-ncols",
        "no-velocity",
        "ephemeris-out-of-order",
        "nan-look-angle",
        "vertex-without-row",
        "three-vertices",
    ],
)
def test_bad_files_give_clear_errors(tmp_path: Path, dimap_dir: Path, edit, match: str) -> None:
    path = _variant(tmp_path, dimap_dir, edit)
    with pytest.raises(DimapError, match=match) as info:
        read_dimap(path).model()
    assert str(path) in str(info.value)


def test_a_missing_file_is_a_file_not_found(tmp_path: Path) -> None:
    with pytest.raises(FileNotFoundError):
        read_dimap(tmp_path / "nope.DIM")


#: The frame-corner and control-point checks run the same model at the same points: they
#: agree to the model's own closure (1e-6 px, well under a millimetre on the ground).
SAME_POINTS_M = 1e-3


@pytest.mark.parametrize(
    "name", ["spot5_hrg1_A_20050313_altai_METADATA.DIM", "spot2_hrv1_P_19980220_izmit_METADATA.DIM"]
)
def test_control_points_of_a_real_scene(name: str, refdata: Path, tmp_path: Path) -> None:
    """A user's control points on a real scene (docs/gcp.md), here the producer's own frame
    corners: the DIMAP model misses them as the frame check says; a point measured 10
    columns off is seen 10 pixels off."""
    from levels.locate import check_frame, check_gcps
    from levels.readers.dimap import read_dimap

    path = refdata / "dimap" / name
    scene = read_dimap(path)
    gcps = frame_gcps(scene, tmp_path / "frame.gcp.csv")
    got = check_gcps(path, gcps)
    frame = check_frame(path)
    assert got.ground_miss_m == pytest.approx(frame.error_m[:4], abs=SAME_POINTS_M)
    off = tmp_path / "off.gcp.csv"
    lines = gcps.read_text().splitlines()
    first = lines[1].split(",")
    first[5] = repr(float(first[5]) + 10.0)
    off.write_text("\n".join([lines[0], ",".join(first), *lines[2:]]) + "\n")
    moved = check_gcps(path, off)
    assert moved.image_miss_px[0] == pytest.approx(10.0, abs=0.1)
