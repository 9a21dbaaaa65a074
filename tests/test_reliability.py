"""A full disk, a kill, a damaged file or a hostile name: one line, the documented exit code,
nothing half-written, nothing outside ``--out`` (the station's exit codes: ``station.cli``)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import h5py
import numpy as np
import pytest
from _cli import one_line, tree

from station.cli import EXIT_BAD_INPUT, EXIT_DIFFERENT, EXIT_INTERNAL, EXIT_INTERRUPTED, main

ROOT = Path(__file__).resolve().parents[1]
SMALL = ROOT / "scenarios" / "small_test.toml"


def _no_partials(d: Path) -> None:
    assert not list(d.rglob(".*.partial")), list(d.rglob(".*.partial"))


def test_a_full_disk_is_one_line_and_nothing_half_written(tmp_path, monkeypatch, capsys) -> None:
    """The disk fills while a product is written: HDF5 never writes to the disk itself
    (levels.hdf5.new_hdf5), so the final write fails cleanly, its temporary file goes,
    and the run directory does not claim a finished run."""
    real = Path.write_bytes

    def full(self: Path, data) -> int:
        if self.name.endswith(".partial") and "_s000_1B" in self.name:
            raise OSError(28, "No space left on device")
        return real(self, data)

    monkeypatch.setattr(Path, "write_bytes", full)
    out = tmp_path / "run"
    code = main(["run", str(SMALL), "--out", str(out), "--quiet", "--no-quicklooks"])
    one_line(capsys, code, EXIT_BAD_INPUT, "No space left on device", "_s000_1B.h5")
    _no_partials(out)
    assert not (out / "report.json").exists() and not (out / "small_test_s000_1B.h5").exists()


def test_interrupt_and_internal_error_have_their_own_codes(monkeypatch, capsys) -> None:
    import station.cli.products as products

    def interrupted(_args) -> int:
        raise KeyboardInterrupt

    def buggy(_args) -> int:
        return 1 // 0

    monkeypatch.setattr(products, "_inspect", interrupted)
    code = main(["inspect", "x.h5"])
    one_line(capsys, code, EXIT_INTERRUPTED, "interrupted")
    monkeypatch.setattr(products, "_inspect", buggy)
    code = main(["inspect", "x.h5"])
    line = one_line(capsys, code, EXIT_INTERNAL, "internal error", "ZeroDivisionError")
    assert "STATION_DEBUG" in line


@pytest.mark.parametrize(
    "toml, words",
    [
        ('name = "../../x"\n', ["name = '../../x'"]),
        ('name = "a/b"\n', ["name = 'a/b'"]),
        ('name = ""\n', ["name = ''"]),
        ('[processing]\ncrs = "EPSG:99999"\n', ["EPSG:99999"]),
        ("[instrument]\nn_lines = 1\n", ["n_lines = 1"]),
    ],
)
def test_a_scenario_is_checked_before_any_work(toml, words, tmp_path, capsys) -> None:
    scn = tmp_path / "s.toml"
    scn.write_text(toml)
    out = tmp_path / "out"
    code = main(["run", str(scn), "--out", str(out), "--quiet"])
    one_line(capsys, code, EXIT_BAD_INPUT, *words)
    assert not out.exists()  # nothing written, and nothing above --out
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.toml"]


def test_an_unwritable_output_fails_first(tmp_path, capsys) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("")
    code = main(["run", str(SMALL), "--out", str(blocker / "run"), "--quiet"])
    one_line(capsys, code, EXIT_BAD_INPUT, "cannot write in")
    code = main(
        [
            "capacity",
            str(ROOT / "scenarios" / "capacity" / "cuiaba.toml"),
            "--out",
            str(blocker / "cap"),
            "--replications",
            "1",
        ]
    )
    one_line(capsys, code, EXIT_BAD_INPUT, "cannot write in")


def test_a_reused_run_directory(run_dir, tmp_path, capsys) -> None:
    """Rerun into it: the earlier run's files of levels not asked this time go; another
    scenario's run there is refused, not mixed in."""
    out = tmp_path / "run"
    shutil.copytree(run_dir, out)
    (out / ".small_test_s000_2A.nc.999999999.partial").write_bytes(b"killed")
    only_1a = tmp_path / "only_1a.toml"
    only_1a.write_text(SMALL.read_text() + '\n[processing]\nlevels = ["1A"]\n')
    assert main(["run", str(only_1a), "--out", str(out), "--quiet", "--no-quicklooks"]) == 0
    capsys.readouterr()
    assert sorted(p.name for p in out.glob("*.h5")) == ["small_test.l0.h5", "small_test_s000_1A.h5"]
    _no_partials(out)
    other = tmp_path / "other.toml"
    other.write_text('name = "other"\n')
    code = main(["run", str(other), "--out", str(out), "--quiet"])
    one_line(capsys, code, EXIT_BAD_INPUT, "holds a run of scenario 'small_test'")


def test_a_full_disk_in_a_rerun_leaves_the_previous_run_whole(
    run_dir, tmp_path, monkeypatch, capsys
) -> None:
    """The rerun builds beside the run and replaces it only when complete: the disk filling
    mid-rerun leaves the earlier run byte for byte, and the line says so."""
    out = tmp_path / "run"
    shutil.copytree(run_dir, out)
    before = tree(out)
    real = Path.write_bytes

    def full(self: Path, data) -> int:
        if self.name.endswith(".partial") and "_s000_2A" in self.name:
            raise OSError(28, "No space left on device")
        return real(self, data)

    monkeypatch.setattr(Path, "write_bytes", full)
    code = main(["run", str(SMALL), "--out", str(out), "--quiet", "--no-quicklooks"])
    one_line(capsys, code, EXIT_BAD_INPUT, "No space left on device", f"{out} left as it was")
    assert tree(out) == before
    assert [p.name for p in tmp_path.iterdir()] == ["run"]  # no staging directory left


def test_a_sigint_in_a_rerun_leaves_the_previous_run_whole(run_dir, tmp_path) -> None:
    """Ctrl-C (a real SIGINT to a ``station run`` process) once the rerun has recorded its
    L0 archive in its staging directory: exit 130, the earlier run byte for byte."""
    import os
    import signal
    import subprocess
    import sys
    import time

    out = tmp_path / "run"
    shutil.copytree(run_dir, out)
    before = tree(out)
    cmd = [sys.executable, "-m", "station.cli", "run", str(SMALL), "--out", str(out), "-q"]
    # a suite started in the background by a shell without job control (`pytest &`) runs with
    # SIGINT ignored, and a child inherits that: it would never see the Ctrl-C. The child is
    # given Python's own handler, which exec resets to the default and Python maps to
    # KeyboardInterrupt, as in a terminal.
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        proc = subprocess.Popen(cmd, stderr=subprocess.PIPE, text=True)
    finally:
        signal.signal(signal.SIGINT, previous)
    try:
        deadline = time.monotonic() + 120
        while not list(tmp_path.glob(".run.*.staging/small_test.gcp.csv")):
            assert proc.poll() is None and time.monotonic() < deadline, "never got to record"
            time.sleep(0.05)
        os.kill(proc.pid, signal.SIGINT)
        _, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == EXIT_INTERRUPTED, err
    assert f"{out} left as it was" in err and "Traceback" not in err, err
    assert tree(out) == before
    assert [p.name for p in tmp_path.iterdir()] == ["run"]


def test_an_output_directory_is_replaced_only_if_it_is_ours(run_dir, tmp_path, capsys) -> None:
    """The run replaces its directory whole: the user's own files there, the current
    directory, or a directory holding the inputs are refused before any work."""
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "thesis.tex").write_text("years of work")
    code = main(["run", str(SMALL), "--out", str(mine), "--quiet"])
    one_line(capsys, code, EXIT_BAD_INPUT, "not a run of scenario 'small_test'", "thesis.tex")
    assert (mine / "thesis.tex").read_text() == "years of work"
    code = main(["process", str(run_dir / "small_test.l0.h5"), "--out", str(run_dir), "-q"])
    one_line(capsys, code, EXIT_BAD_INPUT, "holds the input")
    code = main(["campaign", str(run_dir), "--out", str(run_dir.parent), "-q"])
    one_line(capsys, code, EXIT_BAD_INPUT, "holds the input")


def _damage(kind: str, src: Path, dst: Path) -> None:
    shutil.copy(src, dst)
    if kind == "truncated":
        dst.write_bytes(src.read_bytes()[: src.stat().st_size // 2])
        return
    if kind == "flipped_image_bit":
        with h5py.File(dst) as f:
            info = f["P"].id.get_chunk_info(0)
        b = bytearray(dst.read_bytes())
        b[info.byte_offset + info.size // 2] ^= 0x10
        dst.write_bytes(bytes(b))
        return
    if kind == "flipped_header_bytes":
        b = bytearray(dst.read_bytes())
        for k in range(40, 48):
            b[k] ^= 0xFF
        dst.write_bytes(bytes(b))
        return
    with h5py.File(dst, "r+") as f:
        if kind == "no_scene":
            del f["geometry/scene"]
        elif kind == "no_level_2a":
            del f["geometry/level_2a"]
        elif kind == "no_inverse_grid":
            del f["geometry/level_2a/bands/P/inverse_grid"]
        elif kind == "no_geotransform":
            del f["crs"].attrs["GeoTransform"]
        elif kind == "bad_crs_wkt":
            f["crs"].attrs["crs_wkt"] = "PROJCS[nonsense"
        elif kind == "no_valid_mask":
            del f["P_valid"]
        elif kind == "other_format":
            f.attrs["format_version"] = 99


DAMAGES = [
    "truncated",
    "flipped_image_bit",
    "flipped_header_bytes",
    "no_scene",
    "no_level_2a",
    "no_inverse_grid",
    "no_geotransform",
    "bad_crs_wkt",
    "no_valid_mask",
    "other_format",
]


@pytest.mark.parametrize("kind", DAMAGES)
def test_compare_never_passes_a_damaged_product(kind, run_dir, tmp_path, capsys) -> None:
    """A regression campaign trusts exit 0: a damaged product is bad input (2), or a
    difference (1), never equal; inspect and export say so in one line too."""
    src = run_dir / "small_test_s000_2A.nc"
    bad = tmp_path / src.name
    _damage(kind, src, bad)
    code = main(["compare", str(src), str(bad)])
    err = capsys.readouterr().err
    assert code in (EXIT_DIFFERENT, EXIT_BAD_INPUT) and "Traceback" not in err
    for args in (
        ["inspect", str(bad)],
        ["export", str(bad), "--geotiff", "--out", str(tmp_path / "x.tif")],
    ):
        code = main(args)
        out = capsys.readouterr()
        if code != 0:  # a damage inspect does not read (an image bit) may pass it
            assert code == EXIT_BAD_INPUT and len(out.err.splitlines()) == 1, out.err
    _no_partials(tmp_path)


@pytest.mark.parametrize("kind", ["no_report", "no_l0", "empty_l0", "flipped_l0_bit", "killed"])
def test_compare_never_passes_a_damaged_run(kind, run_dir, tmp_path, capsys) -> None:
    b = tmp_path / "b"
    shutil.copytree(run_dir, b)
    l0 = b / "small_test.l0.h5"
    if kind in ("no_report", "killed"):
        (b / "report.json").unlink()
        if kind == "killed":
            (b / "small_test_s000_2A.nc").unlink()
    elif kind == "no_l0":
        l0.unlink()
    elif kind == "empty_l0":
        l0.write_bytes(b"")
    elif kind == "flipped_l0_bit":
        with h5py.File(l0) as f:
            info = f["bands/P/counts"].id.get_chunk_info(0)
        data = bytearray(l0.read_bytes())
        data[info.byte_offset + 7] ^= 0x01
        l0.write_bytes(bytes(data))
    code = main(["compare", str(run_dir), str(b)])
    capsys.readouterr()
    assert code in (EXIT_DIFFERENT, EXIT_BAD_INPUT)


def test_a_flipped_bit_in_the_l0_ephemeris_is_caught(run_dir, tmp_path, capsys) -> None:
    """One flipped bit in an ephemeris point moved products by 32 m unseen: the checksum
    of its chunk now stops the processing with one line."""
    l0 = tmp_path / "small_test.l0.h5"
    shutil.copy(run_dir / "small_test.l0.h5", l0)
    with h5py.File(l0) as f:
        info = f["ephemeris/r_ecef_m"].id.get_chunk_info(0)
    data = bytearray(l0.read_bytes())
    data[info.byte_offset + 13] ^= 0x04
    l0.write_bytes(bytes(data))
    code = main(["process", str(l0), "--out", str(tmp_path / "p")])
    one_line(capsys, code, EXIT_BAD_INPUT, "checksum does not match", "ephemeris/r_ecef_m")


def test_every_command_says_what_it_does(capsys) -> None:
    from station.cli import _parser

    parser = _parser()
    sub = next(a for a in parser._actions if a.dest == "command")
    for name, p in sub.choices.items():
        assert p.description and len(p.description) > 40, name
    with pytest.raises(SystemExit) as done:
        main(["--version"])
    assert done.value.code == 0 and capsys.readouterr().out.startswith("station ")


def test_the_report_names_its_run(run_dir) -> None:
    report = json.loads((run_dir / "report.json").read_text())
    assert report["scenario"]["name"] == "small_test" and report["scenario"]["sha256"]
    assert np.all([p["file"].startswith("small_test") for p in report["products"]])
