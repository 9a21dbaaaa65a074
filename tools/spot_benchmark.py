"""The open SPOT 1–4 benchmark at full size: run a scenario, export each 1A as a DIMAP v1
scene with its truth, and print what a user gets (issue 35 §5).

    python tools/spot_benchmark.py                                   # full P at 27°
    python tools/spot_benchmark.py scenarios/cuiaba_xs_twin.toml --out runs/bench_twin

For each 1A product: the pack's directory and size, the export time, the exported scene's
model against the product's (largest image distance at 1000 points, every band), and this
station's scores at the truth's checkpoints (pack.json).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from levels.geo.scenes import models_of_tree
from levels.products import read_product
from levels.readers.dimap import read_dimap
from levels.writers.dimap import BAND_INDEX
from station.benchmark_pack import write_pack
from station.cli import main as station

ROOT = Path(__file__).resolve().parents[1]


def model_gap_px(product_path: Path, metadata: Path, n: int = 1000) -> float:
    """Largest image distance between the product's model and the DIMAP scene's."""
    _, models = models_of_tree(read_product(product_path, images=False).geometry)
    scene = read_dimap(metadata)
    rng = np.random.default_rng(0)
    gap = 0.0
    for name, ours in models.items():
        theirs = scene.model(band=BAND_INDEX[name], attitude="integrated_zeroed")
        line, col = rng.uniform(0, ours.n_lines - 1, n), rng.uniform(0, ours.n_columns - 1, n)
        h = rng.uniform(-100.0, 2000.0, n)
        g = ours.image_to_ground(line, col, h)
        i = theirs.ground_to_image(g.lat_rad, g.lon_rad, h)
        gap = max(gap, float(np.hypot(i.line - line, i.column - col).max()))
    return gap


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("scenario", nargs="?", default=str(ROOT / "scenarios" / "cuiaba_p_27deg.toml"))
    ap.add_argument("--out", default="runs/spot_benchmark")
    args = ap.parse_args()
    out = Path(args.out)
    run = out / "run"
    code = station(["run", args.scenario, "--out", str(run), "--quiet", "--no-quicklooks"])
    if code != 0:
        raise SystemExit(code)
    for product in sorted(run.glob("*_1A.h5")):
        pack = out / product.name.removesuffix("_1A.h5")
        t0 = time.perf_counter()
        result = write_pack(product, pack, scenario=args.scenario)
        dt = time.perf_counter() - t0
        size = sum(p.stat().st_size for p in pack.rglob("*") if p.is_file())
        gap = model_gap_px(product, pack / "METADATA.DIM")
        print(f"{pack}: {size / 1e6:.1f} MB, exported in {dt:.1f} s")
        print(f"  the scene's model against the product's: {gap:.2e} px at most")
        for name, s in json.loads((pack / "pack.json").read_text())["scores_m"].items():
            print(f"  {name}: RMS {s['rms_m']:.2f} m, max {s['max_m']:.2f} m ({s['n']} points)")
        assert result.truth


if __name__ == "__main__":
    main()
