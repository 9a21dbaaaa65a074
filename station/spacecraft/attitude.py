"""Truth attitude: constant offsets, a drift with Westin's variograms, jitter; and the gyros.

Angles are roll, pitch, yaw in SPOT's convention (:mod:`levels.geometry.frames`).

Drift
    Westin (paper ``000_…``) gives empirical variograms of SPOT 1's attitude, the variance of
    attitude increments over a time Δt (s):

        2γ_ω(Δt) = 1774 Δt^1.8                                 roll,   eq. (24)
        2γ_ρ(Δt) = 17500 Δt^0.5 + 80000 (1 − cos 0.93 Δt)       pitch,  eq. (25)
        2γ_κ(Δt) = 3200 Δt                                      yaw,    eq. (26)

    The paper says "in units of [10⁻⁶]²" and checks itself: [2γ_ω(31)]^½ = 0.93° × 10⁻³.
    1774 · 31^1.8 = 8.58e5, whose root is 926: so the unit is the micro-degree, and that is
    how the emulator reads the equations.

    Each power-law term ``c Δt^α`` (0 < α < 2) is a fractional Brownian motion of Hurst
    exponent α/2 (α = 1: a Wiener process). It is generated exactly on a regular grid by
    circulant embedding of the covariance of its increments (Davies & Harte 1987):
    ``C(k) = c δ^α (|k+1|^α + |k−1|^α − 2|k|^α) / 2``, whose circulant extension is
    non-negative definite for fractional Gaussian noise, so no approximation is made.
    The term ``c (1 − cos ω Δt)`` is a random harmonic ``A cos ωt + B sin ωt`` with
    A, B ~ N(0, c/2): its increments have exactly that variance. Between grid points
    (``drift_step_s``) the drift is linear: that piecewise-linear function *is* the truth.

Gyros
    Every ``gyro_period_s`` (125 ms on SPOT) the gyros report the mean angular rate over the
    period centred on the sample time, ``(θ(t + T/2) − θ(t − T/2)) / T``: an integrating
    gyro read out with a boxcar filter. White noise is added and the result quantised to the
    gyro's least significant bit. The constant offsets are invisible to rates: the station
    can only integrate to an attitude known up to ω0, ρ0, κ0 (INPE's null attitude).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from levels.geometry.attitude import (
    MICRODEGREE_RAD,
    WESTIN_HARMONIC,
    WESTIN_POWER,
    westin_variogram_rad2,
)

__all__ = [
    "MICRODEGREE_RAD",
    "GyroRecord",
    "TruthAttitude",
    "fractional_brownian",
    "random_harmonic",
    "sample_gyros",
    "westin_variogram_rad2",
]


def fractional_brownian(
    n: int, step_s: float, c: float, alpha: float, rng: np.random.Generator, size: int = 1
) -> NDArray[np.float64]:
    """``size`` paths of a process with 2γ(Δt) = c Δt^α at ``n`` grid points, starting at 0.

    Davies–Harte circulant embedding (module docstring). Returns shape ``(size, n)``.
    """
    if not 0 < alpha < 2:
        raise ValueError(f"alpha = {alpha}: a power-law variogram needs 0 < alpha < 2")
    m = max(n - 1, 1)
    k = np.arange(m + 1, dtype=np.float64)
    cov = 0.5 * c * step_s**alpha * (np.abs(k + 1) ** alpha + np.abs(k - 1) ** alpha - 2 * k**alpha)
    row = np.concatenate([cov, cov[-2:0:-1]])  # circulant of length 2m
    eig = np.fft.rfft(row).real
    eig = np.clip(eig, 0.0, None)  # only round-off can make them negative for fGn
    z = rng.standard_normal((size, eig.size)) + 1j * rng.standard_normal((size, eig.size))
    z[:, 0] = z[:, 0].real * np.sqrt(2)  # real at zero frequency …
    if row.size % 2 == 0:
        z[:, -1] = z[:, -1].real * np.sqrt(2)  # … and at Nyquist
    increments = np.fft.irfft(np.sqrt(eig / 2) * z, n=row.size) * np.sqrt(row.size)
    paths = np.zeros((size, n))
    paths[:, 1:] = np.cumsum(increments[:, : n - 1], axis=1)
    return paths


def random_harmonic(
    t_s: NDArray[np.float64],
    c: float,
    omega_rad_per_s: float,
    rng: np.random.Generator,
    size: int = 1,
) -> NDArray[np.float64]:
    """``size`` paths of ``A cos ωt + B sin ωt`` with 2γ(Δt) = c (1 − cos ωΔt), shape (size, N)."""
    ab = rng.standard_normal((size, 2)) * np.sqrt(c / 2)
    wt = omega_rad_per_s * np.asarray(t_s, dtype=np.float64)
    return ab[:, :1] * np.cos(wt) + ab[:, 1:] * np.sin(wt)


@dataclass(frozen=True, eq=False)
class TruthAttitude:
    """The satellite's true attitude over ``[t_start_s, t_end_s]`` (``Attitude`` protocol).

    Parameters
    ----------
    offsets_rad
        Constant roll, pitch, yaw (Westin's ω0, ρ0, κ0), shape (3,).
    t_grid_s, drift_rad
        Drift samples, shapes (N,) and (N, 3); linear in between.
    jitter_amplitude_rad, jitter_frequency_hz, jitter_phase_rad
        One sinusoid per axis, shapes (3,).
    """

    offsets_rad: NDArray[np.float64]
    t_grid_s: NDArray[np.float64]
    drift_rad: NDArray[np.float64]
    jitter_amplitude_rad: NDArray[np.float64]
    jitter_frequency_hz: NDArray[np.float64]
    jitter_phase_rad: NDArray[np.float64]

    @classmethod
    def generate(
        cls,
        t_start_s: float,
        t_end_s: float,
        rng: np.random.Generator,
        offsets_rad: ArrayLike = (0.0, 0.0, 0.0),
        drift_scale: float = 1.0,
        jitter_amplitude_rad: ArrayLike = (0.0, 0.0, 0.0),
        jitter_frequency_hz: ArrayLike = (0.0, 0.0, 0.0),
        drift_step_s: float = 1.0 / 128.0,
    ) -> TruthAttitude:
        """Draw a truth attitude: Westin drift (× ``drift_scale``, variance scales by its
        square), jitter with random phases, the given offsets."""
        n = int(np.ceil((t_end_s - t_start_s) / drift_step_s)) + 1
        t = np.asarray(t_start_s + drift_step_s * np.arange(n), dtype=np.float64)
        drift = np.zeros((n, 3))
        for axis in range(3):
            for c, alpha in WESTIN_POWER[axis]:
                drift[:, axis] += fractional_brownian(n, drift_step_s, c, alpha, rng)[0]
            for c, omega in WESTIN_HARMONIC[axis]:
                drift[:, axis] += random_harmonic(t - t_start_s, c, omega, rng)[0]
        drift *= drift_scale * MICRODEGREE_RAD
        return cls(
            offsets_rad=np.asarray(offsets_rad, dtype=np.float64),
            t_grid_s=t,
            drift_rad=drift - drift[n // 2],  # the drift is an increment: zero mid-span
            jitter_amplitude_rad=np.asarray(jitter_amplitude_rad, dtype=np.float64),
            jitter_frequency_hz=np.asarray(jitter_frequency_hz, dtype=np.float64),
            jitter_phase_rad=rng.uniform(0, 2 * np.pi, 3),
        )

    @property
    def span_s(self) -> tuple[float, float]:
        return float(self.t_grid_s[0]), float(self.t_grid_s[-1])

    def angles_rad(self, t_s: ArrayLike) -> NDArray[np.float64]:
        """Roll, pitch, yaw (rad) at ``t_s``, shape (N, 3); NaN outside the span."""
        t = np.atleast_1d(np.asarray(t_s, dtype=np.float64))
        out = np.empty((t.size, 3))
        for axis in range(3):
            out[:, axis] = np.interp(t, self.t_grid_s, self.drift_rad[:, axis])
        out += self.offsets_rad
        out += self.jitter_amplitude_rad * np.sin(
            2 * np.pi * self.jitter_frequency_hz * t[:, None] + self.jitter_phase_rad
        )
        outside = (t < self.t_grid_s[0]) | (t > self.t_grid_s[-1])
        out[outside] = np.nan
        return out


@dataclass(frozen=True)
class GyroRecord:
    """What the gyros hand to the telemetry: sample times (s) and rates (rad/s), (N,), (N, 3)."""

    t_s: NDArray[np.float64]
    rates_rad_per_s: NDArray[np.float64]


def sample_gyros(
    attitude: TruthAttitude,
    t_first_s: float,
    n_samples: int,
    period_s: float,
    noise_rad_per_s: float,
    lsb_rad_per_s: float,
    rng: np.random.Generator,
) -> GyroRecord:
    """Gyro rates every ``period_s`` from ``t_first_s`` (module docstring)."""
    t = np.asarray(t_first_s + period_s * np.arange(n_samples), dtype=np.float64)
    before = attitude.angles_rad(t - period_s / 2)
    after = attitude.angles_rad(t + period_s / 2)
    rates = (after - before) / period_s + noise_rad_per_s * rng.standard_normal((n_samples, 3))
    if lsb_rad_per_s > 0:
        rates = np.round(rates / lsb_rad_per_s) * lsb_rad_per_s
    return GyroRecord(t, rates)
