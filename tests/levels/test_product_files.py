"""The product format on the files a station records (``scenarios/small_test.toml``'s run, made
in a process of its own): GDAL and xarray open a map product, the geometry objects read back
their trees, version 1 products still read, a product without its geometry refused, the
ephemeris' velocity convention carried, stored image bands read alike. ``levels`` alone."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from levels.errors import ProductError
from levels.geo.level1b import Level1BGeometry
from levels.geo.level2a import Level2AGeometry
from levels.products import read_product


def test_levels_alone_processes_an_l0_archive(run_dir: Path, tmp_path: Path) -> None:
    """The driver runs through the library's public face (``levels.api``) with ``station``
    never imported (a fresh interpreter says so)."""
    code = textwrap.dedent(f"""
        import json, sys
        from levels.api import ProcessingOptions, ProcessingRequest, process, read_l0
        from levels.api import read_product
        [made] = process(ProcessingRequest.of(read_l0({str(run_dir / "small_test.l0.h5")!r}),
                          ProcessingOptions(levels=("1A", "2A")), {str(tmp_path)!r},
                          "alone"))
        paths = [str(p) for s in made.scenes for p in s.paths.values()]
        levels = [read_product(p).level for p in paths]
        print(json.dumps({{"levels": levels,
                          "station": sorted(m for m in sys.modules
                                            if m.split(".")[0] == "station")}}))
    """)
    run = subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        check=False,
        cwd=tmp_path,
        timeout=300,
    )
    assert run.returncode == 0, run.stderr
    out = json.loads(run.stdout)
    assert out["station"] == []
    assert out["levels"] == ["1A", "2A"]


def test_geometry_objects_read_back_their_trees(run_dir: Path) -> None:
    """Each geometry object rebuilt from its product tree maps pixels as it did."""
    p2 = read_product(run_dir / "small_test_s000_2A.nc", images=False)
    g2 = Level2AGeometry.from_tree(p2.geometry["level_2a"], "P")
    assert g2.map_grid == p2.map_grid  # CRS, geotransform and shape
    cp = p2.quality["checkpoints"]["P"]
    line, col = g2.raw_of(cp["output_row"], cp["output_col"])
    # the checkpoints' output positions were solved through the same inverse grid
    assert np.abs(line - cp["raw_line"]).max() < 1e-6
    assert np.abs(col - cp["raw_column"]).max() < 1e-6
    p1 = read_product(run_dir / "small_test_s000_1B.h5", images=False)
    g1 = Level1BGeometry.from_tree(p1.geometry["level_1b"], "P")
    assert (g1.n_rows, g1.n_cols) == (p1.attrs["n_rows"], p1.attrs["n_cols"])
    cp = p1.quality["checkpoints"]["P"]
    i, j = g1.corrected_of(cp["raw_line"], cp["raw_column"])
    assert np.abs(i - cp["output_row"]).max() < 1e-9
    assert np.abs(j - cp["output_col"]).max() < 1e-9
    del p2.geometry["level_2a"]["bands"]
    with pytest.raises(ProductError, match="incomplete or damaged"):
        Level2AGeometry.from_tree(p2.geometry["level_2a"])


def test_a_product_without_its_geometry_is_refused(run_dir: Path, tmp_path: Path) -> None:
    import h5py

    src = run_dir / "small_test_s000_2A.nc"
    bad = tmp_path / src.name
    bad.write_bytes(src.read_bytes())
    with h5py.File(bad, "r+") as f:
        del f["geometry/level_2a"]
    with pytest.raises(ProductError, match="without its geometry/level_2a"):
        read_product(bad)


def test_the_ephemeris_velocity_convention_travels(run_dir: Path) -> None:
    """The emulated SPOT 1–4 bulletins carry the inertial velocity; the L0 archive says so
    and every product made from it repeats it (docs/l0.md)."""
    from levels.readers.l0 import read_l0

    archive = read_l0(run_dir / "small_test.l0.h5")
    assert archive.reference_velocity == "inertial"
    eph = archive.ephemeris
    # the bulletins' velocity against the motion of their own positions (Earth-fixed:
    # central differences over ±1 bulletin, curvature error ~0.03°). An inertial velocity
    # is turned from it by ω × r, about 4° · cos φ at SPOT's height (the real SPOT 2 scene
    # of refdata, at 40.7° N: 2.97°); an Earth-fixed one by nothing.
    r, t, v = eph.r_ecef_m[1:-1], eph.t_s, eph.v_ecef_m_per_s[1:-1]
    dr_dt = (eph.r_ecef_m[2:] - eph.r_ecef_m[:-2]) / (t[2:] - t[:-2])[:, None]

    def angle_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        cos = np.sum(a * b, axis=1) / np.linalg.norm(a, axis=1) / np.linalg.norm(b, axis=1)
        return np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))

    omega_x_r = np.cross([0.0, 0.0, 7.2921150e-5], r)
    expected = angle_deg(v, v - omega_x_r)
    assert expected.min() > 3.0  # the test can tell the two conventions apart
    assert angle_deg(dr_dt, v) == pytest.approx(expected, abs=0.1)
    p = read_product(run_dir / "small_test_s000_2A.nc", images=False)
    assert p.geometry["ephemeris"]["reference_velocity"] == "inertial"


def test_a_control_point_file_from_a_spreadsheet_reads_and_refusals_name_its_line(
    run_dir: Path, tmp_path
) -> None:
    """A spreadsheet's UTF-8 byte-order mark before the header is no part of the column
    ``id``; a refusal names the file's line (a comment and the header before the first
    point: its first point is line 3), not the row's rank among the points."""
    from levels.errors import GcpError
    from levels.readers.gcp import read_gcps

    text = (run_dir / "small_test.gcp.csv").read_text()
    bom = tmp_path / "bom.gcp.csv"
    bom.write_bytes(b"\xef\xbb\xbf" + text.encode())
    assert len(read_gcps(bom)) == len(read_gcps(run_dir / "small_test.gcp.csv"))
    lines = text.splitlines()
    first = next(k for k, ln in enumerate(lines, start=1) if ln.startswith("hrv1_p0000,"))
    bad = tmp_path / "bad.gcp.csv"
    bad.write_text(text.replace(",8,5,0.3,1\n", ",8,5,nan,1\n", 1))
    with pytest.raises(GcpError, match=f"line {first}: sigma_px = 'nan'"):
        read_gcps(bad)


def test_a_control_point_outside_the_image_is_refused(run_dir: Path) -> None:
    from levels.errors import GcpError
    from levels.readers.gcp import read_gcps

    with pytest.raises(GcpError, match="outside the image"):
        read_gcps(run_dir / "small_test.gcp.csv", n_lines=10, n_columns=10)
