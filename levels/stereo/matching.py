"""Dense matching of a pair's epipolar images: OpenCV's semi-global matcher, then the
least-squares refinement of each pixel's disparity with its σ; the disparity range from the
tie points and a coarse pass.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from levels.cor.epipolar import shift_rows, window_solve
from levels.errors import GeometryError
from levels.readers.gcp import ControlPointSet
from levels.stereo.epipolar import EpipolarPair, _to_map

#: Side of the least-squares refinement's window (pixels, odd).
REFINE_WINDOW_PX = 15
#: Refinement iterations, and how far they may move SGBM's disparity (pixels).
REFINE_ITERATIONS = 4
MAX_REFINE_PX = 1.0
#: The largest matching σ kept (pixels): a window that cannot tell its match from the next
#: pixel's (full P pair: the 0.01 % of pixels above it were 24 % of the squared error; the
#: reduced pair's textureless patches, whole windows at 100 m, sit between 0.5 and 1 px).
MAX_SIGMA_PX = 1.0
#: SGBM's block (pixels, odd), smoothness penalties per 8-bit grey level and block pixel,
#: uniqueness (%), left–right tolerance (px), speckle filter (pixels, disparity range).
SGBM_BLOCK_PX = 5
SGBM_P1, SGBM_P2 = 8, 32
SGBM_UNIQUENESS = 10
SGBM_LR_PX = 1
SGBM_SPECKLE_PX, SGBM_SPECKLE_RANGE = 100, 2
#: Margin around the tie points' disparity range (pixels, each side).
DISPARITY_MARGIN_PX = 8.0
#: Lowest gradient energy of a refinement window (counts² per pixel): flatter is refused.
MIN_GRADIENT = 0.2
#: Points triangulated at once (memory: about 1 kB each in flight).
_CHUNK = 1 << 20


@dataclass(frozen=True, eq=False)
class Disparity:
    """A disparity field on the epipolar grid (``u_b = u_a + d``, pixels; NaN where
    refused), its matching σ (pixels) and what each test refused."""

    d: NDArray[np.float32]
    sigma: NDArray[np.float32]
    counts: dict[str, int]

    @property
    def valid(self) -> NDArray[np.bool_]:
        return np.isfinite(self.d)


def _box(x: NDArray, w: int) -> NDArray:
    import cv2

    return cv2.boxFilter(x, -1, (w, w), normalize=True, borderType=cv2.BORDER_REFLECT)


def _bytes(img: NDArray[np.float32]) -> NDArray[np.uint8]:
    return np.clip(np.rint(np.nan_to_num(img, nan=0.0)), 0, 255).astype(np.uint8)


def _sgbm(left: NDArray, right: NDArray, d_lo: float, d_hi: float) -> NDArray[np.float32]:
    """OpenCV's SGBM (its disparity ``left(x) = right(x − D)``: ``D = −d``), NaN where it
    found none."""
    import cv2

    lo = int(np.floor(-d_hi - DISPARITY_MARGIN_PX))
    n = int(np.ceil((d_hi - d_lo + 2 * DISPARITY_MARGIN_PX) / 16.0)) * 16
    if n + SGBM_BLOCK_PX >= left.shape[1]:
        raise GeometryError(
            f"a disparity search of {n} px over epipolar images {left.shape[1]} px wide: the "
            "pair overlaps too little for its relief"
        )
    cn = 1
    sgbm = cv2.StereoSGBM.create(
        minDisparity=lo,
        numDisparities=n,
        blockSize=SGBM_BLOCK_PX,
        P1=SGBM_P1 * cn * SGBM_BLOCK_PX**2,
        P2=SGBM_P2 * cn * SGBM_BLOCK_PX**2,
        disp12MaxDiff=SGBM_LR_PX,
        uniquenessRatio=SGBM_UNIQUENESS,
        speckleWindowSize=SGBM_SPECKLE_PX,
        speckleRange=SGBM_SPECKLE_RANGE,
        mode=cv2.StereoSGBM_MODE_SGBM_3WAY,
    )
    raw = sgbm.compute(_bytes(left), _bytes(right))
    d = -raw.astype(np.float32) / 16.0
    d[raw < lo * 16] = np.nan
    return d


#: Lags over which the residual's correlation is measured (pixels, each axis).
CORRELATION_LAGS = 4


def _correlation_factor(res: NDArray, d: NDArray, w: int) -> float:
    """How much the window's residuals' correlation inflates Förstner's variance: the
    residual (what the two images still differ by once aligned: blur, aliasing, relief) is
    not white, and the variance of a least-squares shift over ``w`` pixels of correlated
    residuals is the white one times ``Σ (1 − |k|/w) ρ(k)`` along each axis (the variance of
    a mean of correlated samples); ``ρ`` measured over the whole image at lags up to
    ``CORRELATION_LAGS``."""
    ok = np.isfinite(d) & (res != 0)
    r = np.where(ok, res, 0.0).astype(np.float64)
    var = float(np.sum(r * r))
    if var <= 0:
        return 1.0
    factor = 1.0
    for axis in (0, 1):
        total = 1.0
        for k in range(1, CORRELATION_LAGS + 1):
            a = np.take(r, np.arange(r.shape[axis] - k), axis=axis)
            b = np.take(r, np.arange(k, r.shape[axis]), axis=axis)
            rho = float(np.sum(a * b)) / var
            total += 2.0 * (1.0 - k / w) * rho
        factor *= max(total, 1.0)
    return factor


#: Rows refined at once (memory: about 130 bytes a pixel in flight).
_REFINE_ROWS = 1024


def _window_sums(
    g: NDArray[np.float32],
    gv: NDArray[np.float32],
    y: NDArray[np.float32],
    kept: NDArray[np.float32],
    w: int,
) -> NDArray[np.float32]:
    """The window sums of :data:`levels.cor.epipolar.WINDOW_SUMS` over ``w × w`` windows
    (``g``, ``gv``, ``y`` zero where ``kept`` is)."""
    import cv2

    t = np.arange(w, dtype=np.float32) - np.float32(w // 2)
    one, t2 = np.ones(w, dtype=np.float32), t * t
    gg, ggv = g * g, g * gv
    gy = g * y
    terms = (
        (g, one, one), (g, t, one), (g, one, t), (gv, one, one), (y, one, one),
        (gg, one, one), (gg, t, one), (gg, one, t), (gg, t2, one), (gg, t, t), (gg, one, t2),
        (ggv, one, one), (ggv, t, one), (ggv, one, t), (gv * gv, one, one),
        (gy, one, one), (gy, t, one), (gy, one, t), (gv * y, one, one), (y * y, one, one),
        (kept, one, one),
    )  # fmt: skip
    out = np.empty((len(terms), *g.shape), dtype=np.float32)
    for k, (f, kx, kz) in enumerate(terms):
        cv2.sepFilter2D(f, cv2.CV_32F, kx, kz, dst=out[k], borderType=cv2.BORDER_REFLECT)
    return out


def _refine(
    left: NDArray[np.float32], right: NDArray[np.float32], d0: NDArray[np.float32]
) -> tuple[NDArray[np.float32], NDArray[np.float32], NDArray[np.float32], NDArray[np.float32]]:
    """SGBM's disparity refined by least squares (module docstring, step 2): the disparity,
    its σ before the residual's correlation, the window's centred gradient energy per pixel
    and the residual image."""
    w, n = REFINE_WINDOW_PX, REFINE_WINDOW_PX**2
    gx_right = np.gradient(right, axis=1).astype(np.float32)
    gv_right = np.gradient(right, axis=0).astype(np.float32)
    lft = np.nan_to_num(left).astype(np.float32)
    ok = np.isfinite(d0)
    d_ref = np.float32(np.median(d0[ok])) if ok.any() else np.float32(0.0)
    d = np.where(ok, d0, d_ref).astype(np.float32)
    var = s2 = den = np.zeros_like(d)
    for _ in range(REFINE_ITERATIONS):
        rw = shift_rows(right, d)
        # a window's pixels: those with a disparity from SGBM, read inside both images (the
        # others' first-order model does not hold: they are left out, not zeroed in)
        kept = np.isfinite(d) & np.isfinite(rw) & np.isfinite(left)
        g = np.where(kept, shift_rows(gx_right, d), 0.0).astype(np.float32)
        gv = np.where(kept, shift_rows(gv_right, d), 0.0).astype(np.float32)
        g, gv = np.nan_to_num(g), np.nan_to_num(gv)
        # y = g·d_true(q) + c, to first order, whatever the disparity d(q) each pixel was
        # warped by: the window fits d_true as a plane (its slope) and solves for its value
        # at its centre, not a mean of its pixels' (biased on a slope by where the texture
        # lies in the window); gv·θ takes the v-parallax the epipolar grid leaves
        y = np.where(kept, lft - rw + g * (d - d_ref), 0.0).astype(np.float32)
        sums = _window_sums(g, gv, y, kept.astype(np.float32), w)
        new, var, s2 = window_solve(sums, n // 2)
        den = (sums[5] - sums[0] * sums[0] / np.maximum(sums[20], 1.0)) / np.maximum(sums[20], 1.0)
        new += d_ref
        d = (d + np.clip(new - d, -0.5, 0.5)).astype(np.float32)
        d[~ok] = np.nan
    rw0 = np.nan_to_num(shift_rows(right, d))
    res = (lft - _box(lft, w)) - (rw0 - _box(rw0, w))
    return d, np.sqrt(s2 * var).astype(np.float32), den.astype(np.float32), res


def match(
    left: NDArray[np.float32], right: NDArray[np.float32], d_lo: float, d_hi: float
) -> Disparity:
    """Dense disparity between two epipolar images over ``[d_lo, d_hi]`` pixels (module
    docstring, step 2)."""
    counts: dict[str, int] = {}
    bad = ~(np.isfinite(left))
    d0 = _sgbm(left, right, d_lo, d_hi)
    d0[bad] = np.nan
    counts["sgbm_none"] = int(np.sum(~np.isfinite(d0) & ~bad))
    d, sigma, den, res = (np.empty_like(d0) for _ in range(4))
    # by strips of rows, each with a halo the iterations' windows reach through: the same
    # disparities as the whole image at once, in a bounded memory
    halo = REFINE_ITERATIONS * (REFINE_WINDOW_PX // 2) + 2
    for r0 in range(0, left.shape[0], _REFINE_ROWS):
        r1 = min(r0 + _REFINE_ROWS, left.shape[0])
        a, b = max(r0 - halo, 0), min(r1 + halo, left.shape[0])
        out = _refine(left[a:b], right[a:b], d0[a:b])
        for whole, part in zip((d, sigma, den, res), out, strict=True):
            whole[r0:r1] = part[r0 - a : r1 - a]
    sigma *= np.float32(np.sqrt(_correlation_factor(res, d, REFINE_WINDOW_PX)))
    moved = np.abs(d - d0)
    refused = [
        ("refinement_moved", np.isfinite(d0) & ~(moved <= MAX_REFINE_PX)),
        ("flat", np.isfinite(d0) & ~(den >= MIN_GRADIENT)),
        ("uncertain", np.isfinite(d0) & ~(sigma <= MAX_SIGMA_PX)),
    ]
    keep = np.isfinite(d0) & np.isfinite(d)
    for why, mask in refused:
        counts[why] = int(np.sum(mask & keep))
        keep &= ~mask
    d[~keep] = np.nan
    sigma[~keep] = np.nan
    counts["valid"] = int(keep.sum())
    return Disparity(d, sigma, counts)


def disparity_range(
    pair: EpipolarPair, ties_a: ControlPointSet, ties_b: ControlPointSet
) -> tuple[float, float]:
    """The disparity range the pair's tie points span (pixels): each tie point's raw
    positions taken onto the epipolar grid through each view's model at ``h0``."""
    common = sorted(set(ties_a.id) & set(ties_b.id))
    if len(common) < 3:
        raise GeometryError(
            f"{len(common)} tie points between the pair: the disparity range needs 3 or more"
        )
    ia = [ties_a.id.index(t) for t in common]
    ib = [ties_b.id.index(t) for t in common]
    first = (pair.a, pair.b)
    u = []
    for view, ties, idx in zip(first, (ties_a, ties_b), (ia, ib), strict=True):
        line = np.asarray(ties.line)[idx] - view.first_line
        col = np.asarray(ties.column)[idx]
        on = view.model.image_to_ground(line, col, view.reference_height_m)
        x, y = _to_map(pair.frame.crs_wkt).transform(np.degrees(on.lon_rad), np.degrees(on.lat_rad))
        uu, _ = pair.frame.uv_of(np.asarray(x), np.asarray(y))
        u.append(uu)
    d = u[1] - u[0]
    d = d[np.isfinite(d)]
    return float(np.min(d)), float(np.max(d))


#: The coarse search's reduction, and its range beyond the tie points' (coarse pixels).
COARSE_FACTOR = 8
COARSE_MARGIN_PX = 24


def coarse_range(
    left: NDArray[np.float32], right: NDArray[np.float32], d_range: tuple[float, float]
) -> tuple[float, float]:
    """The disparity range of the whole pair: SGBM on both images reduced ``COARSE_FACTOR``
    times (area averages) over the tie points' range widened by ``COARSE_MARGIN_PX`` coarse
    pixels each side (tie points, matched where the parallax is small, may miss the
    highest and lowest ground), where both are valid; its 1–99 % span, full scale, a
    coarse pixel wider each side, united with ``d_range``."""
    import cv2

    f = COARSE_FACTOR

    def reduce(x: NDArray) -> NDArray:  # NaN where any pixel of the area is
        return cv2.resize(x, None, fx=1 / f, fy=1 / f, interpolation=cv2.INTER_AREA)

    small = [reduce(x) for x in (left, right)]
    lo, hi = d_range[0] / f - COARSE_MARGIN_PX, d_range[1] / f + COARSE_MARGIN_PX
    try:
        d = _sgbm(np.nan_to_num(small[0]), np.nan_to_num(small[1]), lo, hi)
    except GeometryError:  # a pair too small to be reduced that much: the tie points' range
        return d_range
    # only where the left pixel and its match on the right are valid
    rows, cols = np.nonzero(np.isfinite(d) & np.isfinite(small[0]))
    at = np.rint(cols + d[rows, cols]).astype(np.int64)
    inside = (at >= 0) & (at < d.shape[1])
    ok = np.zeros(rows.size, dtype=bool)
    ok[inside] = np.isfinite(small[1][rows[inside], at[inside]])
    d = d[rows[ok], cols[ok]] * f
    if d.size < 100:
        return d_range
    p_lo, p_hi = np.percentile(d, [1.0, 99.0])
    return min(d_range[0], float(p_lo) - f), max(d_range[1], float(p_hi) + f)
