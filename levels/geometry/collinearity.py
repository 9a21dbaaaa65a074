"""The collinearity condition of the adjustments (:mod:`levels.adjust`) as numba kernels.

One point's condition is a handful of vector operations; the adjustments evaluate it for
every point at every iteration, and 24 times more for the parameters' Jacobian (central
differences in 12 parameters). As numpy stacks that is about 30 array passes per
evaluation; here it is one pass over the points, and the Jacobian one kernel call.

The arithmetic is the numpy version's (:func:`levels.adjust.model._condition_numpy`, kept as the
reference the tests compare with): the orbital frame rebuilt on the corrected state
(SPOT Geometry Handbook: ``Z = P/|P|``, ``X = V × Z / |V × Z|``, ``Y = Z × X``), the body
frame by :func:`levels.geometry.frames.orbital_from_body`, the direction to the ground
point as two angles minus the look table's, in pixels. The kernels are untyped, as the
project's other numba kernels: their arguments are float64 arrays, C-contiguous, one row
per point (``r``, ``v``: position and velocity; ``axes``: the a priori orbital frame;
``att``: the pass's attitude; ``table``: the look table's angles at the point's column;
``pitch``: the table's pitch; ``g``: the ground point, ECEF).
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np


@nb.njit(cache=True, nogil=True)
def _one(p, r, v, axes, att, table, pitch, g0, g1, g2, c, q):
    """The condition of point ``p`` seeing the ground ``g0, g1, g2`` under the corrections
    ``c[q]`` (9: position in the orbital frame, velocity, roll–pitch–yaw). Indices rather
    than row views: a view per call costs more than the arithmetic."""
    r0 = r[p, 0] + axes[p, 0, 0] * c[q, 0] + axes[p, 0, 1] * c[q, 1] + axes[p, 0, 2] * c[q, 2]
    r1 = r[p, 1] + axes[p, 1, 0] * c[q, 0] + axes[p, 1, 1] * c[q, 1] + axes[p, 1, 2] * c[q, 2]
    r2 = r[p, 2] + axes[p, 2, 0] * c[q, 0] + axes[p, 2, 1] * c[q, 1] + axes[p, 2, 2] * c[q, 2]
    v0 = v[p, 0] + axes[p, 0, 0] * c[q, 3] + axes[p, 0, 1] * c[q, 4] + axes[p, 0, 2] * c[q, 5]
    v1 = v[p, 1] + axes[p, 1, 0] * c[q, 3] + axes[p, 1, 1] * c[q, 4] + axes[p, 1, 2] * c[q, 5]
    v2 = v[p, 2] + axes[p, 2, 0] * c[q, 3] + axes[p, 2, 1] * c[q, 4] + axes[p, 2, 2] * c[q, 5]
    nr = math.sqrt(r0 * r0 + r1 * r1 + r2 * r2)
    z0, z1, z2 = r0 / nr, r1 / nr, r2 / nr
    x0 = v1 * z2 - v2 * z1
    x1 = v2 * z0 - v0 * z2
    x2 = v0 * z1 - v1 * z0
    nx = math.sqrt(x0 * x0 + x1 * x1 + x2 * x2)
    x0, x1, x2 = x0 / nx, x1 / nx, x2 / nx
    y0 = z1 * x2 - z2 * x1
    y1 = z2 * x0 - z0 * x2
    y2 = z0 * x1 - z1 * x0
    d0, d1, d2 = g0 - r0, g1 - r1, g2 - r2
    o0 = x0 * d0 + x1 * d1 + x2 * d2
    o1 = y0 * d0 + y1 * d1 + y2 * d2
    o2 = z0 * d0 + z1 * d1 + z2 * d2
    # orbital_from_body(roll, pitch, yaw), a = −pitch, b = −roll, c = yaw; w = Mᵀ o
    a = -(att[p, 1] + c[q, 7])
    b = -(att[p, 0] + c[q, 6])
    k = att[p, 2] + c[q, 8]
    ca, sa, cb, sb = math.cos(a), math.sin(a), math.cos(b), math.sin(b)
    cc, sc = math.cos(k), math.sin(k)
    w0 = cb * cc * o0 + (ca * sc + sa * sb * cc) * o1 + (sa * sc - ca * sb * cc) * o2
    w1 = -cb * sc * o0 + (ca * cc - sa * sb * sc) * o1 + (sa * cc + ca * sb * sc) * o2
    w2 = sb * o0 - sa * cb * o1 + ca * cb * o2
    depth = -w2
    return (
        (math.atan(w1 / depth) - table[p, 0]) / pitch[p],
        (math.atan(-w0 / depth) - table[p, 1]) / pitch[p],
    )


@nb.njit(cache=True, nogil=True)
def condition(r, v, axes, att, table, pitch, g, c):
    """The condition of ``N`` points in pixels, ``(N, 2)``, under corrections ``c``
    (``(N, 9)``: position and velocity in the a priori orbital frame ``axes``, attitude)."""
    n = r.shape[0]
    out = np.empty((n, 2))
    for p in range(n):
        g0, g1, g2 = g[p, 0], g[p, 1], g[p, 2]
        out[p, 0], out[p, 1] = _one(p, r, v, axes, att, table, pitch, g0, g1, g2, c, p)
    return out


@nb.njit(cache=True, nogil=True, parallel=True)
def jacobian(r, v, axes, att, table, pitch, g, c, dc, step):
    """Central differences of the condition along ``K`` directions of the corrections,
    ``dc`` (``(N, K, 9)``: how each parameter moves each point's corrections), by ``step``:
    ``(N, 2, K)``."""
    n, m = dc.shape[0], dc.shape[1]
    out = np.empty((n, 2, m))
    for p in nb.prange(n):  # each point its own: the same result on any thread count
        cpm = np.empty((2, 9))
        g0, g1, g2 = g[p, 0], g[p, 1], g[p, 2]
        for k in range(m):
            for i in range(9):
                cpm[0, i] = c[p, i] + step * dc[p, k, i]
                cpm[1, i] = c[p, i] - step * dc[p, k, i]
            a0, a1 = _one(p, r, v, axes, att, table, pitch, g0, g1, g2, cpm, 0)
            b0, b1 = _one(p, r, v, axes, att, table, pitch, g0, g1, g2, cpm, 1)
            out[p, 0, k] = (a0 - b0) / (2 * step)
            out[p, 1, k] = (a1 - b1) / (2 * step)
    return out


@nb.njit(cache=True, nogil=True, parallel=True)
def ground_jacobian(r, v, axes, att, table, pitch, g, c, dg, step):
    """Forward differences of the condition along ``K`` moves of the ground point, ``dg``
    (``(N, K, 3)``, unit vectors), by ``step`` metres: ``(N, 2, K)`` in pixels per metre."""
    n, m = dg.shape[0], dg.shape[1]
    out = np.empty((n, 2, m))
    for p in nb.prange(n):
        g0, g1, g2 = g[p, 0], g[p, 1], g[p, 2]
        a0, a1 = _one(p, r, v, axes, att, table, pitch, g0, g1, g2, c, p)
        for k in range(m):
            b0, b1 = _one(
                p, r, v, axes, att, table, pitch,
                g0 + step * dg[p, k, 0], g1 + step * dg[p, k, 1], g2 + step * dg[p, k, 2], c, p,
            )  # fmt: skip
            out[p, 0, k] = (b0 - a0) / step
            out[p, 1, k] = (b1 - a1) / step
    return out
