"""Frame accounting and masking against the truth, over a sweep of channel conditions.

For each BER (1e-7 … 1e-3), with Gilbert–Elliott bursts, fades, replayed stretches and
reordering all on, a pass is sent, impaired and received, and the table shows per
virtual channel the frames sent (truth), delivered and counted lost, and whether the masks
in the decoded lines are exactly the segments touched by a lost frame. Exit status 1 if any
check fails.

Run: ``python tools/accounting_sweep.py [mode] [n_lines] [seed]`` (default P, 1000 lines of
the full 6000-detector line, 25 Mbit/s).
"""

from __future__ import annotations

import dataclasses
import sys

import numpy as np

from station.chain.report import expected_valid, lost_data_frames
from station.scenario import scenario_from_dict
from station.spacecraft.channel import impair
from station.spacecraft.downlink import transmit
from station.spacecraft.emulator import emulate
from station.srrs.receiver import receive

HARSH = dict(
    burst_rate_per_s=20.0,
    burst_length_bits=800.0,
    burst_ber=0.1,
    fade_rate_per_min=60.0,
    fade_duration_s=0.02,
    replay_runs=4,
    replay_frames=40,
    reorder_fraction=0.02,
    reorder_distance=4,
)


def main() -> int:
    mode = sys.argv[1] if len(sys.argv) > 1 else "P"
    n_lines = int(sys.argv[2]) if len(sys.argv) > 2 else 1000
    seed = int(sys.argv[3]) if len(sys.argv) > 3 else 0
    scn = scenario_from_dict(
        {
            "instrument": {"mode": mode, "n_lines": n_lines},
            "pass": {"ground_pass_days": 0.0},
            "gcps": {"count": 0},
        }
    )
    acq = emulate(scn)
    tx = transmit(acq, scn.downlink, np.random.default_rng(seed))
    elevation = np.full(tx.slot_t_s.size, np.radians(20.0))
    print(
        f"{mode} strip of {n_lines} lines: {tx.cadus.shape[0]} CADUs; bursts "
        f"{HARSH['burst_rate_per_s']}/s at zenith, fades {HARSH['fade_rate_per_min']}/min, "
        f"{HARSH['replay_runs']} replays, {HARSH['reorder_fraction']:.0%} reordered; "
        "elevation 20°"
    )
    print(
        f"{'BER':>7} {'vc':>3} {'sent':>6} {'deliv.':>6} {'lost':>5} {'dupl.':>5} "
        f"{'o-o-o':>5} {'uncorr.':>7} {'lines ok':>8} {'masked':>6}  checks"
    )
    failed = False
    for ber in (1e-7, 1e-6, 1e-5, 1e-4, 1e-3):
        cfg = dataclasses.replace(scn.channel, ber=ber, **HARSH)
        rx = impair(
            tx.cadus,
            tx.slot_t_s,
            elevation,
            cfg,
            tx.bit_rate_bit_per_s,
            np.random.default_rng([seed, int(-np.log10(ber))]),
        )
        d = receive(rx.stream, rx.n_bits)
        lost = lost_data_frames(tx, d)
        masks = np.array_equal(np.stack(d.valid), expected_valid(tx, lost, n_lines))
        valid_px = all(
            np.array_equal(d.images[b][ok], tx.ground_bands[b][ok])
            for b in range(len(d.images))
            for ok in [d.pixel_valid(b)]
        )
        lines_ok = int(np.stack(d.valid).all(axis=(0, 2)).sum())
        for vc, acc in sorted(d.accounts.items()):
            ok = (
                acc.sent == tx.sent[vc]
                and acc.delivered + acc.lost == acc.sent
                and acc.head_known
                and acc.tail_known
            )
            checks = ok and (vc == 63 or (masks and valid_px and lost.size == acc.lost))
            failed |= not checks
            print(
                f"{ber:7.0e} {vc:3d} {tx.sent[vc]:6d} {acc.delivered:6d} {acc.lost:5d} "
                f"{acc.duplicates:5d} {acc.out_of_order:5d} "
                f"{d.status_counts['uncorrectable'] if vc != 63 else 0:7d} "
                f"{lines_ok if vc != 63 else 0:8d} "
                f"{n_lines - lines_ok if vc != 63 else 0:6d}  {'ok' if checks else 'FAIL'}"
            )
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
