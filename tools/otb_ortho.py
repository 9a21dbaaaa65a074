"""OTB's orthorectification of our exported 1A (or 1B), through the ``.geom`` written beside
it, against our own 2A of the scene (issue 57, finding 14).

    station run scenarios/quickstart.toml --out runs/quickstart
    station export runs/quickstart/quickstart_s000_1A.h5 --geotiff --out q1A.tif
    python tools/otb_ortho.py q1A.tif runs/quickstart/quickstart_s000_2A.nc [TILE]

``otbcli_OrthoRectification`` (Debian's otb-bin) warps the GeoTIFF by its sensor model (the
RPCs of the keyword list: OTB 8 reads RPC tags only from its own GeoTIFFs) onto the 2A's
grid (its UTM zone, corner, size and pixel), at the 2A's reference height above the
ellipsoid, bicubic; then, tile by tile, the shift between the two images
(``levels.reference.phase_shifts``). Printed: the tiles, the mean, RMS and worst shift.

Measured (2026-12-01): the quickstart's 1A, 128-px tiles, 0.021 px RMS, worst 0.032; its 1B
0.048, worst 0.086 (the 1B's resampling and its RPCs' fit); ``small_test``'s 1A, 64-px
tiles, 0.014 px RMS.
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
import warnings
from pathlib import Path

import numpy as np


def main() -> int:
    import pyproj
    import rasterio

    from levels.products import read_product
    from levels.reference import phase_shifts

    tif, two_a = Path(sys.argv[1]), Path(sys.argv[2])
    n = int(sys.argv[3]) if len(sys.argv) > 3 else 128
    product = read_product(two_a)
    grid = product.map_grid
    assert grid is not None
    gt = grid.geotransform
    epsg = pyproj.CRS.from_wkt(grid.crs_wkt).to_epsg()
    if epsg is None or epsg // 100 not in (326, 327):
        raise SystemExit(f"{two_a}: not on a UTM grid (EPSG {epsg})")
    height = float(product.geometry.get("reference_height_m", 450.0))
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "otb.tif"
        cmd = ["otbcli_OrthoRectification", "-io.in", str(tif), "-io.out", str(out), "float",
               "-map", "utm", "-map.utm.zone", str(epsg % 100), "-map.utm.northhem",
               str(int(epsg // 100 == 326)), "-outputs.mode", "auto",
               "-outputs.ulx", str(gt[0]), "-outputs.uly", str(gt[3]),  # the grid's corner
               "-outputs.sizex", str(grid.n_cols), "-outputs.sizey", str(grid.n_rows),
               "-outputs.spacingx", str(gt[1]), "-outputs.spacingy", str(gt[5]),
               "-elev.default", str(height), "-interpolator", "bco",
               "-opt.gridspacing", str(gt[1])]  # fmt: skip
        done = subprocess.run(cmd, capture_output=True, text=True)
        if done.returncode:
            raise SystemExit(done.stderr[-2000:])
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            with rasterio.open(out) as ds:
                otb = ds.read(1).astype(np.float64)
    band = next(iter(product.bands.values()))
    ours, valid = band.image.astype(np.float64), band.valid & (otb > 0)
    shifts = []
    for i in range(0, ours.shape[0] - n, n):
        for j in range(0, ours.shape[1] - n, n):
            if valid[i : i + n, j : j + n].all():
                s, _ = phase_shifts(
                    ours[None, i : i + n, j : j + n], otb[None, i : i + n, j : j + n]
                )
                shifts.append(s[0])
    if not shifts:
        raise SystemExit("no tile of the 2A wholly valid under OTB's image")
    s = np.array(shifts)
    print(
        f"OTB's ortho of {tif.name} against {two_a.name}: {len(s)} tiles of {n} px; mean "
        f"({s[:, 0].mean():+.3f}, {s[:, 1].mean():+.3f}) px, RMS "
        f"{np.sqrt((s**2).sum(axis=1).mean()):.3f} px, worst {np.hypot(*s.T).max():.3f} px"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
