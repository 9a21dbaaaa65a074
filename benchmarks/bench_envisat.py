"""Reading a full ERS frame of ESA's ENVISAT format (issue 50's target: ≤ 2 s on 2 cores),
beside GDAL's ESAT driver reading the same file's image.

A frame of 8300 lines × 5000 slant-range samples (the ERS-1 swath at 3 azimuth looks; the
geometry emulated, the intensity exponential speckle) written as ``SAR_IMP_1P`` on slant
range (the run's), as ``SAR_IMP_1P`` on ground range (ESA's: the reader resamples it onto
slant range) and as ``SAR_IMS_1P`` (complex), then read by :func:`levels.readers.envisat.
read_envisat`: headers, annotation data sets, the image detected (and resampled), the
geolocation grid. The peer: ``rasterio`` reading band 1 of the same file (GDAL's ESAT
driver: the image alone, no annotation). Best of 3; the file's size and the writing time.

    python benchmarks/bench_envisat.py           (BENCH_SMOKE=1: a 300 × 200 frame, once)
"""

from __future__ import annotations

import tempfile
import time
import warnings
from pathlib import Path

import numpy as np
from _smoke import size

TARGET_S = 2.0
REPEATS = size(3, 1)


def best(f) -> float:
    times = []
    for _ in range(REPEATS):
        t = time.perf_counter()
        f()
        times.append(time.perf_counter() - t)
    return min(times)


def main() -> None:
    import rasterio

    from levels.readers.envisat import read_envisat
    from levels.sar import SarImage
    from levels.writers.envisat import write_envisat
    from station.spacecraft.sar import ErsFrame, emulate_frame
    from station.spacecraft.world import World

    world = World(lon0_rad=np.radians(-56.1), base_height_m=200.0, relief_m=400.0, seed=3)
    frame = ErsFrame(
        n_lines=size(8300, 300), n_samples=size(5000, 200), azimuth_looks=3, range_looks=1
    )
    geometry, _ = emulate_frame(frame, world, render=False)
    ann = geometry.annotation
    speckle = np.random.default_rng(1).exponential(1.0, ann.shape).astype(np.float32)
    image = SarImage(ann, speckle)
    print(f"an ERS frame of {ann.shape[0]} × {ann.shape[1]} samples")

    def gdal(path: Path) -> None:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            with rasterio.open(path) as ds:
                ds.read(1)

    with tempfile.TemporaryDirectory() as tmp:
        for label, kw in (
            ("SAR_IMP_1P, slant range (the run's)", {}),
            ("SAR_IMP_1P, ground range (ESA's)", {"ground_range": True}),
            ("SAR_IMS_1P, complex", {"product": "SAR_IMS_1P"}),
        ):
            path = Path(tmp) / "frame.E1"
            t = time.perf_counter()
            write_envisat(path, image, **kw)
            t_write = time.perf_counter() - t
            ours = best(lambda p=path: read_envisat(p))
            peer = best(lambda p=path: gdal(p))
            print(
                f"{label}: {path.stat().st_size / 1e6:.0f} MB written in {t_write:.1f} s; "
                f"read {ours:.2f} s (target ≤ {TARGET_S:.0f} s: {ours / TARGET_S:.2f}× it); "
                f"GDAL's image alone {peer:.2f} s ({ours / peer:.1f}× it)"
            )


if __name__ == "__main__":
    main()
