"""Triangulation of the matched pixels: each pair of rays' closest approach through the views'
rigorous models, by anchor grids in disparity (the exact solution checked at some).
"""

from __future__ import annotations

from dataclasses import dataclass

import numba as nb
import numpy as np
from numpy.typing import NDArray

from levels.geo.inverse_grid import bilinear_grid
from levels.geometry.ellipsoid import WGS84
from levels.geometry.model import PushbroomModel
from levels.stereo.epipolar import EpipolarPair, _to_map
from levels.stereo.matching import _CHUNK, Disparity
from levels.threads import over_blocks


def closest_approach(
    r1: NDArray, u1: NDArray, r2: NDArray, u2: NDArray
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Mid-point of the common perpendicular of two lines (PHOTOMOD's triangulation,
    paper ``003_…``: "the middle of the common perpendicular", the rays never meeting) and
    the lines' miss along it (m, signed)."""
    w = r1 - r2
    b = np.sum(u1 * u2, axis=1)
    d, e = np.sum(u1 * w, axis=1), np.sum(u2 * w, axis=1)
    den = 1.0 - b**2
    s = (b * e - d) / den
    t = (e - b * d) / den
    p1, p2 = r1 + s[:, None] * u1, r2 + t[:, None] * u2
    n = np.cross(u1, u2)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    return 0.5 * (p1 + p2), np.sum((p2 - p1) * n, axis=1)


@dataclass(frozen=True, eq=False)
class StereoPoints:
    """Triangulated points: map position (m), ellipsoidal height (m), the rays' miss (m)
    and the predicted height σ (m)."""

    x_m: NDArray[np.float64]
    y_m: NDArray[np.float64]
    h_m: NDArray[np.float32]
    miss_m: NDArray[np.float32]
    sigma_h_m: NDArray[np.float32]
    pixel_m: float  # the epipolar pixel they were triangulated on
    stride: int  # every stride-th pixel of it


def triangulate_raw(
    a: PushbroomModel,
    b: PushbroomModel,
    la: NDArray,
    ca: NDArray,
    lb: NDArray,
    cb: NDArray,
) -> tuple[NDArray, NDArray, NDArray, NDArray]:
    """Latitude, longitude (rad), height (m) and miss (m) of points measured at raw
    ``(la, ca)`` in the image of model ``a`` and ``(lb, cb)`` in that of ``b``."""
    r1, u1 = a.sight(la, ca)
    r2, u2 = b.sight(lb, cb)
    mid, miss = closest_approach(r1, u1, r2, u2)
    lat, lon, h = WGS84.to_geodetic(mid)
    return lat, lon, h, miss


def _triangulate_exact(
    pair: EpipolarPair, u: NDArray, v: NDArray, d: NDArray
) -> tuple[NDArray, NDArray, NDArray, NDArray]:
    """Map x, y, height and miss of epipolar points ``(u, v)`` matched at ``u + d``."""
    to_map = _to_map(pair.frame.crs_wkt)
    out = [np.empty(u.size) for _ in range(4)]
    for k in range(0, u.size, _CHUNK):
        s = slice(k, k + _CHUNK)
        la, ca = pair.raw_of(0, u[s], v[s])
        lb, cb = pair.raw_of(1, u[s] + d[s], v[s])
        lat, lon, h, miss = triangulate_raw(pair.a.model, pair.b.model, la, ca, lb, cb)
        x, y = to_map.transform(np.degrees(lon), np.degrees(lat))
        out[0][s], out[1][s], out[2][s], out[3][s] = x, y, h, miss
    return out[0], out[1], out[2], out[3]


#: The triangulation's anchor grid: nodes every ``ANCHOR_STEP_PX`` epipolar pixels, and
#: ``ANCHOR_LEVELS`` disparities over the range, fitted per node by a cubic in the
#: disparity (a point moves along smooth curves as its disparity grows), bilinearly
#: between nodes: level 3's anchor grids, in the pair's geometry. Its error against the
#: rigorous triangulation is measured on ``ANCHOR_CHECKS`` points and kept.
ANCHOR_STEP_PX = 32
ANCHOR_LEVELS = 7
ANCHOR_CHECKS = 2000


def _anchor_fit(
    pair: EpipolarPair, d_range: tuple[float, float]
) -> tuple[NDArray, NDArray, NDArray, float, float]:
    """Per node, the cubic coefficients in the normalised disparity of x, y, h and miss:
    ``(4 quantities, 4 powers, nodes v, nodes u)``; the node rows, columns, and the
    normalisation (centre, half span)."""
    rows, cols = pair.frame.shape
    step = ANCHOR_STEP_PX
    nv, nu = -(-(rows - 1) // step) + 1, -(-(cols - 1) // step) + 1
    v_n, u_n = np.arange(nv) * float(step), np.arange(nu) * float(step)
    c, half = 0.5 * (d_range[0] + d_range[1]), max(0.5 * (d_range[1] - d_range[0]), 1.0)
    t = np.cos(np.pi * (np.arange(ANCHOR_LEVELS) + 0.5) / ANCHOR_LEVELS)  # Chebyshev nodes
    V, U, T = np.meshgrid(v_n, u_n, t, indexing="ij")
    q = np.stack(_triangulate_exact(pair, U.ravel(), V.ravel(), c + half * T.ravel()))
    q = q.reshape(4, nv, nu, ANCHOR_LEVELS)
    powers = np.vander(t, 4, increasing=True)  # (levels, 4)
    coef = np.linalg.lstsq(powers, q.reshape(-1, ANCHOR_LEVELS).T, rcond=None)[0]
    return coef.T.reshape(4, nv, nu, 4).transpose(0, 3, 1, 2), v_n, u_n, c, half


@nb.njit(cache=True, nogil=True)
def _kernel_anchor(lo, hi, d, stride, coef, step, c, half, index, out):
    """Rows ``lo … hi − 1`` of the strided disparity field: each valid pixel's x, y, h and
    miss from the anchor fit (Horner in the disparity, coefficients bilinear between
    nodes), stored at its rank ``index[row]`` + its count along the row."""
    nv, nu = coef.shape[2], coef.shape[3]
    for r in range(lo, hi):
        v = r * stride
        a = min(v // step, nv - 2)
        fv = (v - a * step) / step
        k = index[r]
        for q in range(0, d.shape[1], stride):
            dd = d[v, q]
            if not (dd == dd):
                continue
            b = min(q // step, nu - 2)
            fu = (q - b * step) / step
            t = (dd - c) / half
            for m in range(4):
                acc = 0.0
                for p in range(3, -1, -1):
                    z = coef[m, p]
                    at_b = (1.0 - fv) * z[a, b] + fv * z[a + 1, b]
                    at_b1 = (1.0 - fv) * z[a, b + 1] + fv * z[a + 1, b + 1]
                    acc = acc * t + ((1.0 - fu) * at_b + fu * at_b1)
                out[m, k] = acc
            k += 1


def _anchor_eval(
    fit: tuple[NDArray, NDArray, NDArray, float, float], u: NDArray, v: NDArray, d: NDArray
) -> NDArray:
    """x, y, h, miss ``(4, N)`` from the anchor fit at scattered points (the checks)."""
    coef, v_n, u_n, c, half = fit
    t = (d - c) / half
    out = np.zeros((4, u.size))
    for p in range(3, -1, -1):  # Horner in t, each coefficient bilinearly between nodes
        at = np.stack([bilinear_grid(v_n, u_n, coef[k, p], v, u) for k in range(4)])
        out = out * t + at
    return out


def triangulate(
    pair: EpipolarPair, disparity: Disparity, d_range: tuple[float, float], stride: int = 1
) -> tuple[StereoPoints, float]:
    """Every ``stride``-th valid pixel of the disparity field, triangulated through the
    anchor grid (step 3); and the grid's largest height error on the checks (m)."""
    valid = disparity.valid[::stride, ::stride]
    per_row = np.count_nonzero(valid, axis=1)
    index = np.concatenate([[0], np.cumsum(per_row)[:-1]]).astype(np.int64)
    n = int(per_row.sum())
    fit = _anchor_fit(pair, d_range)
    out = np.empty((4, n))
    coef, v_n, _, c, half = fit
    over_blocks(
        _kernel_anchor,
        per_row.size,
        disparity.d,
        stride,
        np.ascontiguousarray(coef),
        int(v_n[1] - v_n[0]),
        float(c),
        float(half),
        index,
        out,
    )
    # the checks: a random draw of the points, their pixels found from their ranks
    check = np.sort(np.random.default_rng(0).choice(n, min(ANCHOR_CHECKS, n), replace=False))
    row = np.searchsorted(index, check, side="right") - 1
    col = np.array(
        [np.flatnonzero(valid[r])[k - index[r]] for r, k in zip(row, check, strict=True)],
        dtype=np.int64,
    )
    v, u = (row * stride).astype(np.float64), (col * stride).astype(np.float64)
    d = disparity.d[row * stride, col * stride].astype(np.float64)
    exact = np.stack(_triangulate_exact(pair, u, v, d))
    error = float(np.max(np.abs(exact[:3] - out[:3, check]))) if check.size else 0.0
    sigma = disparity.sigma[::stride, ::stride][valid].astype(np.float32) * pair.height_per_px_m
    points = StereoPoints(
        out[0],
        out[1],
        out[2].astype(np.float32),
        out[3].astype(np.float32),
        sigma,
        pair.frame.pixel_m,
        stride,
    )
    return points, error


def _mean_correlation(m: int, stride: int, window: int) -> float:
    """Mean correlation of the matching errors of ``m × m`` points ``stride`` pixels apart
    whose ``window``-pixel windows overlap (box windows: ``(1 − |dx|/w)(1 − |dy|/w)``)."""
    k = np.arange(m) * stride
    dx = np.abs(k[:, None] - k[None, :])
    r1 = np.clip(1.0 - dx / window, 0.0, None)
    return float(np.mean(r1) ** 2)
