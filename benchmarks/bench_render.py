"""Speed of the spacecraft emulator: one full HRV P scene (6000 × 6000) rendered.

Figures printed:
* setup (orbit placed and integrated over the day, attitude, HRV, gyros, bulletins);
* rendering of the full P scene with the default 3 × 3 PSF quadrature (target: under 60 s on
  this machine, issue 3), and without PSF integration (centre ray only);
* the peer, real time: the 9.02 s the HRV takes to acquire those 6000 lines; the ratio says
  how many times slower than the satellite the emulator is;
* the Newton iterations of the ray–terrain intersection and the rays that failed.

Run: ``python benchmarks/bench_render.py [n_lines]`` (default 6000; fewer lines give a
quick estimate). Numba uses every core (``NUMBA_NUM_THREADS`` to change it); the first
call compiles, so a warm-up on a few lines comes first and is not timed.
"""

from __future__ import annotations

import dataclasses
import sys
import time

import numba
import numpy as np
from _smoke import SMOKE, size

from station.scenario import scenario_from_dict
from station.spacecraft.emulator import emulate
from station.spacecraft.imaging import render_band

TARGET_S = 60.0


def main() -> None:
    n_lines = int(sys.argv[1]) if len(sys.argv) > 1 else size(6000, 200)
    scn = scenario_from_dict(
        {
            "instrument": {"n_lines": n_lines} | ({"n_detectors": 600} if SMOKE else {}),
            "pass": {"ground_pass_days": 0.0},
        }
    )
    t0 = time.perf_counter()
    acq = emulate(scn, render=False)
    setup = time.perf_counter() - t0
    hrv, band = acq.hrv, acq.hrv.bands[0]
    real_time = n_lines * hrv.line_period_s

    def render(samples: int) -> tuple[float, object]:
        h = dataclasses.replace(hrv, psf_samples=samples)
        start = time.perf_counter()
        out = render_band(
            acq.orbit,
            acq.attitude,
            h,
            band,
            acq.world,
            acq.line_times_s,
            acq.sun_ecef,
            np.random.default_rng(0),
        )
        return time.perf_counter() - start, out

    warm = dataclasses.replace(hrv, psf_samples=3)
    render_band(
        acq.orbit,
        acq.attitude,
        warm,
        band,
        acq.world,
        acq.line_times_s[:4],
        acq.sun_ecef,
        np.random.default_rng(0),
    )
    t_psf, out = render(hrv.psf_samples)
    t_centre, _ = render(1)
    px = n_lines * hrv.n_columns
    print(
        f"scene: {n_lines} lines x {hrv.n_columns} detectors = {px / 1e6:.1f} Mpx, "
        f"{numba.get_num_threads()} numba threads"
    )
    print(f"setup (orbit over the day, attitude, gyros, bulletins): {setup:.2f} s")
    print(
        f"render, PSF {hrv.psf_samples}x{hrv.psf_samples}: {t_psf:.1f} s "
        f"({px / t_psf / 1e6:.2f} Mpx/s); target {TARGET_S:.0f} s for 6000 lines: "
        f"{'met' if t_psf * 6000 / n_lines < TARGET_S else 'MISSED'}"
    )
    print(f"render, centre ray only: {t_centre:.1f} s")
    print(
        f"peer, real time (acquisition of these lines): {real_time:.2f} s; "
        f"emulator / real time = {t_psf / real_time:.1f}"
    )
    print(f"Newton iterations, worst pixel: {out.newton_max}; failed rays: {int(out.failed.sum())}")


if __name__ == "__main__":
    main()
