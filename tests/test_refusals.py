"""Data that looks valid but is wrong, the tool's own limits, and what compare must see
(issue "Reliability, second pass"): each case its exit code and its one line, nothing
written where it should not be."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest
from _cli import one_line, tree

from station.cli import EXIT_BAD_INPUT, EXIT_DIFFERENT, main
from station.reports import REPORTS

ROOT = Path(__file__).resolve().parents[1]
SMALL = ROOT / "scenarios" / "small_test.toml"
REFDATA_DIMAP = "spot2_hrv1_P_19980220_izmit_METADATA.DIM"


def _gcps_moved(src: Path, dst: Path, dlon: float = 0.0, rows: int | None = None, **sigma) -> Path:
    """``src``'s control points, longitudes moved by ``dlon`` degrees (the first ``rows``
    of them, or all), their σ replaced as given (``sigma_px=0.01``)."""
    lines = src.read_text().splitlines()
    head = [ln for ln in lines if ln.startswith("#")]
    header, body = lines[len(head)], lines[len(head) + 1 :]
    cols = header.split(",")
    out = []
    for k, ln in enumerate(body):
        f = ln.split(",")
        if rows is None or k < rows:
            f[cols.index("lon_deg")] = repr(float(f[cols.index("lon_deg")]) + dlon)
        for name, value in sigma.items():
            f[cols.index(name)] = repr(value)
        out.append(",".join(f))
    dst.write_text("\n".join([*head, header, *out]) + "\n")
    return dst


def _write_dem(
    path: Path,
    heights: float | np.ndarray,
    crs: str | None,
    origin: tuple[float, float] = (-56.3, -15.4),
    transform=None,
) -> Path:
    """A GeoTIFF DEM with ``crs`` or none: ``heights`` as given on ``transform``, or one
    height over 20 × 20 cells of 0.02° from ``origin`` (the small scene's north-west)."""
    import warnings

    import rasterio
    from rasterio.transform import from_origin

    h = np.asarray(heights, dtype=np.float32)
    h = np.full((20, 20), h, np.float32) if h.ndim == 0 else h
    with warnings.catch_warnings():  # rasterio's own use of affine's deprecated `*`
        warnings.simplefilter("ignore", PendingDeprecationWarning)
        with rasterio.open(
            path,
            "w",
            driver="GTiff",
            width=h.shape[1],
            height=h.shape[0],
            count=1,
            dtype="float32",
            crs=crs,
            transform=transform or from_origin(*origin, 0.02, 0.02),
        ) as d:
            d.write(h[None])
    return path


def _process(run_dir: Path, out: Path, *extra: str) -> int:
    return main(["process", str(run_dir / "small_test.l0.h5"), "--out", str(out), "-q", *extra])


# 2: level 2 judges its own fit; locate --gcps the same


def test_control_points_of_another_place_are_refused(run_dir, tmp_path, capsys) -> None:
    """Every point moved 18° (about 1900 km): none within the model's reach; exit 2 naming
    points, no product written."""
    far = _gcps_moved(run_dir / "small_test.gcp.csv", tmp_path / "far.csv", dlon=18.0)
    out = tmp_path / "out"
    code = _process(run_dir, out, "--levels", "2", "--gcps", str(far))
    one_line(capsys, code, EXIT_BAD_INPUT, "none of the 12 control points", "hrv1_p")
    assert not out.exists()


def test_a_fit_beyond_its_chi_squared_is_refused(run_dir, tmp_path, capsys) -> None:
    """The points claim 1 cm and 0.01 px when they are good to 8 m and 0.3 px: σ0 far
    beyond what the χ² test at 99.9 % allows; refused, the worst points named."""
    tight = _gcps_moved(
        run_dir / "small_test.gcp.csv", tmp_path / "tight.csv", sigma_ground_m=0.01, sigma_px=0.01
    )
    code = _process(run_dir, tmp_path / "out", "--levels", "2", "--gcps", str(tight))
    one_line(capsys, code, EXIT_BAD_INPUT, "control points rejected", "σ or the model")


def test_two_blunders_among_good_points_are_rejected_not_refused(run_dir, tmp_path) -> None:
    """Two points moved 0.05° (5 km): out of reach or snooped, rejected; the others fit."""
    two = _gcps_moved(run_dir / "small_test.gcp.csv", tmp_path / "two.csv", dlon=0.05, rows=2)
    out = tmp_path / "out"
    assert _process(run_dir, out, "--levels", "2", "--gcps", str(two)) == 0
    from levels.products import read_product

    p = read_product(out / "small_test_s000_2.nc")
    status = json.loads(p.geometry["adjustment"]["points"]["status"])
    assert status[:2] == ["rejected", "rejected"] and set(status[2:]) == {"used"}


def test_locate_with_another_scenes_points(run_dir, refdata, capsys) -> None:
    """The emulated pass's points on a real Izmit scene: exit 2, never ``RMS nan``."""
    dim = refdata / "dimap" / REFDATA_DIMAP
    code = main(["locate", str(dim), "--gcps", str(run_dir / "small_test.gcp.csv")])
    line = one_line(capsys, code, EXIT_BAD_INPUT, "within reach of the model")
    assert "nan" not in line


# 3, 4: compare sees the coordinates; compares process and campaign directories


def test_a_shifted_coordinate_is_caught(run_dir, tmp_path, capsys) -> None:
    """The ``x`` coordinate (xarray's georeferencing) moved 600 m from the GeoTransform
    (GDAL's): inspect and compare refuse the product as edited."""
    edited = tmp_path / "run"
    shutil.copytree(run_dir, edited)
    with h5py.File(edited / "small_test_s000_2A.nc", "r+") as f:
        f["x"][...] = f["x"][()] + 600.0
    code = main(["inspect", str(edited / "small_test_s000_2A.nc")])
    one_line(capsys, code, EXIT_BAD_INPUT, "coordinate 'x'", "600 m")
    code = main(["compare", str(run_dir), str(edited)])
    one_line(capsys, code, EXIT_BAD_INPUT, "coordinate 'x'")


def test_compare_sees_every_number_of_the_geometry(run_dir, tmp_path, capsys) -> None:
    """One ephemeris position moved 1 m, nothing else: compare names it (exit 1)."""
    edited = tmp_path / "run"
    shutil.copytree(run_dir, edited)
    with h5py.File(edited / "small_test_s000_2A.nc", "r+") as f:
        f["geometry/ephemeris/r_ecef_m"][0, 0] += 1.0
    code = main(["compare", str(run_dir), str(edited)])
    out = capsys.readouterr().out
    assert code == EXIT_DIFFERENT and "geometry/ephemeris/r_ecef_m" in out, out


def test_compare_process_and_campaign_directories(run_dir, tmp_path, capsys) -> None:
    """Two reprocessings, two campaigns of the same archive: identical (exit 0); one made
    with other levels differs (exit 1)."""
    a, b = tmp_path / "a", tmp_path / "b"
    assert _process(run_dir, a) == 0 and _process(run_dir, b) == 0
    assert main(["compare", str(a), str(b)]) == 0
    c1, c2 = tmp_path / "c1", tmp_path / "c2"
    for c in (c1, c2):
        assert main(["campaign", str(run_dir / "small_test.l0.h5"), "--out", str(c), "-q"]) == 0
    assert main(["compare", str(c1), str(c2)]) == 0
    only_1a = tmp_path / "only_1a"
    assert _process(run_dir, only_1a, "--levels", "1A") == 0
    capsys.readouterr()
    assert main(["compare", str(a), str(only_1a)]) == EXIT_DIFFERENT
    capsys.readouterr()
    code = main(["compare", str(a), str(c1)])  # a process directory and a campaign's
    one_line(capsys, code, EXIT_BAD_INPUT, "is a reprocessing", "a campaign", "different kinds")
    code = main(["compare", str(run_dir), str(a)])  # a run and a reprocessing
    one_line(capsys, code, EXIT_BAD_INPUT, "the run of a pass", "a reprocessing")
    # every report opens with one header (station.reports); an unknown format is named
    for d in (a, c1, run_dir):
        report = next(r for r in REPORTS if (d / r.file).is_file())
        head = json.loads((d / report.file).read_text())
        assert list(head)[:3] == ["format", "format_version", "software"]
        assert (head["format"], head["format_version"]) == (report.name, report.version)
    odd = tmp_path / "odd"
    odd.mkdir()
    (odd / "process.json").write_text('{"format": "someone-elses"}')
    code = main(["compare", str(odd), str(a)])
    one_line(capsys, code, EXIT_BAD_INPUT, "someone-elses", "no report this version knows")


def test_compare_of_level_2_names_one_control_point_moved(run_dir, tmp_path, capsys) -> None:
    """Level 2 stores an unbounded σ for what it does not estimate (inf): two reprocessings
    with the same points compare equal (inf − inf was a difference, so no level 2 could
    pass a regression comparison); one point moved by 0.001° (about 100 m) is named, in the
    adjustment it changed (exit 1)."""
    a, b = tmp_path / "a", tmp_path / "b"
    gcps = run_dir / "small_test.gcp.csv"
    moved = _gcps_moved(gcps, tmp_path / "moved.csv", dlon=0.001, rows=1)
    for out, points in ((a, gcps), (b, moved)):
        assert _process(run_dir, out, "--levels", "2", "--gcps", str(points)) == 0
    level2 = h5py.File(a / "small_test_s000_2.nc", "r")
    with level2:
        assert np.isinf(level2["geometry/adjustment/attitude_jump_sigma_rad"][()]).any()
    assert main(["compare", str(a), str(a)]) == 0
    capsys.readouterr()
    assert main(["compare", str(a), str(b)]) == EXIT_DIFFERENT
    out = capsys.readouterr().out
    assert "geometry/adjustment/pass_parameters" in out, out


def test_a_tolerance_file_holds_finite_numbers(run_dir, tmp_path, capsys) -> None:
    tol = tmp_path / "tol.toml"
    tol.write_text("[pixels]\nrms_counts = nan\n")
    code = main(["compare", str(run_dir), str(run_dir), "--tolerances", str(tol)])
    one_line(capsys, code, EXIT_BAD_INPUT, "rms_counts = nan", "finite")


# 5: names are names


@pytest.mark.parametrize("name", ["../evil", "/tmp/abs", "a/b", ".hidden"])
def test_a_name_is_not_a_path(name, run_dir, tmp_path, capsys) -> None:
    out = tmp_path / "out"
    code = _process(run_dir, out, "--name", name)
    one_line(capsys, code, EXIT_BAD_INPUT, f"--name = {name!r}")
    assert sorted(p.name for p in tmp_path.iterdir()) == []


# 6, 7: user errors are exit 2, checked before work


def test_user_errors_are_not_bugs(run_dir, tmp_path, refdata, monkeypatch, capsys) -> None:
    nocrs = _write_dem(tmp_path / "nocrs.tif", 400.0, None)
    opts = tmp_path / "opts.toml"
    opts.write_text(f'[processing]\nlevels = ["3"]\ndem_path = "{nocrs}"\n')
    code = _process(run_dir, tmp_path / "o1", "--options", str(opts))
    one_line(capsys, code, EXIT_BAD_INPUT, "no CRS")
    code = _process(run_dir, tmp_path / "o2", "--scheduler", "nonsense")
    one_line(capsys, code, EXIT_BAD_INPUT, "nonsense")
    code = _process(run_dir, tmp_path / "o3", "--workers", "4096")
    one_line(capsys, code, EXIT_BAD_INPUT, "4096 workers", "cores")
    for n in ("0", "-1"):  # both refused alike (0 was taken as "in this process")
        code = _process(run_dir, tmp_path / "o3", "--workers", n)
        one_line(capsys, code, EXIT_BAD_INPUT, f"--workers {n}", "positive number")
    tle = tmp_path / "binary.tle"
    tle.write_bytes(bytes(range(256)) * 4)
    scn = tmp_path / "tle.toml"
    scn.write_text(f'name = "t"\n[orbit]\nkind = "tle"\ntle_path = "{tle}"\n')
    code = main(["run", str(scn), "--out", str(tmp_path / "o4"), "-q"])
    one_line(capsys, code, EXIT_BAD_INPUT, "not a TLE file")
    accented = tmp_path / "accented.toml"
    accented.write_text('name = "Cuiabá"\n', encoding="utf-8")
    code = main(["run", str(accented), "--out", str(tmp_path / "o5"), "--check"])
    one_line(capsys, code, EXIT_BAD_INPUT, "ASCII letters", "'á' not ASCII", "'Cuiaba'")
    dim = refdata / "dimap" / REFDATA_DIMAP
    code = main(["locate", str(dim), "--rpc", str(tmp_path / "x_RPC.TXT"), "--heights", "0,1e9"])
    one_line(capsys, code, EXIT_BAD_INPUT, "--heights '0,1e9'")

    import station.cli.products as products

    def exhausted(_args) -> int:
        raise MemoryError("Unable to allocate 22.0 GiB")

    monkeypatch.setattr(products, "_inspect", exhausted)
    code = main(["inspect", "x.h5"])
    one_line(capsys, code, EXIT_BAD_INPUT, "out of memory", "22.0 GiB")
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
        ["nocrs.tif", "opts.toml", "binary.tle", "tle.toml", "accented.toml"]
    )


def test_a_run_too_large_for_the_machine_is_refused_at_once(tmp_path, capsys) -> None:
    """6000 detectors × 10⁶ lines: refused with the figure and the limit, before any work
    (no 22 GiB allocation minutes later); ``--check`` says the same."""
    scn = tmp_path / "huge.toml"
    scn.write_text('name = "huge"\n[instrument]\nn_detectors = 6000\nn_lines = 1000000\n')
    for extra in ([], ["--check"]):
        code = main(["run", str(scn), "--out", str(tmp_path / "out"), "-q", *extra])
        one_line(capsys, code, EXIT_BAD_INPUT, "GiB of memory", "6000 detectors")
    assert not (tmp_path / "out").exists()


def test_a_dem_off_the_pass_is_refused_before_any_scene(run_dir, tmp_path, capsys) -> None:
    """A DEM of another place: refused once GEO has placed the scenes, before the first
    is made (not after every other level)."""
    elsewhere = _write_dem(tmp_path / "elsewhere.tif", 300.0, "EPSG:4326", (10.0, 5.0))
    opts = tmp_path / "opts.toml"
    opts.write_text(f'[processing]\nlevels = ["1A", "3"]\ndem_path = "{elsewhere}"\n')
    code = _process(run_dir, tmp_path / "out", "--options", str(opts))
    one_line(capsys, code, EXIT_BAD_INPUT, "does not cover scene 0")
    assert not (tmp_path / "out").exists()


def test_an_archive_named_dot_is_not_a_name(run_dir, tmp_path, capsys) -> None:
    odd = tmp_path / "..l0.h5"
    shutil.copy(run_dir / "small_test.l0.h5", odd)
    code = main(["campaign", str(odd), "--out", str(tmp_path / "c"), "-q"])
    one_line(capsys, code, EXIT_BAD_INPUT, "cannot name products after this file")


def test_a_dem_is_checked_before_the_pass_is_emulated(tmp_path, capsys) -> None:
    """A level 3 DEM off the pass (its footprint traced on the geometry alone), missing,
    none, a world DEM not there, heights in feet: one line, before the pass is imaged."""
    feet = _write_dem(tmp_path / "feet.tif", 29_000.0, "EPSG:4326")  # Everest in feet
    away = _write_dem(tmp_path / "away.tif", 300.0, "EPSG:4326", (10.0, 5.0))
    cases = [
        (f'[processing]\nlevels = ["3"]\ndem_path = "{away}"\n', "does not cover the pass"),
        ('[processing]\nlevels = ["3"]\ndem_path = "missing.tif"\n', "not found"),
        ('[processing]\nlevels = ["3"]\n', "needs a DEM"),
        ('[world]\nkind = "dem"\ndem_path = "N00E010.hgt"\n', "not found"),
        (f'[processing]\nlevels = ["3"]\ndem_path = "{feet}"\n', "not metres on Earth"),
    ]
    for k, (table, words) in enumerate(cases):
        scn = tmp_path / f"s{k}.toml"
        scn.write_text(f'name = "s{k}"\n' + table)
        code = main(["run", str(scn), "--out", str(tmp_path / f"o{k}"), "-q"])
        one_line(capsys, code, EXIT_BAD_INPUT, words)
        assert not (tmp_path / f"o{k}").exists()


# 8, 10: an empty result is not a success; no line silently dropped


def test_a_run_that_made_nothing_is_not_a_success(tmp_path, capsys) -> None:
    """An outage from the 61st line on: the one scene below min_valid_share, skipped; the
    run and the reprocessing exit 2 saying so."""
    scn = tmp_path / "lost.toml"
    scn.write_text(
        SMALL.read_text() + "\n[channel]\noutage_start_s = 4.0\noutage_duration_s = 1000.0\n"
    )
    for command in ("process", "run"):
        code = main([command, str(scn), "--out", str(tmp_path / command), "-q"])
        one_line(capsys, code, EXIT_BAD_INPUT, "made no product")


@pytest.mark.parametrize(
    "scene_lines, made, skipped", [(200, 2, 0), (250, 1, 1)], ids=["made", "skipped"]
)
def test_the_tail_of_a_pass_is_made_or_said(scene_lines, made, skipped, run_dir, tmp_path) -> None:
    """300 lines cut every 200: the last 100 (half a scene) made as a partial scene; every
    250: the last 50 (a fifth) skipped, with the reason in process.json."""
    opts = tmp_path / "opts.toml"
    opts.write_text(f'[processing]\nlevels = ["1A"]\nscene_lines = {scene_lines}\n')
    out = tmp_path / "out"
    assert _process(run_dir, out, "--options", str(opts)) == 0
    report = json.loads((out / "process.json").read_text())
    assert len(report["products"]) == made and len(report["skipped"]) == skipped
    if skipped:
        assert "partial last scene of 50 lines" in report["skipped"][0]["reason"]
        assert "min_valid_share" in report["skipped"][0]["reason"]
    else:
        from levels.products import read_product

        last = read_product(out / "small_test_s001_1A.h5")
        assert last.bands["P"].image.shape[0] == 100


def test_a_scene_of_few_valid_lines_is_skipped() -> None:
    from levels.geo.scenes import SceneCut
    from levels.options import ProcessingOptions
    from levels.passes import _too_few_lines

    seen = np.zeros(600, dtype=bool)
    seen[100:107] = True
    reason = _too_few_lines(SceneCut(0, 0, 600), seen, 600, ProcessingOptions())
    assert reason.startswith("7 valid lines of 600") and "min_valid_share = 0.5" in reason
    seen[:] = True
    assert _too_few_lines(SceneCut(0, 0, 600), seen, 600, ProcessingOptions()) == ""


# 12: a closed pipe


def test_a_closed_pipe_is_not_an_error(run_dir) -> None:
    """``station compare … | head``: the reader leaves; no ``Broken pipe``, exit 0."""
    cmd = [sys.executable, "-m", "station.cli", "compare", str(run_dir), str(run_dir), "--json"]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    assert proc.stdout is not None
    proc.stdout.close()  # before it writes: its first write meets a closed pipe
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 0 and b"Broken pipe" not in err and b"Errno" not in err, err


def test_a_south_up_dem_is_the_same_dem(run_dir, tmp_path) -> None:
    """A DEM stored south-up (positive y step, rows from the south) is read where it is:
    level 3 over it is the level 3 over the same heights stored north-up."""
    from rasterio.transform import Affine

    lat = -15.2 - 0.01 * np.arange(80)  # north → south, 0.01°
    lon = -56.5 + 0.01 * np.arange(80)
    heights = (300.0 + 2000.0 * (lat[:, None] + 15.6) + 900.0 * (lon[None, :] + 56.1)).astype(
        np.float32
    )
    north_up = Affine(0.01, 0.0, -56.505, 0.0, -0.01, -15.195)
    south_up = Affine(0.01, 0.0, -56.505, 0.0, 0.01, -15.195 - 0.8)
    dirs = []
    for name, gt, h in (("north", north_up, heights), ("south", south_up, heights[::-1])):
        path = _write_dem(tmp_path / f"{name}.tif", h, "EPSG:4326", transform=gt)
        opts = tmp_path / f"{name}.toml"
        opts.write_text(f'[processing]\nlevels = ["3"]\ndem_path = "{path}"\n')
        out = tmp_path / f"out_{name}"
        assert _process(run_dir, out, "--options", str(opts)) == 0
        dirs.append(out)
    from levels.products import read_product

    a, b = (read_product(d / "small_test_s000_3.nc").bands["P"] for d in dirs)
    assert np.array_equal(a.valid, b.valid) and np.array_equal(a.image, b.image)


def test_heights_in_kilometres_are_said(run_dir, tmp_path, capsys) -> None:
    """A DEM in km over the small scene (0.45): made, with a warning naming the file."""
    heights = 0.45 + 0.05 * np.random.default_rng(1).random((20, 20))  # not whole numbers
    km = _write_dem(tmp_path / "km.tif", heights, "EPSG:4326")
    opts = tmp_path / "opts.toml"
    opts.write_text(f'[processing]\nlevels = ["3"]\ndem_path = "{km}"\n')
    code = main(
        [
            "process",
            str(run_dir / "small_test.l0.h5"),
            "--options",
            str(opts),
            "--out",
            str(tmp_path / "out"),
        ]
    )
    err = capsys.readouterr().err
    assert code == 0 and "kilometres rather than metres?" in err and "km.tif" in err, err


def test_a_failed_reprocessing_or_campaign_leaves_the_previous_one(run_dir, tmp_path, capsys):
    """Reprocessing into an earlier reprocessing's directory, then failing (control points
    out of reach; a campaign whose one archive is damaged makes nothing): the earlier
    products and reports, byte for byte."""

    out = tmp_path / "out"
    assert _process(run_dir, out) == 0
    before = tree(out)
    far = _gcps_moved(run_dir / "small_test.gcp.csv", tmp_path / "far.csv", dlon=18.0)
    code = _process(run_dir, out, "--levels", "2", "--gcps", str(far))
    one_line(capsys, code, EXIT_BAD_INPUT, "within reach", f"{out} left as it was")
    assert tree(out) == before
    camp = tmp_path / "camp"
    assert main(["campaign", str(run_dir / "small_test.l0.h5"), "--out", str(camp), "-q"]) == 0
    before = tree(camp)
    opts = tmp_path / "bad.toml"
    opts.write_text('[processing]\nlevels = ["3"]\ndem_path = "missing.tif"\n')
    code = main(
        [
            "campaign",
            str(run_dir / "small_test.l0.h5"),
            "--options",
            str(opts),
            "--out",
            str(camp),
            "-q",
        ]
    )
    one_line(capsys, code, EXIT_BAD_INPUT, "not published over the previous", "left as it was")
    assert tree(camp) == before


def test_a_control_point_far_off_is_one_console_line(run_dir, tmp_path, capsys) -> None:
    """One of the 12 points moved 1° (about 107 km): level 2 is made on the others
    (exit 0) and says so in one line naming the point, never silently."""
    far = _gcps_moved(run_dir / "small_test.gcp.csv", tmp_path / "one_far.csv", dlon=1.0, rows=1)
    code = main(["process", str(run_dir / "small_test.l0.h5"), "--out", str(tmp_path / "out"),
                 "--levels", "2", "--gcps", str(far)])  # fmt: skip
    err = capsys.readouterr().err
    assert code == 0, err
    said = [ln for ln in err.splitlines() if "control point" in ln]
    assert len(said) == 1 and "hrv1_p0000" in said[0] and "not used" in said[0], err


def test_export_says_where_it_cannot_write(run_dir, tmp_path, capsys) -> None:
    """``--out`` under a file: exit 2 naming the file; ``--out`` a directory: the product's
    name in it; GDAL's errors, which carry no errno, said without "[Errno None] None"."""
    from levels.files import atomic_path

    product = run_dir / "small_test_s000_2A.nc"
    blocked = tmp_path / "a_file"
    blocked.write_text("")
    code = main(["export", str(product), "--geotiff", "--out", str(blocked / "x.tif")])
    one_line(capsys, code, EXIT_BAD_INPUT, f"{blocked} is a file, not a directory")
    into = tmp_path / "exports"
    into.mkdir()
    assert main(["export", str(product), "--geotiff", "--out", str(into)]) == 0
    assert (into / "small_test_s000_2A.tif").is_file()
    with pytest.raises(OSError) as caught, atomic_path(tmp_path / "y.tif"):
        raise OSError("Attempt to create new tiff file failed: Permission denied")
    assert "Errno" not in str(caught.value) and "Permission denied (writing" in str(caught.value)


def test_a_rerun_never_deletes_what_the_station_did_not_write(
    run_dir, tmp_path, monkeypatch, capsys
) -> None:
    """A run lists its own files (``station.outdir.MANIFEST``); a rerun into it refuses
    (exit 2, naming them) the user's notes and analyses there, and replaces it once they
    are moved; GDAL's ``.aux.xml`` beside a product is the product's; an export goes to
    the current directory, not into the run."""
    from station.outdir import MANIFEST

    scenario = Path(__file__).resolve().parents[1] / "scenarios" / "small_test.toml"
    out = tmp_path / "run"
    shutil.copytree(run_dir, out)
    own = (out / MANIFEST).read_text().splitlines()
    assert "report.json" in own and "small_test_s000_2A.nc" in own and MANIFEST in own
    (out / "small_test_s000_2A.nc.aux.xml").write_text("<PAMDataset/>")  # GDAL's
    (out / "notes.txt").write_text("seen on 27 Nov")
    (out / "analysis").mkdir()
    (out / "analysis" / "fig.png").write_bytes(b"")
    args = ["run", str(scenario), "--out", str(out), "-q", "--no-quicklooks"]
    code = main(args)
    one_line(capsys, code, EXIT_BAD_INPUT, "did not write", "analysis/fig.png", "notes.txt")
    assert (out / "notes.txt").read_text() == "seen on 27 Nov"  # nothing touched
    monkeypatch.chdir(tmp_path)
    assert main(["export", str(out / "small_test_s000_2A.nc"), "--geotiff", "-q"]) == 0
    assert (tmp_path / "small_test_s000_2A.tif").is_file()
    shutil.move(out / "notes.txt", tmp_path / "notes.txt")
    shutil.rmtree(out / "analysis")
    assert main(args) == 0
    # GDAL's cache of the unchanged 2A carried into the new run, still not the station's
    assert (out / "small_test_s000_2A.nc.aux.xml").read_text() == "<PAMDataset/>"
