"""Speed of the photogrammetric model on a real scene (one core).

Figures printed:
* image → ground of 1 000 000 image points (target: under 2 s on one core, issue 2);
* ground → image of 100 000 ground points (iterative inverse);
* the peer, measured in the same run: pyproj transforming the same 1 000 000 points from
  ECEF to geodetic, one step of our chain done by PROJ's C code; the ratio says how many
  such PROJ passes one full location costs.

Run: ``python benchmarks/bench_locate.py [METADATA.DIM]`` (default: the SPOT 5 Altai scene
in ../shared/refdata). Single-threaded BLAS is forced so that "one core" holds.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from _smoke import size  # noqa: E402
from pyproj import Transformer  # noqa: E402

from levels.readers import read_dimap  # noqa: E402

DEFAULT = (
    Path(__file__).resolve().parents[2]
    / "shared/refdata/dimap/spot5_hrg1_A_20050313_altai_METADATA.DIM"
)
TARGET_S = 2.0
N_POINTS = size(1_000_000, 20_000)
N_INVERSE = size(100_000, 2_000)


def _best_of(fn, repeat: int = 3) -> float:
    best = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def main(argv: list[str]) -> int:
    path = Path(argv[1]) if len(argv) > 1 else DEFAULT
    scene = read_dimap(path)
    model = scene.model()
    rng = np.random.default_rng(0)
    line = rng.uniform(0, scene.n_rows - 1, N_POINTS)
    col = rng.uniform(0, scene.n_cols - 1, N_POINTS)

    t_direct = _best_of(lambda: model.image_to_ground(line, col, 0.0))
    ground = model.image_to_ground(line[:N_INVERSE], col[:N_INVERSE], 0.0)
    t_inverse = _best_of(lambda: model.ground_to_image(ground.lat_rad, ground.lon_rad, 0.0))

    r, _ = model.sight(line, col)
    to_geod = Transformer.from_crs("EPSG:4978", "EPSG:4979", always_xy=True)
    x, y, z = (r[:, k].copy() for k in range(3))
    t_peer = _best_of(lambda: to_geod.transform(x, y, z))

    print(f"scene: {scene.name} ({path.name})")
    print(
        f"image -> ground, {N_POINTS:,} points: {t_direct:.3f} s "
        f"({N_POINTS / t_direct / 1e6:.2f} Mpoint/s); target {TARGET_S:.1f} s: "
        f"ratio target/measured {TARGET_S / t_direct:.2f}"
    )
    print(
        f"ground -> image, {N_INVERSE:,} points: {t_inverse:.3f} s "
        f"({N_INVERSE / t_inverse / 1e6:.3f} Mpoint/s)"
    )
    print(
        f"peer: pyproj ECEF -> geodetic, {N_POINTS:,} points: {t_peer:.3f} s; "
        f"full location / PROJ step = {t_direct / t_peer:.2f}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
