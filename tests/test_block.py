"""Block adjustment (issue 36 §3): two passes over one ground, 26 days apart, the mirror at
0° and +8.4°, full P geometry (no image), tied by points; measured against the truth.

The first pass has 12 control points, the second none. Tie points come from the truth
(``station.truth.optical.true_tie_points``: a 15 × 15 lattice, 0.2 px of image noise, the
matcher's figure): the adjustment is tested here, the matcher in ``test_tiepoints.py``.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest
from _passes import run_pass

from levels.adjust import Strip, adjust, adjust_block
from levels.errors import GeometryError
from levels.geometry.dem import Dem
from levels.options import ProcessingOptions
from levels.readers.gcp import ControlPointSet
from station.chain.gcps import control_points
from station.fixtures import emulated_pass
from station.scenario import scenario_from_dict
from station.spacecraft.dem import world_dem
from station.spacecraft.emulator import emulate, truth_model
from station.truth.optical import Truth, true_tie_points

PIXEL_M = 10.0
#: The issue's bar for a block's scenes (ADRIN: 25–105 m at 10 m pixels).
BLOCK_RMS_PX = 1.5
TIE_SIGMA_PX = 0.2
#: One draw of one block: the measured/predicted ratio within twice the issue's band
#: (its [0.7, 1.5] is over 10 blocks: `tools/` for that figure).
RATIO = (0.35, 3.0)
DEM_SIGMA_M = 5.0


def _pass(seed: int, date: str, step: int, count: int):
    scn = scenario_from_dict(
        {
            "name": f"p{seed}",
            "seed": seed,
            "pass": {"date_utc": date},
            "instrument": {"mirror_step": step},
            "world": {"relief_m": 400.0},
            "gcps": {"count": count},
        }
    )
    acq = emulate(scn, render=False)
    pg, scenes = emulated_pass(acq, 6000)
    return acq, pg, scenes


@pytest.fixture(scope="module")
def block():
    a = _pass(1, "1998-02-20", 48, 12)
    b = _pass(2, "1998-03-18", 62, 0)
    ties = true_tie_points(a[0], b[0], 15, TIE_SIGMA_PX, np.random.default_rng(36), 450.0)
    return a, b, ties


def _error_m(acq, pg, scenes, adj) -> float:
    e = np.hypot(*Truth(acq, 0).model_error_en(adj.refine(pg, scenes[0])))
    return float(np.sqrt(np.mean(e**2)))


def _strip(p, gcps=None) -> Strip:
    acq, pg, scenes = p
    return Strip(pg, scenes, control_points(acq) if gcps is None else gcps)


def _world_dem(acq) -> Dem:
    """The world's terrain at 1" around the scenes, with 5 m of white error."""
    lat, lon = np.radians(-15.6), np.radians(-56.1)
    return world_dem(
        acq.world,
        (lat - 0.012, lat + 0.012),
        (lon - 0.014, lon + 0.014),
        1 / 3600,
        DEM_SIGMA_M,
        np.random.default_rng(5),
    )


def test_tie_points_carry_the_control_across(block) -> None:
    """Tied by points only (B/H 0.15), the second pass, with no control point of its own,
    is located by the first's: the lines of sight of the two swaths converge differently
    from one edge to the other, which leaves no freedom. Its predicted σ stays on the safe
    side (the across-baseline direction is the weakest; the budget's priors are larger than
    the emulator's errors), never below the measured error."""
    a, b, (ta, tb) = block
    opts = ProcessingOptions()
    adj_a, adj_b = (r[0] for r in adjust_block([[_strip(a)], [_strip(b)]], [[ta], [tb]], opts))
    alone_a = adjust(a[1], a[2], control_points(a[0]), opts)
    # the first pass: as alone (its control points hold it)
    assert abs(_error_m(*a, adj_a) - _error_m(*a, alone_a)) < 1.0
    assert _error_m(*a, adj_a) <= BLOCK_RMS_PX * PIXEL_M
    err_b = _error_m(*b, adj_b)
    assert err_b <= BLOCK_RMS_PX * PIXEL_M
    assert err_b <= adj_b.predicted_sigma_m[0, 2]  # it does not claim more than it has
    assert adj_b.mode == "block" and 0.8 < adj_b.sigma0 < 1.2


def test_a_shared_control_point_carries_the_control_across(block) -> None:
    a, b, (ta, tb) = block
    acq_a, acq_b = a[0], b[0]
    cp = control_points(acq_a)
    g = acq_a.gcps
    seen = truth_model(acq_b).ground_to_image(g.true_lat_rad, g.true_lon_rad, g.true_h_m)
    k = np.flatnonzero(
        seen.converged
        & (seen.line > 0)
        & (seen.line < 5999)
        & (seen.column > 0)
        & (seen.column < 5999)
    )[:1]
    assert k.size == 1
    rng = np.random.default_rng(1)
    in_b = ControlPointSet(
        tuple(cp.id[i] for i in k),
        cp.lon_rad[k],
        cp.lat_rad[k],
        cp.h_m[k],
        seen.line[k] + cp.sigma_px[k] * rng.standard_normal(1),
        seen.column[k] + cp.sigma_px[k] * rng.standard_normal(1),
        cp.sigma_ground_m[k],
        cp.sigma_h_m[k],
        cp.sigma_px[k],
        np.full(1, acq_b.hrv.number, dtype=np.int64),
    )
    res = adjust_block([[_strip(a)], [_strip(b, in_b)]], [[ta], [tb]], ProcessingOptions())
    adj_b = res[1][0]
    err = _error_m(*b, adj_b)
    assert err <= BLOCK_RMS_PX * PIXEL_M
    assert RATIO[0] <= err / adj_b.predicted_sigma_m[0, 2] <= RATIO[1]


def test_the_dem_under_the_tie_points_carries_the_control_across(block) -> None:
    """ADRIN's secondary controls were map points, heights and all: the tie points'
    heights from a DEM (5 m) leave the second pass, without a control point of its own, as
    good as the first."""
    a, b, (ta, tb) = block
    res = adjust_block(
        [[_strip(a)], [_strip(b)]],
        [[ta], [tb]],
        ProcessingOptions(),
        dem=_world_dem(a[0]),
        dem_sigma_m=DEM_SIGMA_M,
    )
    adj_b = res[1][0]
    err = _error_m(*b, adj_b)
    assert err <= BLOCK_RMS_PX * PIXEL_M
    assert RATIO[0] <= err / adj_b.predicted_sigma_m[0, 2] <= RATIO[1]
    assert _error_m(*b, adjust(b[1], b[2], control_points(b[0]), ProcessingOptions())) > 100.0


def test_a_tie_point_in_one_pass_only_is_refused(block) -> None:
    a, b, (ta, _tb) = block
    empty = ControlPointSet((), *(np.zeros(0) for _ in range(8)), np.zeros(0, dtype=np.int64))
    with pytest.raises(GeometryError, match="fewer than two"):
        adjust_block([[_strip(a)], [_strip(b)]], [[ta], [empty]], ProcessingOptions())


#: Reduced scenes (100 m pixels): the block's second pass, with no control point of its
#: own, must reach a fifth of a pixel (it does 0.1 px; alone it has none to reach).
REDUCED_BLOCK_PX = 0.2


def test_station_processes_a_block_end_to_end(tmp_path) -> None:
    """Two passes run, their tie points found (station tie), then both reprocessed to
    level 2 as one block (station process --adjustment block), the DEM the first run
    exported observing the tie points' heights; checkpoints against each pass's truth."""
    from levels.products import read_product
    from station.cli import main

    dem = "[dem]\nspacing_arcsec = 3.0\nerror_rms_m = 5.0"
    sa, ra = run_pass(tmp_path, "pa", 11, "1998-02-20", 48, extra=dem)
    sb, rb = run_pass(tmp_path, "pb", 12, "1998-03-18", 62, gcps=0)
    ties = tmp_path / "ties"
    assert (
        main(["tie", str(ra / "pa_s000_2A.nc"), str(rb / "pb_s000_2A.nc"), "--out", str(ties)]) == 0
    )
    options = tmp_path / "block.toml"
    options.write_text(
        '[processing]\nlevels = ["2A", "2"]\nadjustment = "block"\n'
        f'dem_path = "{ra / "pa.dem.tif"}"\ntie_height_sigma_m = 5.0\n'
    )
    out = tmp_path / "block"
    args = ["process", str(ra / "pa.l0.h5"), str(rb / "pb.l0.h5"), "--options", str(options)]
    args += ["--ties", str(ties), "--scenario", str(sa), "--scenario", str(sb)]
    assert main([*args, "--out", str(out), "-q"]) == 0
    level2 = read_product(out / "pb_s000_2.nc", images=False)
    adj = level2.geometry["adjustment"]
    assert adj["mode"] == "block"
    los = level2.quality["checkpoints"]["P"]["line_of_sight"]["rms_m"]
    before = level2.quality["checkpoints_2a"]["P"]["line_of_sight"]["rms_m"]
    pixel = level2.attrs["pixel_size_m"]
    assert before > 150.0 and los <= REDUCED_BLOCK_PX * pixel
    assert RATIO[0] <= los / adj["predicted_sigma_m"]["horizontal"] <= RATIO[1]
    # the second pass alone has no control point to make a level 2 of
    alone = ["process", str(rb / "pb.l0.h5"), "--levels", "2", "--out", str(tmp_path / "x")]
    assert main([*alone, "-q"]) == 2


#: Planted blunders among the tie points (pixels along the line in the second image).
TIE_BLUNDER_PX = 5.0


def test_tie_point_blunders_are_found_as_control_points_are(block) -> None:
    """Three tie points measured 5 px off in the second pass: data snooping (Baarda, the
    threshold of control points) rejects them and only them, and the block is as without."""
    import dataclasses

    a, b, (ta, tb) = block
    planted = np.array([3, 50, 120])
    line = tb.line.copy()
    line[planted] += TIE_BLUNDER_PX
    dirty = dataclasses.replace(tb, line=line)
    opts = ProcessingOptions()
    clean = adjust_block([[_strip(a)], [_strip(b)]], [[ta], [tb]], opts)[1][0]
    res = adjust_block([[_strip(a)], [_strip(b)]], [[ta], [dirty]], opts)[1][0]
    assert set(res.ties_rejected) == {tb.id[k] for k in planted}
    assert clean.ties_rejected == ()
    assert abs(_error_m(*b, res) - _error_m(*b, clean)) < 1.0
    assert res.product_tree(res.scene_index[0])["ties_rejected"] == list(res.ties_rejected)


#: The block run's level 2 on reduced scenes (100 m pixels): the control points' 0.3 px of
#: pointing error (30 m) dominates; a third of a pixel covers it.
BLOCK_RUN_PX = 0.33


#: Where GDAL and the product itself put a checkpoint differ by the round-off of map
#: coordinates of 1e6 m (1e-10 m); a millimetre is far below any misreading.
GDAL_ROUNDOFF_M = 1e-3


def _through_gdal_m(path: Path, product) -> float:
    """RMS (m) of where GDAL puts each checkpoint's pixel of a level 2 product, opened as
    written (the netCDF driver's first subdataset: its CRS and transform), against where
    the truth says that pixel looked at the reference height: the checkpoints' true map
    positions are the product's minus its reported errors, both in the product's CRS,
    which GDAL must read as the same."""
    import rasterio
    import rasterio.errors
    from rasterio.crs import CRS

    cp = product.quality["checkpoints"]["P"]
    x0, dx, _, y0, _, dy = product.map_grid.geotransform
    true_e = x0 + (cp["output_col"] + 0.5) * dx - cp["error_e_m"]
    true_n = y0 + (cp["output_row"] + 0.5) * dy - cp["error_n_m"]
    with warnings.catch_warnings():  # the container itself is not georeferenced: its bands are
        warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
        with rasterio.open(str(path)) as ds:
            first = ds.subdatasets[0]
    with rasterio.open(first) as band:
        assert band.crs == CRS.from_wkt(product.map_grid.crs_wkt)
        e, n = band.transform @ (cp["output_col"] + 0.5, cp["output_row"] + 0.5)
    return float(np.sqrt(np.mean((np.asarray(e) - true_e) ** 2 + (np.asarray(n) - true_n) ** 2)))


def test_station_runs_a_block_scenario(tmp_path) -> None:
    """``scenarios/blocks/two_passes.toml``: every pass run, their tie points found, level
    2 of both on one adjustment, in one command; the second pass has no control point.
    Each level 2 is also read through GDAL and its checkpoints placed by GDAL's reading of
    its georeferencing, against the truth."""
    import json

    import pystac

    from levels.products import read_product
    from station.cli import main
    from station.errors import ScenarioError
    from station.loader import load_scenario

    path = Path(__file__).resolve().parents[1] / "scenarios" / "blocks" / "two_passes.toml"
    out = tmp_path / "run"
    assert main(["run", str(path), "--out", str(out), "-q", "--no-quicklooks"]) == 0
    report = json.loads((out / "report.json").read_text())
    assert report["scenario"]["passes"] == ["two_passes_a", "two_passes_b"]
    assert report["ties"]["pairs"][0]["points"] >= 200
    ties = {p.name for p in (out / "ties").iterdir()}
    assert ties == {"two_passes_a.tie.csv", "two_passes_b.tie.csv"}
    for name in ("two_passes_a", "two_passes_b"):
        written = out / "block" / f"{name}_s000_2.nc"
        level2 = read_product(written, images=False)
        assert level2.geometry["adjustment"]["mode"] == "block"
        los = level2.quality["checkpoints"]["P"]["line_of_sight"]["rms_m"]
        assert los <= BLOCK_RUN_PX * level2.attrs["pixel_size_m"]
        # GDAL's reading of the georeferencing is ours to round-off (a half-pixel or a
        # CRS misread would move every checkpoint by tens of metres)
        assert _through_gdal_m(written, level2) == pytest.approx(los, abs=GDAL_ROUNDOFF_M)
        # level 3 on the block's model over the first pass's DEM: on the terrain as level 2
        # is at its reference height, the relief's displacement (2A's "ground") removed
        level3 = read_product(out / "block" / f"{name}_s000_3.nc", images=False)
        assert level3.geometry["adjustment"]["mode"] == "block"
        on_terrain = level3.quality["checkpoints"]["P"]["ground"]["rms_m"]
        assert on_terrain <= BLOCK_RUN_PX * level3.attrs["pixel_size_m"]
    relief = level3.quality["checkpoints"]["P"]["ground_2a"]["rms_m"]
    assert relief > 2 * on_terrain  # the pass 8.4° off nadir: its relief displacement
    children = pystac.Catalog.from_file(str(out / "catalog.json")).get_children()
    assert {c.id for c in children} >= {"two_passes_a", "block"}
    with pytest.raises(ScenarioError, match="block of several passes"):
        load_scenario(path)


TWIN_PASS = """
name = "tw"
seed = 21
[pass]
date_utc = "1998-02-20"
[[instrument]]
hrv = 2
twin = true
n_detectors = 600
n_lines = 600
[[instrument]]
hrv = 1
twin = true
n_detectors = 600
n_lines = 600
[world]
relief_m = 400.0
[gcps]
count = 12
hrvs = [1]
[dem]
spacing_arcsec = 3.0
error_rms_m = 5.0
[downlink]
bit_rate_mbps = 2.0
preamble_s = 0.1
postamble_s = 0.1
[processing]
levels = ["2A"]
"""


def test_a_twin_pass_in_a_block_carries_its_control_through_the_platform(tmp_path) -> None:
    """A twin pass (HRV2 aimed at the target, HRV1 56 km west with the 12 control points)
    and a second pass 26 days later over the target, with none: the tie points join the
    second pass to HRV2 only. The block takes the twin's two archives as one pass (one
    epoch: one platform, its attitude shared), so the control points reach HRV2 through the
    platform and the second pass through the tie points."""
    from levels.products import read_product
    from station.cli import main

    twin = tmp_path / "tw.toml"
    twin.write_text(TWIN_PASS)
    run = tmp_path / "tw"
    assert main(["run", str(twin), "--out", str(run), "-q", "--no-quicklooks"]) == 0
    sb, rb = run_pass(tmp_path, "pb", 60, "1998-03-18", 60, gcps=0)
    ties = tmp_path / "ties"
    pair = [str(run / "tw_hrv2_s000_2A.nc"), str(rb / "pb_s000_2A.nc")]
    assert main(["tie", *pair, "--out", str(ties), "-q"]) == 0
    assert {p.name for p in ties.iterdir()} == {"tw_hrv2.tie.csv", "pb.tie.csv"}
    options = tmp_path / "block.toml"
    options.write_text(
        '[processing]\nlevels = ["2A", "2"]\nadjustment = "block"\n'
        f'dem_path = "{run / "tw.dem.tif"}"\ntie_height_sigma_m = 5.0\n'
    )
    archives = [str(run / f"tw_hrv{h}.l0.h5") for h in (2, 1)] + [str(rb / "pb.l0.h5")]
    scenarios = ["--scenario", str(twin), "--scenario", str(twin), "--scenario", str(sb)]
    out = tmp_path / "block"
    args = ["process", *archives, "--options", str(options), "--ties", str(ties)]
    assert main([*args, *scenarios, "--out", str(out), "-q"]) == 0
    for name in ("tw_hrv2", "pb"):  # no control point of their own
        level2 = read_product(out / f"{name}_s000_2.nc", images=False)
        adj = level2.geometry["adjustment"]
        assert adj["mode"] == "block"
        los = level2.quality["checkpoints"]["P"]["line_of_sight"]["rms_m"]
        before = level2.quality["checkpoints_2a"]["P"]["line_of_sight"]["rms_m"]
        assert before > 150.0 and los <= BLOCK_RUN_PX * level2.attrs["pixel_size_m"]
        assert RATIO[0] <= los / adj["predicted_sigma_m"]["horizontal"] <= RATIO[1]


#: A control point's map position planted this far off (metres north): 20 of its 8 m σ.
GCP_BLUNDER_M = 160.0


def test_control_point_blunders_are_found_in_a_block(block) -> None:
    """One of the first pass's control points planted 160 m off: the block's data snooping
    (Baarda's, with the leverage of a row on the parameters) rejects it and only it, says
    so in the pass's adjustment, and the block is as without it."""
    import dataclasses

    a, b, (ta, tb) = block
    opts = ProcessingOptions()
    gcps = control_points(a[0])
    planted = 5
    lat = gcps.lat_rad.copy()
    lat[planted] += GCP_BLUNDER_M / 6.37e6
    dirty = dataclasses.replace(gcps, lat_rad=lat)
    clean = adjust_block([[_strip(a)], [_strip(b)]], [[ta], [tb]], opts)
    res = adjust_block([[_strip(a, dirty)], [_strip(b)]], [[ta], [tb]], opts)
    status = res[0][0].point_status
    assert [i for i, s in zip(res[0][0].point_id, status, strict=True) if s == "rejected"] == [
        gcps.id[planted]
    ]
    assert clean[0][0].point_status.count("rejected") == 0
    for k, p in enumerate((a, b)):
        assert abs(_error_m(*p, res[k][0]) - _error_m(*p, clean[k][0])) < 1.0
