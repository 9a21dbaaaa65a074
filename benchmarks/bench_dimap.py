"""Speed of the DIMAP route: a full P level-1A scene as SPOT World Heritage delivers it (a
zip, read in place) to its 2A, beside the L0 route's 2A of the same scene.

Figures printed (issue 50's target: ≤ 3 s on 2 cores, "the L0 route's time plus the
reading"):

1. **The L0 route**: the default P scene's L0 archive to its 1A and 2A (the peer);
2. **the DIMAP route**: that 1A written as SWH's zip (``station export --dimap X.zip``),
   then the zip opened (``levels.readers.scene1a``: the metadata parsed, the image's rows
   scanned for lost lines through GDAL's ``/vsizip/``) and made into its 2A; the opening
   alone beside it; the ratio to figure 1;
3. the two 2As compared: identical counts and the largest difference.

Run: ``python benchmarks/bench_dimap.py [L0.h5]`` (without an archive the default P scene
is emulated and received first, about a minute). Best of 3; ``BENCH_SMOKE=1``: a 600 × 600
scene, once.
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

import numba
import numpy as np
from _smoke import size
from bench_levels import make_l0

from levels.options import ProcessingOptions
from levels.process import ProcessingRequest, process
from levels.products import read_product
from levels.readers.l0 import read_l0
from levels.readers.scene1a import read_scene_1a
from station.benchmark_pack import zip_pack

REPEATS = size(3, 1)


def best(f) -> tuple[float, object]:
    times, out = [], None
    for _ in range(REPEATS):
        t = time.perf_counter()
        out = f()
        times.append(time.perf_counter() - t)
    return min(times), out


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        l0 = Path(sys.argv[1]) if len(sys.argv) > 1 else make_l0(root)
        opts = ProcessingOptions(levels=("1A", "2A"))
        t_l0, made = best(
            lambda: process(ProcessingRequest.of(read_l0(l0), opts, root / "l0", "bench"))[0]
        )
        first = made.scenes[0]
        pack = root / "bench.zip"
        zip_pack(first.paths["1A"], pack)
        two_a = ProcessingOptions(levels=("2A",), scene_lines=0)

        def dimap() -> object:
            return process(ProcessingRequest.of(read_scene_1a(pack), two_a, root / "d", "bench"))

        t_open, scene = best(lambda: read_scene_1a(pack))
        t_dimap, again = best(dimap)
        n_rows, n_cols = scene.n_lines, scene.n_columns  # type: ignore[attr-defined]
        print(
            f"a {n_rows} × {n_cols} P scene, {numba.get_num_threads()} threads; "
            f"the zip {pack.stat().st_size / 1e6:.1f} MB"
        )
        print(f"1. L0 route, L0 → 1A, 2A:                 {t_l0:.2f} s (the peer)")
        print(
            f"2. DIMAP route, SWH's zip → 2A:            {t_dimap:.2f} s (target ≤ 3 s: "
            f"{t_dimap / 3.0:.2f}× it; {t_dimap / t_l0:.2f}× the L0 route); opening alone "
            f"{t_open:.2f} s"
        )
        a = read_product(first.paths["2A"]).bands["P"]
        b = read_product(again[0].scenes[0].paths["2A"]).bands["P"]  # type: ignore[index]
        d = np.abs(a.image.astype(np.int16) - b.image.astype(np.int16))[a.valid | b.valid]
        print(
            f"3. the two 2As: {np.mean(d == 0) * 100:.3f} % identical counts, largest "
            f"difference {int(d.max())}"
        )


if __name__ == "__main__":
    main()
