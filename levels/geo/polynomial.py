"""Least-squares polynomials on normalised variables, the form GEO hands to COR.

INPE's 1B maps are cubic polynomials of one variable (paper ``004_…`` eqs. 1–3) and its 2A
inverse maps polynomials of two variables of order 3 to 5 (§3). Both are fitted here on
variables centred and scaled to [−1, 1] over the breakpoints, so that the normal equations
stay well conditioned for images of thousands of pixels; the centre and scale are part of
the polynomial and are stored with its coefficients.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.linalg
from numpy.typing import ArrayLike, NDArray

from levels.errors import GeometryError

__all__ = ["Poly1D", "Poly2D"]


def _normaliser(x: NDArray[np.float64]) -> tuple[float, float]:
    lo, hi = float(np.min(x)), float(np.max(x))
    if not hi > lo:
        raise GeometryError(f"breakpoints span no interval ({lo} .. {hi})")
    return 0.5 * (lo + hi), 0.5 * (hi - lo)


@dataclass(frozen=True, eq=False)
class Poly1D:
    """``y = Σ coef[k] · u^k`` with ``u = (x − centre) / scale``."""

    coef: NDArray[np.float64]
    centre: float
    scale: float

    @classmethod
    def fit(cls, x: ArrayLike, y: ArrayLike, order: int) -> Poly1D:
        x = np.asarray(x, dtype=np.float64)
        y = np.asarray(y, dtype=np.float64)
        if x.size <= order:
            raise GeometryError(f"{x.size} breakpoints cannot fix a polynomial of order {order}")
        centre, scale = _normaliser(x)
        u = (x - centre) / scale
        coef, *_ = np.linalg.lstsq(np.vander(u, order + 1, increasing=True), y, rcond=None)
        return cls(coef, centre, scale)

    def __call__(self, x: ArrayLike) -> NDArray[np.float64]:
        u = (np.asarray(x, dtype=np.float64) - self.centre) / self.scale
        return np.asarray(np.polynomial.polynomial.polyval(u, self.coef), dtype=np.float64)

    def derivative(self, x: ArrayLike) -> NDArray[np.float64]:
        u = (np.asarray(x, dtype=np.float64) - self.centre) / self.scale
        return np.asarray(
            np.polynomial.polynomial.polyval(u, np.polynomial.polynomial.polyder(self.coef))
            / self.scale,
            dtype=np.float64,
        )

    def solve(self, y: ArrayLike, x0: ArrayLike, iterations: int = 6) -> NDArray[np.float64]:
        """``x`` with ``p(x) = y`` by Newton from ``x0`` (the maps are monotonic)."""
        x = np.array(x0, dtype=np.float64, copy=True)
        y = np.asarray(y, dtype=np.float64)
        for _ in range(iterations):
            x -= (self(x) - y) / self.derivative(x)
        return x

    def as_array(self) -> NDArray[np.float64]:
        """``[centre, scale, coef…]``: how products store it."""
        return np.concatenate([[self.centre, self.scale], self.coef])

    @classmethod
    def from_array(cls, a: ArrayLike) -> Poly1D:
        a = np.asarray(a, dtype=np.float64)
        return cls(a[2:].copy(), float(a[0]), float(a[1]))


#: Largest condition number of a design fitted through its normal equations (their
#: square, 1e10, leaves 6 digits); beyond it, QR.
_NORMAL_EQUATIONS_MAX_COND = 1e5


def _triangular_factor(
    design: NDArray[np.float64], z: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Upper-triangular R with ``RᵀR = AᵀA`` and ``Qᵀz = R⁻ᵀAᵀz``: the least-squares
    solution of ``A c ≈ z`` is ``R c = Qᵀz``, and that of the leading columns of ``A`` the
    leading block of both."""
    try:
        lower: NDArray[np.float64] = np.linalg.cholesky(design.T @ design).astype(
            np.float64, copy=False
        )
        d = np.abs(np.diagonal(lower))
        # the ratio of R's diagonal bounds the design's condition number from below
        if d.min() * _NORMAL_EQUATIONS_MAX_COND > d.max():
            return lower.T, _solve_triangular(lower, design.T @ z, lower=True)
    except np.linalg.LinAlgError:
        pass  # not positive definite in floating point: QR below
    # R of [A | z] holds R of A and, in its last column, Qᵀz: Q is never formed
    n = design.shape[1]
    r_aug: NDArray[np.float64] = np.asarray(np.linalg.qr(np.column_stack([design, z]), mode="r"))
    return r_aug[:n, :n], r_aug[:n, n]


def _solve_triangular(
    t: NDArray[np.float64], b: NDArray[np.float64], lower: bool
) -> NDArray[np.float64]:
    """``t⁻¹ b`` by LAPACK's ``dtrtrs``, without ``scipy.linalg.solve_triangular``'s checks
    (ten times the solve on these 21 × 21 systems)."""
    x, info = scipy.linalg.lapack.dtrtrs(t, b, lower=int(lower))
    if info != 0:
        raise GeometryError("the breakpoints leave the polynomial's coefficients undetermined")
    return x


def _powers(u: NDArray[np.float64], order: int) -> NDArray[np.float64]:
    """``u⁰ … u^order`` as columns, shape ``(N, order + 1)``."""
    out = np.empty((u.size, order + 1))
    out[:, 0] = 1.0
    for k in range(1, order + 1):
        np.multiply(out[:, k - 1], u, out=out[:, k])
    return out


def _exponents(order: int) -> NDArray[np.int64]:
    """(p, q) of every monomial ``u^p v^q`` with ``p + q <= order``."""
    return np.array(
        [(p, t - p) for t in range(order + 1) for p in range(t, -1, -1)], dtype=np.int64
    )


@dataclass(frozen=True, eq=False)
class Poly2D:
    """``z = Σ coef[k] · u^p_k v^q_k`` over ``p + q <= order``, ``u``, ``v`` normalised."""

    coef: NDArray[np.float64]
    order: int
    centre: tuple[float, float]
    scale: tuple[float, float]

    @classmethod
    def fit(cls, x: ArrayLike, y: ArrayLike, z: ArrayLike, order: int) -> Poly2D:
        return cls.fit_orders(x, y, z, (order,))[order]

    @classmethod
    def fit_orders(
        cls, x: ArrayLike, y: ArrayLike, z: ArrayLike, orders: Sequence[int]
    ) -> dict[int, Poly2D]:
        """The least-squares fits of several orders on the same points, from one
        factorisation: the monomials are ordered by total degree, so the design matrix of a
        lower order is the leading columns of the highest's, and so is its R.

        R is the Cholesky factor of the normal matrix ``AᵀA``: on variables normalised to
        [−1, 1] the design's condition number is about 125 for a direct grid (``AᵀA``'s
        1.6e4), so the normal equations lose 4 of 16 digits and cost a seventh of a QR
        factorisation. A design conditioned worse than ``_NORMAL_EQUATIONS_MAX_COND``
        (few or clustered breakpoints) is factorised by QR.
        """
        x, y, z = (np.asarray(a, dtype=np.float64).ravel() for a in (x, y, z))
        top = max(orders)
        n_top = (top + 1) * (top + 2) // 2
        if x.size < n_top:
            raise GeometryError(f"{x.size} breakpoints cannot fix {n_top} coefficients")
        cx, sx = _normaliser(x)
        cy, sy = _normaliser(y)
        design = cls(np.zeros(n_top), top, (cx, cy), (sx, sy))._design(x, y)
        r, qz = _triangular_factor(design, z)
        out = {}
        for order in orders:
            n = (order + 1) * (order + 2) // 2
            coef = _solve_triangular(r[:n, :n], qz[:n], lower=False)
            out[order] = cls(coef, order, (cx, cy), (sx, sy))
        return out

    def _design(self, x: NDArray[np.float64], y: NDArray[np.float64]) -> NDArray[np.float64]:
        u = (x - self.centre[0]) / self.scale[0]
        v = (y - self.centre[1]) / self.scale[1]
        pu, pv = _powers(u, self.order), _powers(v, self.order)
        e = _exponents(self.order)
        return pu[:, e[:, 0]] * pv[:, e[:, 1]]

    def __call__(self, x: ArrayLike, y: ArrayLike) -> NDArray[np.float64]:
        xa, ya = np.broadcast_arrays(
            np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)
        )
        return (self._design(xa.ravel(), ya.ravel()) @ self.coef).reshape(xa.shape)

    def as_array(self) -> NDArray[np.float64]:
        """``[order, cx, cy, sx, sy, coef…]``: how products store it."""
        return np.concatenate([[self.order, *self.centre, *self.scale], self.coef])

    @classmethod
    def from_array(cls, a: ArrayLike) -> Poly2D:
        """The inverse of :meth:`as_array`."""
        a = np.asarray(a, dtype=np.float64)
        order = int(a[0])
        n = (order + 1) * (order + 2) // 2
        if a.shape != (5 + n,):
            raise ValueError(f"a Poly2D of order {order} is {5 + n} numbers, got {a.shape}")
        return cls(a[5:].copy(), order, (float(a[1]), float(a[2])), (float(a[3]), float(a[4])))
