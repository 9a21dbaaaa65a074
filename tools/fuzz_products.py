"""Fuzz the readers of level products and L0 archives with damaged files.

    python tools/fuzz_products.py [N] [SEED]      # N damaged files (default 2000)

A reduced run (``scenarios/small_test.toml``) gives one L0 archive and its 1A, 1B and 2A
products; each trial damages a copy of one of them (bytes flipped in a run or at random
places, the file truncated, a group, dataset or attribute deleted or replaced) and reads
it back as ``station`` does: ``read_l0`` and the processing of the archive, or
``read_product``, ``compare_products`` against the original and the product summary. The
outcome is counted: read and equal, read and different (compare says so), refused with
the package's error (one line, exit 2), or anything else, which is a defect and printed
with its traceback. A crash of the process (HDF5 aborting) would end the run: the count
printed last says how far it went.
"""

from __future__ import annotations

import shutil
import sys
import tempfile
import traceback
from collections import Counter
from pathlib import Path

import h5py
import numpy as np

from levels.compare import compare_products
from levels.errors import LevelsError
from levels.inspect import product_summary
from levels.options import ProcessingOptions
from levels.process import ProcessingRequest, process
from levels.products import is_product_file, read_product
from levels.readers.l0 import read_l0
from station.cli import main as station

ROOT = Path(__file__).resolve().parents[1]


def _flip(data: bytearray, rng: np.random.Generator) -> None:
    if rng.random() < 0.5:  # a run of bytes, as a bad sector
        start = int(rng.integers(0, len(data)))
        for k in range(start, min(len(data), start + int(rng.integers(1, 64)))):
            data[k] ^= int(rng.integers(1, 256))
    else:  # a few bits anywhere
        for k in rng.integers(0, len(data), size=int(rng.integers(1, 8))):
            data[int(k)] ^= 1 << int(rng.integers(0, 8))


def _structural(path: Path, rng: np.random.Generator) -> None:
    """Delete or replace one object or attribute, as a careless tool would."""
    with h5py.File(path, "r+") as f:
        names: list[str] = []
        f.visit(names.append)
        attrs = [(n, a) for n in ["/", *names] for a in f[n].attrs]
        if attrs and rng.random() < 0.5:
            n, a = attrs[int(rng.integers(0, len(attrs)))]
            if rng.random() < 0.5:
                del f[n].attrs[a]
            else:
                f[n].attrs[a] = ["7", "nan", "", "[]", "{"][int(rng.integers(0, 5))]
        elif names:
            n = names[int(rng.integers(0, len(names)))]
            del f[n]


def damage(src: Path, dst: Path, rng: np.random.Generator) -> str:
    """Write a damaged copy of ``src`` to ``dst``; returns the kind of damage."""
    kind = ["flip", "truncate", "structural"][int(rng.integers(0, 3))]
    if kind == "structural":
        shutil.copy(src, dst)
        try:
            _structural(dst, rng)
        except (OSError, KeyError, RuntimeError, ValueError):
            kind = "flip"  # the tool could not do it: damage the bytes instead
    if kind == "truncate":
        data = src.read_bytes()
        dst.write_bytes(data[: int(rng.integers(0, len(data)))])
    elif kind == "flip":
        data = bytearray(src.read_bytes())
        _flip(data, rng)
        dst.write_bytes(bytes(data))
    return kind


def _l0_data(a) -> list[np.ndarray]:
    bands = [x for b in a.bands.values() for x in (b.counts, b.valid, b.gain, b.offset_counts)]
    return [
        a.line_t_s,
        a.ephemeris.r_ecef_m,
        a.ephemeris.v_ecef_m_per_s,
        a.gyro_rates_rad_per_s,
        *bands,
    ]


def _trial_l0(path: Path, out: Path, original) -> str:
    archive = read_l0(path)
    same = all(
        np.array_equal(x, y) for x, y in zip(_l0_data(archive), _l0_data(original), strict=True)
    )
    if not same:  # read without complaint, yet not what was written: a lie
        raise AssertionError("damaged L0 archive read as valid with different data")
    made = process(
        ProcessingRequest.of(archive, ProcessingOptions(levels=("1A", "2A")), out, "fuzz")
    )[0]
    return f"read, data equal, processed ({len(made.scenes)} scenes)"


def _trial_product(path: Path, original) -> str:
    p = read_product(path)
    product_summary(p, path)
    findings = compare_products(original, p)
    return "read, equal" if all(f.ok for f in findings) else "read, differences named"


def main(argv: list[str]) -> int:
    n = int(argv[0]) if argv else 2000
    seed = int(argv[1]) if len(argv) > 1 else 0
    rng = np.random.default_rng(seed)
    outcomes: Counter[str] = Counter()
    defects = 0
    with tempfile.TemporaryDirectory() as tmp:
        t = Path(tmp)
        run = t / "run"
        if (
            station(
                [
                    "run",
                    str(ROOT / "scenarios" / "small_test.toml"),
                    "--out",
                    str(run),
                    "--quiet",
                    "--no-quicklooks",
                ]
            )
            != 0
        ):
            print("could not make the reference run", file=sys.stderr)
            return 2
        sources = sorted(q for q in run.glob("*") if is_product_file(q))
        originals = {
            p: read_l0(p) if p.name.endswith(".l0.h5") else read_product(p) for p in sources
        }
        for k in range(n):
            src = sources[int(rng.integers(0, len(sources)))]
            bad = t / f"bad{k}_{src.name}"  # a new file each time: HDF5 caches open ones
            kind = damage(src, bad, rng)
            what = "L0" if src.name.endswith(".l0.h5") else "product"
            try:
                if what == "L0":
                    result = _trial_l0(bad, t / "out", originals[src])
                else:
                    result = _trial_product(bad, originals[src])
            except LevelsError:
                result = "refused (LevelsError: one line, exit 2)"
            except Exception:  # a defect: what the tool is for
                defects += 1
                result = "DEFECT"
                print(f"trial {k}: {what} {src.name}, {kind}:", file=sys.stderr)
                traceback.print_exc()
            outcomes[f"{what} {kind}: {result}"] += 1
            if (k + 1) % 500 == 0:
                print(f"{k + 1} damaged files read, {defects} defects", flush=True)
            shutil.rmtree(t / "out", ignore_errors=True)
            bad.unlink()
    for key, count in sorted(outcomes.items()):
        print(f"{count:6d}  {key}")
    print(f"{n} damaged files (seed {seed}): {defects} defects, no crash")
    return 1 if defects else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
