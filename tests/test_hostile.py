"""Hostile inputs made from the run's own files (issue 57): each refused in one line, exit
2, in about a second, never a crash (exit 3), a hang or a machine's memory; nothing written
where it should not be."""

from __future__ import annotations

import json
import re
import shutil
import warnings
import zipfile
from pathlib import Path

import numpy as np
import pytest
from _cli import bounded, one_line

from levels.readers.bounded import MAX_METADATA_BYTES
from station.cli import EXIT_BAD_INPUT, main

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def dimap_zip(run_dir: Path, tmp_path_factory) -> Path:
    """The small run's 1A as SWH's zip."""
    out = tmp_path_factory.mktemp("dimap") / "scene.zip"
    assert main(["export", str(run_dir / "small_test_s000_1A.h5"), "--dimap", str(out), "-q"]) == 0
    return out


def _rezip(src: Path, dst: Path, change: dict[str, bytes]) -> Path:
    """``src``'s scene (its folder's members) with the members named in ``change``
    replaced (deflated)."""
    with zipfile.ZipFile(src) as z, zipfile.ZipFile(dst, "w", zipfile.ZIP_DEFLATED) as out:
        for info in z.infolist():
            if "/" in info.filename and not info.filename.startswith("truth/"):
                out.writestr(info.filename, change.get(info.filename, z.read(info)))
    return dst


def _dim_name(z: Path) -> str:
    with zipfile.ZipFile(z) as f:
        return next(n for n in f.namelist() if n.endswith("METADATA.DIM"))


# 1: a zip bomb's METADATA.DIM, and GDAL kept from its sibling


def test_a_metadata_that_inflates_beyond_the_cap_is_refused_unread(
    dimap_zip, tmp_path, capsys
) -> None:
    """A METADATA.DIM inflating to 1.5× the cap (a few hundred kB deflated): refused by
    its declared size, by process and locate, before it is parsed or handed to GDAL."""
    name = _dim_name(dimap_zip)
    with zipfile.ZipFile(dimap_zip) as z:
        dim = z.read(name)
    head = dim.index(b"?>") + 2
    bomb = dim[:head] + b"<!--" + b" " * int(1.5 * MAX_METADATA_BYTES) + b"-->" + dim[head:]
    z = _rezip(dimap_zip, tmp_path / "bomb.zip", {name: bomb})
    assert z.stat().st_size < 1e6
    with bounded():
        code = main(["process", str(z), "--out", str(tmp_path / "out"), "-q"])
        one_line(capsys, code, EXIT_BAD_INPUT, "METADATA.DIM", "MiB")
        one_line(capsys, main(["locate", str(z)]), EXIT_BAD_INPUT, "MiB")
    assert not (tmp_path / "out").exists()


def test_gdal_opens_the_scenes_image_without_reading_its_sibling_metadata(
    refdata, tmp_path
) -> None:
    """GDAL's TIFF driver parses a METADATA.DIM beside the image (its SPOT metadata
    reader: the IMAGERY domain); opened the project's way, it sees the image alone."""
    import rasterio

    from levels.readers.bounded import gdal_image_alone

    scene = refdata / "dimap" / "spot2_hrv1_P_19980220_izmit_METADATA.DIM"
    (tmp_path / "METADATA.DIM").write_bytes(scene.read_bytes())
    profile = {"driver": "GTiff", "width": 8, "height": 8, "count": 1, "dtype": "uint8"}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # no georeferencing: not what is checked
        with rasterio.open(tmp_path / "IMAGERY.TIF", "w", **profile) as ds:
            ds.write(np.ones((1, 8, 8), np.uint8))
        with rasterio.open(tmp_path / "IMAGERY.TIF") as ds:
            assert ds.tags(ns="IMAGERY").get("SATELLITEID") == "SPOT 2"  # GDAL reads it
        with gdal_image_alone(), rasterio.open(tmp_path / "IMAGERY.TIF") as ds:
            assert ds.tags(ns="IMAGERY") == {}


def test_an_empty_truncated_or_junk_zip_is_called_a_zip(dimap_zip, tmp_path, capsys) -> None:
    """Not "not a readable HDF5 file" nor "not an XML document": a broken zip, by name."""
    raw = dimap_zip.read_bytes()
    cases = {"empty.zip": b"", "cut.zip": raw[: len(raw) // 2], "junk.zip": b"junk " * 100}
    for name, data in cases.items():
        (tmp_path / name).write_bytes(data)
        for cmd in (
            ["process", str(tmp_path / name), "--out", str(tmp_path / "o"), "-q"],
            ["locate", str(tmp_path / name)],
        ):
            one_line(capsys, main(cmd), EXIT_BAD_INPUT, name, "zip")
    assert not (tmp_path / "o").exists()


# 5: sizes a DIMAP declares, before any scanning


def _dim_edited(dimap_zip: Path, tmp_path: Path, edit) -> Path:
    name = _dim_name(dimap_zip)
    with zipfile.ZipFile(dimap_zip) as z:
        text = z.read(name).decode()
    return _rezip(dimap_zip, tmp_path / "edited.zip", {name: edit(text).encode()})


def test_a_scene_declaring_100000_pixels_a_side_is_refused_at_once(
    dimap_zip, tmp_path, capsys
) -> None:
    """NROWS of 100 000 (16 full scenes long): no SPOT 1–4 level 1A scene; refused from
    the metadata, before the image is opened or scanned, without a scenario's advice."""

    def huge(t: str) -> str:
        return re.sub(r"<NROWS>\d+</NROWS>", "<NROWS>100000</NROWS>", t)

    z = _dim_edited(dimap_zip, tmp_path, huge)
    with bounded():
        code = main(["process", str(z), "--out", str(tmp_path / "out"), "-q"])
    line = one_line(capsys, code, EXIT_BAD_INPUT, "100000", "SPOT 1–4")
    assert "n_lines" not in line  # a scenario's advice, not a scene's


def test_locate_refuses_a_frame_off_its_own_image(dimap_zip, tmp_path, capsys) -> None:
    """Sizes that contradict the frame (NROWS halved): one of the two is wrong; refused,
    never a 'max error' of kilometres and exit 0."""

    def halved(t: str) -> str:
        n = int(re.search(r"<NROWS>(\d+)</NROWS>", t).group(1))
        return t.replace(f"<NROWS>{n}</NROWS>", f"<NROWS>{n // 2}</NROWS>")

    z = _dim_edited(dimap_zip, tmp_path, halved)
    one_line(capsys, main(["locate", str(z)]), EXIT_BAD_INPUT, "off the", "contradict")


def test_the_memory_estimate_counts_the_output_grids() -> None:
    """``pixel_size_m = 2`` on the small scene (200 m pixels: 10⁴ times the map grids'
    pixels): the estimate must exceed the 9.12 GiB the run was seen to fail allocating,
    where it said 0.28 GiB; the default pixel keeps the pass's own figure."""
    from dataclasses import replace

    from station.loader import load_scenario
    from station.preflight import MEMORY_BASE_BYTES, run_needs

    scn = load_scenario(ROOT / "scenarios" / "small_test.toml")
    fine = run_needs(replace(scn, processing=replace(scn.processing, pixel_size_m=2.0)))
    assert fine.memory_bytes > 9.12 * 2**30
    assert "2 m pixels" in fine.what
    assert run_needs(scn).memory_bytes < MEMORY_BASE_BYTES + 0.1 * 2**30


@pytest.mark.parametrize("value", ["1e-300", "0.1", "-1"])
def test_a_pixel_below_half_a_metre_is_refused_before_work(value, tmp_path, capsys) -> None:
    toml = tmp_path / "fine.toml"
    toml.write_text(
        (ROOT / "scenarios" / "small_test.toml").read_text()
        + f"\n[processing]\npixel_size_m = {value}\n"
    )
    code = main(["run", str(toml), "--check"])
    one_line(capsys, code, EXIT_BAD_INPUT, "pixel_size_m")


# 3: a control-point file of a million rows


def test_a_million_control_points_are_read_in_bounded_time(run_dir, tmp_path) -> None:
    """10⁶ rows (the small run's 12 points, renamed): read whole, the duplicate check a
    set's (it searched a list: 5·10¹¹ comparisons); and a repeated id still caught."""
    from levels.errors import GcpError
    from levels.readers.gcp import read_gcps

    lines = (run_dir / "small_test.gcp.csv").read_text().splitlines()
    head = [ln for ln in lines if ln.startswith("#")]
    header, body = lines[len(head)], lines[len(head) + 1 :]
    rows = []
    for i in range(10**6):
        f = body[i % len(body)].split(",")
        f[0] = f"p{i}"
        rows.append(",".join(f))
    big = tmp_path / "big.csv"
    big.write_text("\n".join([header, *rows]) + "\n")
    with bounded(120):
        assert len(read_gcps(big).id) == 10**6
    (tmp_path / "twice.csv").write_text("\n".join([header, *rows[:5000], rows[17]]) + "\n")
    with pytest.raises(GcpError, match="'p17' given twice"):
        read_gcps(tmp_path / "twice.csv")


# 6: one refusal rule for every single-file output


def test_single_file_outputs_never_replace_what_they_did_not_write(
    run_dir, tmp_path, capsys
) -> None:
    """A user's text file as --out of downlink, export --geotiff, gcps and capacity
    calibrate: refused before any work, the file as it was; an export replaces its own
    earlier export, never another product's."""
    notes = tmp_path / "notes.txt"
    notes.write_text("my notes\n")
    small = str(ROOT / "scenarios" / "small_test.toml")
    two_a, one_b = run_dir / "small_test_s000_2A.nc", run_dir / "small_test_s000_1B.h5"
    commands = [
        ["downlink", small, "--out", str(notes)],
        ["export", str(two_a), "--geotiff", "--out", str(notes)],
        ["capacity", "calibrate", "--out", str(notes)],
        ["gcps", str(run_dir / "small_test.l0.h5"), "--reference", str(two_a), "--dem",
         str(two_a), "--out", str(notes)],
    ]  # fmt: skip
    for cmd in commands:
        with bounded():
            one_line(capsys, main(cmd), EXIT_BAD_INPUT, "notes.txt", "not replaced")
    assert notes.read_text() == "my notes\n"
    tif = tmp_path / "e.tif"
    for _ in range(2):  # its own export: replaced
        assert main(["export", str(two_a), "--geotiff", "--out", str(tif)]) == 0
    capsys.readouterr()
    code = main(["export", str(one_b), "--geotiff", "--out", str(tif)])
    one_line(capsys, code, EXIT_BAD_INPUT, "level 2A", "level 1B")


def test_downlink_never_replaces_another_passs_archive(run_dir, tmp_path, capsys) -> None:
    """The run's own L0 of small_test as --out of another scenario's downlink: refused (it
    was replaced, and compare then found the shapes changed)."""
    import shutil

    l0 = tmp_path / "small_test.l0.h5"
    shutil.copy(run_dir / "small_test.l0.h5", l0)
    before = l0.read_bytes()
    other = str(ROOT / "scenarios" / "quickstart.toml")
    one_line(capsys, main(["downlink", other, "--out", str(l0)]), EXIT_BAD_INPUT, "small_test")
    assert l0.read_bytes() == before


def test_a_rerun_keeps_gdals_statistics_of_its_unchanged_files(tmp_path) -> None:
    """``gdalinfo -stats`` caches a product's statistics in ``<file>.aux.xml``: a rerun
    whose file is the same bytes carries it over (it deleted it), and lists it as not
    its own."""
    from station.outdir import MANIFEST

    out = tmp_path / "run"
    cli = ["run", str(ROOT / "scenarios" / "small_test.toml"), "--out", str(out), "-q",
           "--no-quicklooks"]  # fmt: skip
    assert main(cli) == 0
    cache = out / "small_test_s000_2A.nc.aux.xml"
    cache.write_text("<PAMDataset><Metadata/></PAMDataset>\n")
    assert main(cli) == 0
    assert cache.read_text() == "<PAMDataset><Metadata/></PAMDataset>\n"
    assert cache.name not in (out / MANIFEST).read_text().splitlines()


# 9–12: what a user's first hour meets


def test_an_empty_scenario_is_refused_not_run_as_a_full_scene(tmp_path, capsys) -> None:
    """0 bytes: every key has a default, and the defaults are a 60 km scene (190 s of work
    without a word); refused, saying where to start."""
    empty = tmp_path / "empty.toml"
    empty.write_bytes(b"")
    with bounded():
        code = main(["run", str(empty), "--out", str(tmp_path / "out")])
    one_line(capsys, code, EXIT_BAD_INPUT, "empty scenario", "quickstart.toml")
    assert not (tmp_path / "out").exists()


def test_every_kind_of_scenario_file_has_its_keys_described() -> None:
    from station.loader import describe_keys

    text = describe_keys()
    assert "[[passes]]" in text and "[sar]" in text
    assert "  azimuth_looks = " in text and "  target_lat_deg = " in text


def test_messages_name_what_went_wrong(run_dir, tmp_path, capsys) -> None:
    """An OS error as "file: reason" (not "[Errno 2] …"); a .E1 that is not one said so,
    not "not a readable HDF5 file"; two products of two kinds refused as such (exit 2),
    not "171 outside tolerance"."""
    one_line(capsys, main(["locate", str(tmp_path / "none.DIM")]), EXIT_BAD_INPUT,
             "none.DIM: No such file or directory")  # fmt: skip
    assert "Errno" not in capsys.readouterr().err
    (tmp_path / "junk.E1").write_bytes(b"junk" * 10)
    code = main(["process", str(tmp_path / "junk.E1"), "--out", str(tmp_path / "o"), "-q"])
    line = one_line(capsys, code, EXIT_BAD_INPUT, "junk.E1", "ENVISAT")
    assert "HDF5" not in line
    two_a, one_b = run_dir / "small_test_s000_2A.nc", run_dir / "small_test_s000_1B.h5"
    code = main(["compare", str(two_a), str(one_b)])
    one_line(capsys, code, EXIT_BAD_INPUT, "different kinds", "2A", "1B")


def test_a_dimap_packs_zip_is_processed_to_level_2_on_the_points_it_holds(
    dimap_zip, tmp_path
) -> None:
    """``export --dimap X.zip`` puts control_points.csv in the zip: ``process X.zip`` with
    level 2 finds them there (it looked for X.gcp.csv beside it)."""
    out = tmp_path / "out"
    assert main(["process", str(dimap_zip), "--levels", "1A,2A,2", "--out", str(out), "-q"]) == 0
    from levels.products import read_product

    p = read_product(out / "scene_s000_2.nc")
    status = json.loads(p.geometry["adjustment"]["points"]["status"])
    assert status.count("used") >= 10
    # the same pack as a directory
    pack = tmp_path / "pack"
    with zipfile.ZipFile(dimap_zip) as z:
        z.extractall(pack)
    cli = ["process", str(pack / "SCENE01"), "--levels", "1A,2A,2", "--out", str(tmp_path / "o2")]
    shutil.copy(pack / "control_points.csv", pack / "SCENE01" / "control_points.csv")
    assert main([*cli, "-q"]) == 0


def test_process_fills_the_size_and_valid_columns_and_says_its_checks(
    run_dir, tmp_path, capsys
) -> None:
    l0 = str(run_dir / "small_test.l0.h5")
    assert main(["process", l0, "--out", str(tmp_path / "o")]) == 0
    out = capsys.readouterr().out
    assert "  300×300    1.000" in out  # the 1A's size and valid share, as a run prints them
    assert main(["process", l0, "--out", str(tmp_path / "o2"), "--check"]) == 0
    line = capsys.readouterr().out.strip()
    assert line.startswith("small_test: checks passed;") and "GiB of memory" in line
    assert "{" not in line


def test_an_interrupted_capacity_study_leaves_no_empty_out(tmp_path, monkeypatch) -> None:
    """Ctrl-C during the simulation: --out was made (empty) by the check before it; the
    check now makes nothing, the directory only when written."""
    import station.capacity.study as study
    from station.capacity.config import load_capacity

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(study, "simulate", interrupted)
    scn = load_capacity(ROOT / "scenarios" / "capacity" / "cuiaba.toml")
    out = tmp_path / "deep" / "capacity"
    with pytest.raises(KeyboardInterrupt):
        study.run_study(scn, out, replications=1, plots=False)
    assert not (tmp_path / "deep").exists()
