"""A pass on Dask distributed: N full P scenes from one L0 archive, with 1 and 2 workers.

Figures printed (issue 21's target in brackets):

1. **Scenes per second** of a pass of N full P scenes (6000 × 6000 each, levels 1A, 1B,
   2A; default N = 4), reprocessed from its L0 archive as ``station process`` does (GEO
   here, each scene a task: :mod:`levels.tasks`), wall time from the archive opened to the
   last product written:
   - on a local Dask cluster of **1 worker** of one core, and of **2 workers** of one core
     each (``NUMBA_NUM_THREADS=1``, BLAS on one thread, as Dask's nanny sets it): the
     **scaling** from 1 to 2 workers and its efficiency (≥ 1.7×);
   - in this process on every core (the default: the kernels' threads, no Dask), for
     comparison.
   The cluster's start is timed apart (it is paid once per command, not per scene).
2. **Peak memory per worker** (the largest resident set of any worker process, from the
   operating system): one scene in flight per worker, the L0 read by rows.
3. **Identical products**: every product of every run compared byte for byte.
4. **What this machine allows**: the same measure of scaling (one process, then two at
   once) for a plain copy of a full P scene's float image (memory bandwidth) and for
   deflating its 8-bit image (ISA-L's level 2, the products' compression), measured in the
   same run. A scene is made of such passes over whole images: where two processes on this
   machine's two cores get less than 2× of either, the pass cannot either.

Run: ``python benchmarks/bench_pass.py [DIR] [--scenes N]``. The pass is emulated and
received once into DIR (about 1.5 min per scene; kept for the next run), else into a
temporary directory. Each configuration first makes the pass once untimed (its processes
load the compiled kernels from numba's cache: 1–2 s here), then best of 2.
"""

from __future__ import annotations

import argparse
import os
import resource
import shutil
import tempfile
import time
from pathlib import Path

from _smoke import SMOKE, size

from levels.options import ProcessingOptions
from levels.process import all_made, run_plans
from levels.products import is_product_file
from levels.tasks import DaskRunner, InProcess, Runner, dask_runner
from station.reprocess import plan_reprocess
from station.scenario import scenario_from_dict

REPEATS = 2
SCENE_LINES = size(6000, 300)


def make_pass(directory: Path, n_scenes: int) -> Path:
    """The L0 archive of a pass of ``n_scenes`` full P scenes (emulated once, kept)."""
    from station.chain.session import downlink, record
    from station.spacecraft.emulator import emulate

    l0 = directory / f"pass{n_scenes}.l0.h5"
    if l0.is_file():
        return l0
    print(f"emulating and receiving a pass of {n_scenes} full P scenes …", flush=True)
    t = time.perf_counter()
    scn = scenario_from_dict(
        {
            "name": f"pass{n_scenes}",
            "instrument": {"n_lines": n_scenes * SCENE_LINES}
            | ({"n_detectors": SCENE_LINES} if SMOKE else {}),
        }
    )
    acq = emulate(scn)
    record(acq, downlink(acq), l0)
    print(f"   {time.perf_counter() - t:.0f} s, {l0.stat().st_size / 1e6:.0f} MB", flush=True)
    return l0


def run_pass(l0: Path, out: Path, runner: Runner) -> tuple[float, int]:
    """Wall time of the pass through ``runner``, and its scenes."""
    shutil.rmtree(out, ignore_errors=True)
    t = time.perf_counter()
    plans = plan_reprocess([l0], out, options=ProcessingOptions(), names=["pass"])
    [made] = all_made(run_plans(plans, runner))
    return time.perf_counter() - t, len(made.scenes)


def _peak_rss_mb() -> float:
    """This process's peak resident set (MB): Linux's ``VmHWM``, the high-water mark of
    its own memory map. Not ``ru_maxrss``: Linux keeps it across ``exec``, so a worker
    spawned by a process that had emulated the pass (5.5 GB) reported the parent's peak."""
    try:
        with open("/proc/self/status") as status:
            for line in status:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) / 1024.0
    except OSError:
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def on_cluster(l0: Path, out: Path, workers: int) -> tuple[float, float, int, float]:
    """Best wall time on a local cluster of ``workers`` one-core workers, its start time,
    the scenes, and the peak resident memory of its largest worker (MB)."""
    t = time.perf_counter()
    with dask_runner(workers=workers, cores_per_worker=1) as runner:
        assert isinstance(runner, DaskRunner)
        start = time.perf_counter() - t
        run_pass(l0, out, runner)  # loads each worker's kernels
        times = []
        for _ in range(REPEATS):
            dt, n = run_pass(l0, out, runner)
            times.append(dt)
        peak = max(runner.client.run(_peak_rss_mb).values())
    return min(times), start, n, peak


def _machine_work(kind: str) -> float:
    """One process's share of the machine ceiling test: seconds for 10 copies of a full P
    float32 image, or for deflating a full P 8-bit image in 512-row chunks."""
    import numpy as np

    from levels.hdf5 import deflate

    rng = np.random.default_rng(0)
    if kind == "copy":
        src = np.ones((SCENE_LINES, 6000), np.float32)
        dst = np.empty_like(src)
        t = time.perf_counter()
        for _ in range(10):
            np.copyto(dst, src)
        return time.perf_counter() - t
    img = rng.normal(100.0, 20.0, (SCENE_LINES, 6000)).clip(0, 255).astype(np.uint8)
    t = time.perf_counter()
    for i in range(0, SCENE_LINES, 512):
        deflate(img[i : i + 512], 2)
    return time.perf_counter() - t


def machine_scaling(kind: str) -> float:
    """Throughput of two processes at once over one process alone (2.0: perfect)."""
    from concurrent.futures import ProcessPoolExecutor

    alone = min(_machine_work(kind) for _ in range(2))
    with ProcessPoolExecutor(2) as pool:
        both = max(pool.map(_machine_work, [kind, kind]))
    return 2.0 * alone / both


def products(out: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(q for q in out.glob("*") if is_product_file(q))}


def differences(a: Path, b: Path) -> None:
    """Which products of ``b`` differ from ``a``'s, and in what: every check of ``station
    compare`` with its tolerances at zero."""
    from levels.compare import compare_products, load_tolerances
    from levels.products import read_product

    zero = {k: dict.fromkeys(v, 0.0) for k, v in load_tolerances(None).items()}
    made, reference = products(b), products(a)
    for name in sorted(set(reference) ^ set(made)):
        print(f"   {name}: in {a.name if name in reference else b.name} only")
    for name, data in made.items():
        if reference.get(name, data) == data:
            continue
        found = compare_products(read_product(a / name), read_product(b / name), zero)
        bad = [f.text() for f in found if not f.ok]
        print(f"   {b.name}/{name} differs from {a.name}'s: {'; '.join(bad[:6]) or 'bytes only'}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dir", nargs="?", help="where the pass's L0 archive is kept")
    ap.add_argument("--scenes", type=int, default=size(4, 2), help="full P scenes in the pass")
    args = ap.parse_args()
    keep = Path(args.dir) if args.dir else Path(tempfile.mkdtemp(prefix="bench_pass_"))
    keep.mkdir(parents=True, exist_ok=True)
    l0 = make_pass(keep, args.scenes)
    work = Path(tempfile.mkdtemp(prefix="bench_pass_out_"))
    print(f"\nA pass of {args.scenes} full P scenes (levels 1A, 1B, 2A), {os.cpu_count()} cores")

    run_pass(l0, work / "in_process", InProcess())  # loads this process's kernels
    t_in, n = min(run_pass(l0, work / "in_process", InProcess()) for _ in range(REPEATS))
    t1, start1, n1, peak1 = on_cluster(l0, work / "one", 1)
    reference = products(work / "one")
    t2, start2, n2, peak2 = on_cluster(l0, work / "two", 2)
    assert n == n1 == n2 == args.scenes, (n, n1, n2)

    print("\n1. scenes per second")
    print(f"   Dask, 1 worker of 1 core:    {t1:6.1f} s  {n / t1:.3f} scenes/s")
    print(f"   Dask, 2 workers of 1 core:   {t2:6.1f} s  {n / t2:.3f} scenes/s")
    speedup = t1 / t2
    print(f"   scaling 1 → 2 workers: {speedup:.2f}× (efficiency {speedup / 2:.0%}; target ≥ 1.7×)")
    print(
        f"   in process, every core (no Dask): {t_in:6.1f} s  {n / t_in:.3f} scenes/s "
        f"({t1 / t_in:.2f}× one core)"
    )
    print(f"   cluster start: {start1:.1f} s (1 worker), {start2:.1f} s (2 workers)")
    print("\n2. peak memory per worker (largest resident set)")
    print(f"   1 worker: {peak1:.0f} MB; 2 workers: {peak2:.0f} MB each at most")
    same = products(work / "two") == reference == products(work / "in_process")
    print(
        f"\n3. products identical byte for byte (in process, 1 and 2 workers): "
        f"{'yes' if same else 'NO'} ({len(reference)} products)"
    )
    if not same:
        for other in ("two", "in_process"):
            differences(work / "one", work / other)
    copy, deflate = machine_scaling("copy"), machine_scaling("deflate")
    print(
        f"\n4. this machine, 1 → 2 processes at once: copying a full P float image "
        f"{copy:.2f}×, deflating a full P 8-bit image {deflate:.2f}× (against the "
        f"pass's {speedup:.2f}×)"
    )
    if same:
        shutil.rmtree(work, ignore_errors=True)
    else:
        print(f"\nthe products are kept in {work}")


if __name__ == "__main__":
    main()
