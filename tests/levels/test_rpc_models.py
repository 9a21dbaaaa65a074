"""RPCs fitted to the rigorous model, ``levels`` alone: their error against a smooth model
(a synthetic pass, ``_orbits.synthetic_pass``), GDAL's evaluation of them, their product
tree, and OSSIM's keyword list of a real SPOT 5 scene as the model OSSIM locates with. What
keeps SPOT's RPCs above a hundredth of a pixel (the buttings, the gyros' attitude) and the
station's commands are ``tests/test_rpc.py``'s."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from _orbits import smooth_table, synthetic_pass

from levels.geo.rpc import Rpc, rpc_of_model

#: The issue's figures for the algebraic model against the rigorous one (pixels).
RPC_RMS_PX, RPC_MAX_PX = 0.01, 0.05
#: GDAL's evaluation of our coefficients against ours (pixels): the same rational
#: function, so only rounding separates them.
GDAL_AGREEMENT_PX = 0.01
HEIGHTS_M = (0.0, 1500.0)
#: OSSIM's keyword list of the Teheran SPOT 5 scene against OSSIM's own localisation of 36
#: points in it (metres): the same model, to rounding.
OSSIM_AGREEMENT_M = 0.01


@pytest.fixture(scope="module", params=[48, 93], ids=["nadir", "27deg"])
def scene(request) -> object:
    """A full P scene at the mirror step, on a smooth attitude (a steady drift)."""
    _pg, scene, _res = synthetic_pass(6000, 6000, mirror_step=request.param)
    return scene


def test_rpcs_follow_a_smooth_rigorous_model(scene) -> None:
    """A smooth attitude and the buttings' steps taken out of the look table: the RPCs are within
    the issue's figures over the image and 1500 m of height."""
    model = dataclasses.replace(scene.model, look_angles=smooth_table(scene.model.look_angles))
    e = rpc_of_model(model, HEIGHTS_M).fit_error_px
    assert e["n_points"] > 1000
    assert e["rms_px"] <= RPC_RMS_PX and e["max_px"] <= RPC_MAX_PX


def test_gdal_evaluates_our_rpcs_as_we_do(scene) -> None:
    """GDAL's RPC transformer (through rasterio) on our coefficients at 1000 ground points:
    the same image positions, GDAL's pixel corners half a pixel from RPC00B's centres."""
    from rasterio.rpc import RPC
    from rasterio.transform import RPCTransformer

    rpc = rpc_of_model(scene.model, HEIGHTS_M)
    rng = np.random.default_rng(7)
    lat = rpc.lat_off + rpc.lat_scale * rng.uniform(-0.95, 0.95, 1000)
    lon = rpc.lon_off + rpc.lon_scale * rng.uniform(-0.95, 0.95, 1000)
    h = rng.uniform(*HEIGHTS_M, 1000)
    line, sample = rpc.image_of(lat, lon, h)
    with RPCTransformer(RPC.from_gdal(rpc.gdal_metadata())) as gdal:
        rows, cols = (np.asarray(a) for a in gdal.rowcol(lon, lat, zs=h, op=lambda v: v))
    assert np.max(np.abs(rows - 0.5 - line)) <= GDAL_AGREEMENT_PX
    assert np.max(np.abs(cols - 0.5 - sample)) <= GDAL_AGREEMENT_PX


def test_rpcs_round_trip_through_a_product_tree(scene) -> None:
    rpc = rpc_of_model(scene.model, HEIGHTS_M)
    back = Rpc.from_tree(rpc.product_tree())
    lat, lon = rpc.lat_off + 0.3 * rpc.lat_scale, rpc.lon_off - 0.2 * rpc.lon_scale
    assert back.image_of(lat, lon, 700.0) == rpc.image_of(lat, lon, 700.0)
    assert back.fit_error_px == rpc.fit_error_px


def test_ossims_keyword_list_is_the_model_ossim_locates_with(refdata) -> None:
    """Read into our rigorous model, the ``.geom`` puts OSSIM's own points where OSSIM
    does, once OSSIM's image coordinates are ours: its (line, sample) is our (line + 0.5,
    column + 1); at the same numbers the two differ by the ground size of that offset."""
    from pyproj import Geod

    from levels.readers.ossim import read_ossim_gcps, read_ossim_geom

    d = refdata / "dimap"
    scene = read_ossim_geom(d / "otb_spot5_hrg2_20030723_teheran_ossim.geom")
    pts = read_ossim_gcps(d / "otb_spot5_hrg2_20030723_teheran_ossim.gcp")
    assert scene.n_lines == 6000 and pts["line"].size == 36
    geod = Geod(ellps="WGS84")

    def miss_m(dline: float, dcol: float) -> np.ndarray:
        g = scene.model.image_to_ground(pts["line"] + dline, pts["sample"] + dcol, pts["height_m"])
        assert g.ok.all()
        lon, lat = np.degrees(g.lon_rad), np.degrees(g.lat_rad)
        return geod.inv(lon, lat, pts["lon_deg"], pts["lat_deg"])[2]

    assert miss_m(-0.5, -1.0).max() <= OSSIM_AGREEMENT_M
    assert 5.0 < miss_m(0.0, 0.0).min()  # the convention, about a pixel of 10 m
    e = rpc_of_model(scene.model, (0.0, 3000.0)).fit_error_px
    # its attitude, sampled at 8 Hz and interpolated linearly, has a kink every 83 lines
    assert e["rms_px"] < 0.06 and e["max_px"] < 0.1
