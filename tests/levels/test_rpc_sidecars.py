"""Real SPOT scenes' models as RPCs (:mod:`levels.locate`, :mod:`levels.geo.rpc`): the
sidecar GDAL reads beside an image (``_RPC.TXT``, DigitalGlobe's ``.RPB``) fitted to the
scene's DIMAP, and control points checked through the RPCs where the rigorous model puts
them."""

from __future__ import annotations

import numpy as np
import pytest
from _frames import frame_gcps

from levels.geo.rpc import rpc_of_model
from levels.locate import check_gcps, write_rpc
from levels.readers.dimap import read_dimap

#: SPOT 1–4 DIMAP tabulate the first and last detector only (a straight line of look
#: angles) with the corrected attitude constant: the RPC is exact to rounding. SPOT 5
#: tabulates every detector and samples the attitude at 8 Hz (its own wiggles).
REAL_MAX_PX = {"spot2": 0.001, "spot4": 0.001, "spot5": 0.15}


@pytest.mark.filterwarnings("ignore::rasterio.errors.NotGeoreferencedWarning")  # the blank
@pytest.mark.parametrize(
    "name",
    [
        "spot2_hrv1_P_19980220_izmit_METADATA.DIM",
        "spot4_hrvir2_M_20120115_altai_METADATA.DIM",
        "spot5_hrg1_A_20050313_altai_METADATA.DIM",
    ],
)
def test_real_scenes_get_a_sidecar_gdal_reads(refdata, tmp_path, name) -> None:
    """:func:`levels.locate.write_rpc`: the ``_RPC.TXT`` beside an image is what GDAL then
    finds for it, and the fit's error is said."""
    import rasterio

    image = tmp_path / "scene.tif"
    with rasterio.open(image, "w", driver="GTiff", width=8, height=8, count=1, dtype="uint8") as ds:
        ds.write(np.zeros((1, 8, 8), dtype=np.uint8))
    sidecar = tmp_path / "scene_RPC.TXT"
    dim = refdata / "dimap" / name
    written = write_rpc(dim, sidecar, (0.0, 3000.0))
    assert written["path"] == str(sidecar) and "max_px" in written["fit_error_px"]
    with rasterio.open(image) as ds:
        rpcs = ds.rpcs
    assert rpcs is not None
    fitted = rpc_of_model(read_dimap(dim).model(), (0.0, 3000.0))
    assert rpcs.line_off == pytest.approx(fitted.line_off)
    assert np.allclose(rpcs.samp_num_coeff, fitted.samp_num, rtol=1e-12, atol=1e-15)
    assert fitted.fit_error_px["max_px"] <= REAL_MAX_PX[name.split("_")[0]]
    # DigitalGlobe's .RPB, which GDAL reads as well (once the _RPC.TXT is gone)
    sidecar.unlink()
    write_rpc(dim, image.with_suffix(".RPB"), (0.0, 3000.0))
    with rasterio.open(image) as ds:
        assert ds.rpcs is not None and ds.rpcs.lat_off == pytest.approx(fitted.lat_off)
        assert np.allclose(ds.rpcs.line_den_coeff, fitted.line_den, rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize(
    "name", ["spot2_hrv1_P_19980220_izmit_METADATA.DIM", "spot5_hrg1_A_20050313_altai_METADATA.DIM"]
)
def test_control_points_through_the_algebraic_model(name, refdata, tmp_path) -> None:
    """Control points checked through RPCs (``model="rpc"``): the ground → image step lands
    where the rigorous model does, within the RPC's own fit error (PHOTOMOD's comparison)."""
    path = refdata / "dimap" / name
    scene = read_dimap(path)
    gcps = frame_gcps(scene, tmp_path / "frame.gcp.csv", height_step_m=100.0)
    rigorous = check_gcps(path, gcps)
    algebraic = check_gcps(path, gcps, model="rpc")
    assert algebraic.model == "rpc" and algebraic.rpc_fit_error_px is not None
    assert algebraic.rpc_vs_rigorous_px is not None
    assert algebraic.rpc_vs_rigorous_px <= max(1e-3, 2 * algebraic.rpc_fit_error_px["max_px"])
    assert algebraic.image_miss_px == pytest.approx(rigorous.image_miss_px, abs=0.3)
