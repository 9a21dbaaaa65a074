"""The downlink report: what the station received, and how it compares with the truth.

A plain dict (JSON-ready) built from a :class:`~station.chain.session.DownlinkResult`; the
comparison with the truth is possible only because the pass was emulated.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from station.chain.session import DownlinkResult
from station.spacecraft.downlink import Transmission
from station.spacecraft.emulator import Acquisition
from station.srrs.receiver import CORRECTED, OK, OUT_OF_ORDER, DecodedPass

__all__ = [
    "STATION_RATE_BIT_PER_S",
    "comparable",
    "downlink_report",
    "downlink_scenario",
    "expected_valid",
    "lost_data_frames",
]

STATION_RATE_BIT_PER_S = 50e6  # two X-band channels of 25 Mbit/s


def lost_data_frames(tx: Transmission, d: DecodedPass) -> NDArray[np.int64]:
    """Indices (0-based in the session) of the data frames sent but not delivered."""
    acc = d.accounts.get(tx.data_vc)
    if acc is None:
        return np.arange(tx.sent[tx.data_vc])
    status, count = np.asarray(d.frame_status), np.asarray(d.frame_count)
    got = (np.asarray(d.frame_vc) == tx.data_vc) & np.isin(status, [OK, CORRECTED, OUT_OF_ORDER])
    delivered = np.unique(count[got]) - acc.first_count
    return np.setdiff1d(np.arange(tx.sent[tx.data_vc]), delivered)


def expected_valid(tx: Transmission, lost: NDArray[np.int64], n_lines: int) -> NDArray[np.bool_]:
    """The validity (bands, lines, segments) the truth calls for: a segment is valid iff
    no frame its packet occupied was lost."""
    is_lost = np.zeros(tx.sent[tx.data_vc], bool)
    is_lost[lost] = True
    touched = np.concatenate([[0], np.cumsum(is_lost)])
    hit = touched[tx.packet_last_frame + 1] - touched[tx.packet_first_frame] > 0
    valid = np.zeros((len(tx.ground_bands), n_lines, tx.segment_first_detector.size), bool)
    valid[tx.packet_band, tx.packet_row, tx.packet_segment] = ~hit
    return valid


def downlink_report(acq: Acquisition, result: DownlinkResult) -> dict:
    """Decode statistics, line and pixel validity, and errors against the truth."""
    tx, rx, d = result.transmission, result.reception, result.decoded
    bands = []
    for b, band in enumerate(acq.bands):
        ok = d.pixel_valid(b)
        got, sent, raw = np.asarray(d.images[b])[ok], tx.ground_bands[b][ok], band.counts[ok]
        err = np.abs(got.astype(np.int64) - raw)
        bands.append(
            {
                "name": band.name,
                "lines_complete": int(d.valid[b].all(axis=1).sum()),
                "lines_partial": int((d.valid[b].any(axis=1) & ~d.valid[b].all(axis=1)).sum()),
                "lines_missing": int((~d.valid[b].any(axis=1)).sum()),
                "pixels_valid_fraction": round(float(ok.mean()), 6),
                "valid_pixels_as_sent": bool(np.array_equal(got, sent)),
                "max_error_vs_raw_counts": int(err.max(initial=0)),
                "rms_error_vs_raw_counts": round(
                    float(np.sqrt(np.mean(err**2.0))) if err.size else 0.0, 4
                ),
            }
        )
    n_bits = rx.n_bits
    t_rx = result.timings_s["receive"]
    lost = lost_data_frames(tx, d)
    masks_ok = bool(
        np.array_equal(np.stack(d.valid), expected_valid(tx, lost, d.line_counter.size))
    )
    line_err = np.abs(d.line_t_s - acq.line_times_s)
    return {
        "scenario": acq.scenario.name,
        "hrv": d.hrv,
        "mode": d.mode,
        "lines": int(d.line_counter.size),
        "detectors": int(d.images[0].shape[1]),
        "link": {
            "cadus_sent": int(tx.cadus.shape[0]),
            "duration_s": round(8 * tx.n_bytes / tx.bit_rate_bit_per_s, 3),
            "bit_rate_mbps": tx.bit_rate_bit_per_s / 1e6,
            "bits_recorded": n_bits,
            "bit_errors": rx.n_bit_errors,
            "bursts": rx.n_bursts,
            "fades": rx.n_fades,
        },
        "cadus": d.status_counts,
        "channels": {
            f"vc{v:02d}": {**a.as_dict(), "truth_sent": int(tx.sent.get(v, -1))}
            for v, a in sorted(d.accounts.items())
        },
        "sync": {"bits_searched": d.bits_searched, "losses": d.sync_losses},
        "truth_check": {
            "data_frames_lost": int(lost.size),
            "masks_match_lost_frames": masks_ok,
            "accounts_balance": all(a.delivered + a.lost == a.sent for a in d.accounts.values()),
            "sent_as_counted": all(a.sent == tx.sent.get(v, -1) for v, a in d.accounts.items()),
        },
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


def comparable(report: dict) -> dict:
    """The part of a downlink report that must not change between runs or machines: counts
    of frames and lines and the truth checks (frame losses depend only on where the channel
    put its errors, which the seed fixes, not on the image)."""
    keys = (
        "sent",
        "delivered",
        "lost",
        "gaps",
        "duplicates",
        "out_of_order",
        "head_known",
        "tail_known",
    )
    lines = ("lines_complete", "lines_partial", "lines_missing", "valid_pixels_as_sent")
    return {
        "cadus": report["cadus"],
        "channels": {vc: {k: c[k] for k in keys} for vc, c in report["channels"].items()},
        "bands": [{k: b[k] for k in ("name", *lines)} for b in report["bands"]],
        "truth_check": report["truth_check"],
        "link": {k: report["link"][k] for k in ("cadus_sent", "bit_errors", "bursts", "fades")},
    }


def downlink_scenario(scenario: str | Path, out: str | Path | None = None) -> dict[str, object]:
    """``station downlink``: a scenario's pass emulated, sent through its channel, decoded
    and recorded as an L0 archive at ``out`` (default ``<name>.l0.h5``; only an earlier
    archive of the same scenario is replaced); the downlink's report, with the archive."""
    from levels.readers.l0 import l0_scenario
    from station.chain.session import downlink, record
    from station.loader import load_scenario
    from station.outdir import replaceable_file
    from station.spacecraft.emulator import emulate

    start = time.perf_counter()
    scn = load_scenario(scenario)
    path = replaceable_file(
        out or f"{scn.name}.l0.h5",
        l0_scenario,
        scn.name,
        lambda name: f"the L0 archive of scenario {name!r}",
    )
    acq = emulate(scn)
    t_emulate = time.perf_counter() - start
    result = downlink(acq)
    t0 = time.perf_counter()
    record(acq, result, path)
    result.timings_s.update(emulate=t_emulate, record=time.perf_counter() - t0)
    rep = downlink_report(acq, result)
    rep["l0"] = {"path": str(path), "size_mb": round(path.stat().st_size / 1e6, 2)}
    return rep
