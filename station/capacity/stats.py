"""Queueing figures: time-weighted statistics of a piecewise-constant count, confidence
intervals over replications, and the closed forms the model is checked against.

- **Erlang C** (M/M/c): the probability that an arrival waits,
  ``C(c, a) = [aᶜ/c! · c/(c − a)] / [Σₖ₌₀^{c−1} aᵏ/k! + aᶜ/c! · c/(c − a)]`` with
  ``a = λ/μ`` the offered load, and the mean wait in queue ``W_q = C(c, a) / (cμ − λ)``
  (Kleinrock, *Queueing Systems* I, §3.5, the m-server queue).
- **Little's law**: ``L = λ W`` for any stage in steady state, L the time-average number in
  the stage, λ its arrival rate and W the mean time spent in it.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike
from scipy import stats

__all__ = ["erlang_c", "erlang_c_wait_s", "mean_ci", "time_weighted"]


def erlang_c(c: int, offered_load: float) -> float:
    """Probability of waiting in an M/M/c queue of offered load ``a = λ/μ`` (< c)."""
    a = float(offered_load)
    if not 0 <= a < c:
        raise ValueError(f"offered load {a} must be below the {c} servers")
    terms = np.cumprod(np.concatenate([[1.0], a / np.arange(1, c)]))  # aᵏ/k!, k < c
    last = terms[-1] * a / c * c / (c - a)  # aᶜ/c! · c/(c − a)
    return float(last / (terms.sum() + last))


def erlang_c_wait_s(arrival_rate: float, service_rate: float, c: int) -> float:
    """Mean time in queue of an M/M/c queue, ``C(c, a) / (cμ − λ)``."""
    return erlang_c(c, arrival_rate / service_rate) / (c * service_rate - arrival_rate)


def time_weighted(
    t: ArrayLike, n: ArrayLike, t_end: float, quantiles: tuple[float, ...] = (0.95,)
) -> dict[str, float]:
    """Mean, quantiles and max of a count that holds ``n[i]`` from ``t[i]`` to ``t[i+1]``
    (the last value until ``t_end``), weighted by time."""
    t = np.asarray(t, dtype=np.float64)
    n = np.asarray(n, dtype=np.float64)
    if t.size == 0:
        return {"mean": 0.0, "max": 0.0} | {f"p{round(q * 100)}": 0.0 for q in quantiles}
    dt = np.diff(np.append(t, t_end))
    total = dt.sum()
    order = np.argsort(n, kind="stable")
    cum = np.cumsum(dt[order]) / total
    out = {"mean": float((n * dt).sum() / total), "max": float(n.max())}
    for q in quantiles:
        out[f"p{round(q * 100)}"] = float(n[order][np.searchsorted(cum, q)])
    return out


def mean_ci(values: ArrayLike, level: float = 0.95) -> tuple[float, float]:
    """Mean of independent replications and the half-width of its Student-t interval
    (NaN for one replication)."""
    x = np.asarray(values, dtype=np.float64)
    x = x[np.isfinite(x)]
    if x.size == 0:
        return math.nan, math.nan
    if x.size == 1:
        return float(x[0]), math.nan
    half = stats.t.ppf(0.5 + level / 2, x.size - 1) * x.std(ddof=1) / math.sqrt(x.size)
    return float(x.mean()), float(half)
