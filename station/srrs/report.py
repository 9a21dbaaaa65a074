"""The downlink report: what the station received, and how it compares with the truth.

A plain dict (JSON-ready) built from a :class:`~station.srrs.session.DownlinkResult`; the
comparison with the truth is possible only because the pass was emulated.
"""

from __future__ import annotations

import numpy as np

from station.spacecraft.emulator import Acquisition
from station.srrs.session import DownlinkResult

__all__ = ["STATION_RATE_BIT_PER_S", "downlink_report"]

STATION_RATE_BIT_PER_S = 50e6  # two X-band channels of 25 Mbit/s


def downlink_report(acq: Acquisition, result: DownlinkResult) -> dict:
    """Decode statistics, line and pixel validity, and errors against the truth."""
    tx, rx, d = result.transmission, result.reception, result.decoded
    bands = []
    for b, band in enumerate(acq.bands):
        seg = np.searchsorted(d.segment_first_detector, np.arange(d.images[b].shape[1]),
                              side="right") - 1
        ok = d.valid[b][:, seg]
        got, sent, raw = d.images[b][ok], tx.ground_bands[b][ok], band.counts[ok]
        err = np.abs(got.astype(np.int64) - raw)
        bands.append({
            "name": band.name,
            "lines_complete": int(d.valid[b].all(axis=1).sum()),
            "lines_partial": int((d.valid[b].any(axis=1) & ~d.valid[b].all(axis=1)).sum()),
            "lines_missing": int((~d.valid[b].any(axis=1)).sum()),
            "pixels_valid_fraction": round(float(ok.mean()), 6),
            "valid_pixels_as_sent": bool(np.array_equal(got, sent)),
            "max_error_vs_raw_counts": int(err.max(initial=0)),
            "rms_error_vs_raw_counts": round(float(np.sqrt(np.mean(err ** 2.0)))
                                             if err.size else 0.0, 4),
        })
    n_bits = rx.n_bits
    t_rx = result.timings_s["receive"]
    line_err = np.abs(d.line_t_s - acq.line_times_s)
    return {
        "scenario": acq.scenario.name,
        "hrv": d.hrv, "mode": d.mode,
        "lines": int(d.line_counter.size), "detectors": int(d.images[0].shape[1]),
        "link": {
            "cadus_sent": int(tx.cadus.shape[0]),
            "duration_s": round(8 * tx.n_bytes / tx.bit_rate_bit_per_s, 3),
            "bit_rate_mbps": tx.bit_rate_bit_per_s / 1e6,
            "bits_recorded": n_bits,
            "bit_errors": rx.n_bit_errors, "bursts": rx.n_bursts, "fades": rx.n_fades,
        },
        "cadus": d.status_counts,
        "channels": {f"vc{v:02d}": {**a.as_dict(), "truth_sent": int(tx.sent.get(v, -1))}
                     for v, a in sorted(d.accounts.items())},
        "sync": {"bits_searched": d.bits_searched, "losses": d.sync_losses},
        "packets": d.packets,
        "bands": bands,
        "line_clock": {
            "period_s": d.line_period_s,
            "uncertainty_us": round(d.line_clock_uncertainty_s * 1e6, 2),
            "max_error_vs_truth_us": round(float(line_err.max()) * 1e6, 2),
        },
        "timings_s": {k: round(v, 4) for k, v in result.timings_s.items()},
        "receive_speed_x_real_time": round(n_bits / STATION_RATE_BIT_PER_S / t_rx, 2),
    }
