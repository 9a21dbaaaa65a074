"""How well a scene's 1B sits under its own RPCs, as GDAL sees it (issue 49, finding 7).

The 1A and the 1B of one scene are exported (``station export --geotiff``: their RPCs in
GDAL's RPC metadata) and warped by GDAL (``gdalwarp -rpc``, cubic, at the scene's
reference height) onto the scene's 2A grid; then, tile by tile, the shift between the two
warped images (``levels.quality.image_shift_px``). Both go through the same warp, so the
shift is the 1B's own: its pixels against where its RPCs put them, relative to the 1A's
(whose RPCs describe raw pixels exactly, to their fit error). The same against the 2A
gives the measurement's floor on the scene (the 2A's resampling is not GDAL's).

    python tools/rpc_tiles.py RUN_DIR STEM [TILE]      # e.g. runs/quickstart quickstart_s000 128

Measured (2026-11-27): the quickstart's scene 0, 128-px tiles: the 1B against the 1A
0.072 px RMS, worst 0.164 (nearest raw line, INPE's: 0.232, worst 0.414); the 1A against
the 2A 0.086, worst 0.182 (the floor). ``small_test``, 100-px tiles: 0.036 px RMS, worst
0.061 (nearest: 0.360, worst 0.408).
"""

from __future__ import annotations

import json
import sys
import tempfile
from pathlib import Path
from typing import Any

import numpy as np


def warped(run: Path, stem: str, level: str, band: str = "P") -> np.ndarray:
    """The scene's ``level`` product (1A, 1B) through GDAL's RPC warp onto its 2A grid."""
    import rasterio
    import rasterio.warp
    from affine import Affine
    from rasterio.enums import Resampling

    from levels.export import write_geotiff
    from levels.products import read_product

    a2 = read_product(run / f"{stem}_2A.nc")
    grid = a2.map_grid
    assert grid is not None
    height = json.loads(a2.provenance["processing"])["reference_height_m"]
    out = np.zeros(a2.bands[band].image.shape, np.float32)
    with tempfile.TemporaryDirectory() as d:
        tif = write_geotiff(read_product(run / f"{stem}_{level}.h5"), Path(d) / "x.tif")
        with rasterio.open(tif) as ds:
            rasterio.warp.reproject(
                rasterio.band(ds, 1),
                out,
                rpcs=ds.rpcs,
                src_crs="EPSG:4326",
                dst_transform=Affine.from_gdal(*grid.geotransform),
                dst_crs=grid.crs_wkt,
                resampling=Resampling.cubic,
                dst_nodata=0,
                RPC_HEIGHT=height,
            )
    return out


def tile_shifts(a: np.ndarray, b: np.ndarray, valid: np.ndarray, tile: int) -> np.ndarray:
    """The shift (px) between ``a`` and ``b`` in every ``tile``² tile valid at 90 %."""
    from levels.quality import image_shift_px

    rows, cols = a.shape
    out = []
    for r in range(0, rows - tile + 1, tile):
        for c in range(0, cols - tile + 1, tile):
            m = valid[r : r + tile, c : c + tile]
            if m.mean() >= 0.9:
                w = (slice(r, r + tile), slice(c, c + tile))
                out.append(float(np.hypot(*image_shift_px(a[w], b[w], m))))
    return np.array(out)


def rpc_tiles(run: Path, stem: str, tile: int = 128) -> dict[str, Any]:
    """The 1B against the 1A through GDAL's RPC warp, and the 1A against the 2A (the
    floor), tile by tile: each's tiles, RMS and worst shift (px)."""
    from levels.products import read_product

    a1, b1 = warped(run, stem, "1A"), warped(run, stem, "1B")
    a2 = read_product(run / f"{stem}_2A.nc").bands["P"]
    figures = {}
    for name, (x, y, ok) in {
        "1B_vs_1A": (a1, b1, (a1 > 0) & (b1 > 0)),
        "1A_vs_2A": (a2.image.astype(np.float32), a1, a2.valid & (a1 > 0)),
    }.items():
        s = tile_shifts(x, y, ok, tile)
        figures[name] = {
            "tiles": int(s.size),
            "rms_px": float(np.sqrt(np.mean(s**2))) if s.size else float("nan"),
            "worst_px": float(s.max()) if s.size else float("nan"),
        }
    return figures


def main(argv: list[str]) -> int:
    if len(argv) < 2:
        print(__doc__)
        return 2
    tile = int(argv[2]) if len(argv) > 2 else 128
    for name, f in rpc_tiles(Path(argv[0]), argv[1], tile).items():
        print(
            f"{name}: {f['tiles']} tiles of {tile} px; RMS {f['rms_px']:.3f} px, "
            f"worst {f['worst_px']:.3f} px"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
