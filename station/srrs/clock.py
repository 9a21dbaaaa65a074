"""The line clock: line times from the (line counter, 1 ms time code) pairs of the aux
records, to a fraction of a millisecond.

The recovery is this project's: Westin (paper ``000_…``) meets the same 1 ms truncation by
matching attitude records in the overlap of successive scenes, which a single scene or a
scene after a gap cannot use; here every aux record's pair of codes constrains the clock.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import linprog

from station.srrs.errors import ReceiverError
from station.telemetry import format as tf

__all__ = ["line_clock", "on_the_clock", "plausible_times"]

_MAX_TIME_MS = tf.TIME_CODE_LIMIT_MS  # 557 years after 1950


def plausible_times(aux: NDArray) -> NDArray[np.bool_]:
    """Time codes within the counter's range (after 1950, before 2507) and a line time
    within a minute of its record's time: anything else is a damaged record."""
    t = aux["time_ms"].astype(np.uint64)
    lt = aux["line_time_ms"].astype(np.uint64)
    ok = (t < _MAX_TIME_MS) & (lt < _MAX_TIME_MS)
    gap = np.abs(t.astype(np.float64) - lt.astype(np.float64))
    return ok & (gap <= 60_000.0)


def on_the_clock(aux: NDArray, first_line: int) -> NDArray[np.bool_]:
    """Records consistent with one line clock: a robust line (median of the slopes between
    records half the span apart, then median intercept) and a 2 ms tolerance around it
    (twice the truncation), so that a record damaged on board cannot drag the fit."""
    x = aux["line"].astype(np.float64) - first_line
    y = aux["line_time_ms"].astype(np.float64)
    y = y - y.min()
    order = np.argsort(x, kind="stable")
    half = max(aux.size // 2, 1)  # pair each record with one half the span away
    dx = x[order][half:] - x[order][:-half]
    dy = y[order][half:] - y[order][:-half]
    if np.count_nonzero(dx > 0) == 0:
        return np.ones(aux.size, bool)
    slope = np.median(dy[dx > 0] / dx[dx > 0])
    icept = np.median(y - slope * x)
    return np.abs(y - icept - slope * x) <= 2.0


def line_clock(
    aux: NDArray, first_line: int, n_lines: int, method: str = "feasible"
) -> tuple[np.datetime64, NDArray[np.float64], float, float]:
    """Line times from the (line counter, time code) pairs of the aux records.

    A time code is latched, truncated to the millisecond, at the start of its line: the
    true start t = a + P·x (x the line counter from the strip's first line) satisfies
    T ≤ t < T + 1 ms for every record. Those constraints bound (a, P) to a small polygon;
    its extent in a and in P is found by four linear programmes, and the clock is the
    middle of it (this project's recovery, module docstring). A least-squares line through the
    codes + 0.5 ms would be biased by the deterministic pattern of the truncation (the
    codes sample t mod 1 ms on a coarse lattice): up to 0.1 ms on a full scene. If the
    constraints cannot all hold (a record damaged on board), the least-squares line is
    used. Returns the epoch, the line times, the period and half the feasible range of the
    time of the middle line (the clock's uncertainty, s), or the least-squares residual
    RMS when it fell back. ``method="least_squares"`` skips the linear programmes (the
    comparison the tests make).
    """
    if method not in ("feasible", "least_squares"):
        raise ValueError(f"line clock method {method!r}: 'feasible' or 'least_squares'")
    if aux.size == 0:
        raise ReceiverError(
            "no auxiliary record with a plausible time code (ms since 1950-01-01, below "
            "2⁴⁴): the line clock is unknown"
        )
    aux = aux[on_the_clock(aux, first_line)]
    ms = aux["line_time_ms"].astype(np.int64)
    day_ms = 86_400_000
    day0 = int(aux["time_ms"].astype(np.int64).min()) // day_ms * day_ms
    epoch_utc = tf.CNES_EPOCH + np.timedelta64(day0, "ms")
    x = aux["line"].astype(np.float64) - first_line
    if np.unique(x).size < 2:
        raise ReceiverError("fewer than two auxiliary records: the line clock is unknown")
    x_mid = (n_lines - 1) / 2.0
    xc = x - x_mid
    y_ms = (ms - ms.min()).astype(np.float64)
    slope, icept = np.polyfit(xc, y_ms + 0.5, 1)
    a_ms, p_ms, spread = (
        icept,
        slope,
        float(np.sqrt(np.mean((y_ms + 0.5 - icept - slope * xc) ** 2))) * 1e-3,
    )
    # T <= a + P x < T + 1  as  A z <= b, z = (a, P)
    a_ub = np.concatenate(
        [np.stack([-np.ones_like(xc), -xc], 1), np.stack([np.ones_like(xc), xc], 1)]
    )
    b_ub = np.concatenate([-y_ms, y_ms + 1.0 - 1e-9])
    ext = []
    for c in ([1, 0], [-1, 0], [0, 1], [0, -1]) if method == "feasible" else ():
        r = linprog(c, A_ub=a_ub, b_ub=b_ub, bounds=[(None, None), (None, None)], method="highs")
        if r.status != 0:
            break
        ext.append(r.x)
    if len(ext) == 4:
        a_ms = (ext[0][0] + ext[1][0]) / 2
        p_ms = (ext[2][1] + ext[3][1]) / 2
        spread = (ext[1][0] - ext[0][0]) / 2 * 1e-3
    t0_s = (ms.min() - day0) / 1e3 + a_ms * 1e-3
    t = t0_s + p_ms * 1e-3 * (np.arange(n_lines) - x_mid)
    return epoch_utc, t, float(p_ms * 1e-3), spread
