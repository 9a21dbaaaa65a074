"""Radiometry of a geocoded frame: γ⁰ by radiometric terrain flattening (Small 2011, as
sarsen), the output's pixels as facets over the DEM splatted into the slant cells.
"""

from __future__ import annotations

import numba as nb
import numpy as np
from numpy.typing import NDArray

from levels.geometry.ellipsoid import WGS84
from levels.sar.annotation import SarImage, _to_geo, nominal_cell_m2
from levels.sar.geocoding import Geocoded
from levels.threads import over_blocks

#: Cells where the terrain shows the radar less than this share of their nominal area
#: (seen edge-on, or all hidden) are not flattened: NaN.
FLATTEN_MIN_AREA = 0.05


@nb.njit(cache=True, nogil=True)
def _kernel_facets(height, shadow, line, col, los, step, px, n_l, n_s, shown):
    """Every output pixel a facet of the terrain (:func:`terrain_flattening`): its
    ``A·cos θ_loc = px² · n · l`` (``n`` from central differences of ``height``, one-sided
    at the grid's edges; ``l`` east, north, up from ``los`` every ``step`` pixels,
    bilinearly) added into ``shown`` (the slant image's cells, flat) about its (line,
    column), bilinearly; nothing for a facet turned away, in shadow, or off the DEM.
    Serial: facets of any rows add into the same cells."""
    n_rows, n_cols = height.shape
    na, nb = los.shape[1], los.shape[2]
    inv = 1.0 / step
    for i in range(n_rows):
        a = min(i // step, na - 2)
        fu = (i - a * step) * inv
        i0, i1 = max(i - 1, 0), min(i + 1, n_rows - 1)
        b, jb = 0, -1
        for j in range(n_cols):
            jb += 1
            if jb == step and b < nb - 2:
                b, jb = b + 1, 0
            q_l, q_c = line[i, j], col[i, j]
            if shadow[i, j] or not (q_l == q_l and q_c == q_c):
                continue
            j0, j1 = max(j - 1, 0), min(j + 1, n_cols - 1)
            d_south = (height[i1, j] - height[i0, j]) / ((i1 - i0) * px)
            d_east = (height[i, j1] - height[i, j0]) / ((j1 - j0) * px)
            fv = jb * inv
            w00, w10 = (1.0 - fu) * (1.0 - fv), fu * (1.0 - fv)
            w01, w11 = (1.0 - fu) * fv, fu * fv
            area = 0.0
            for c in range(3):  # n · l, n = (−∂h/∂E, ∂h/∂S, 1)
                lc = (
                    w00 * los[c, a, b]
                    + w10 * los[c, a + 1, b]
                    + w01 * los[c, a, b + 1]
                    + w11 * los[c, a + 1, b + 1]
                )
                area += lc * (-d_east if c == 0 else (d_south if c == 1 else 1.0))
            area *= px * px
            if not area > 0.0:
                continue
            l0, c0 = int(np.floor(q_l)), int(np.floor(q_c))
            fl, fc = q_l - l0, q_c - c0
            for dl in range(2):
                for dc in range(2):
                    ll, cc = l0 + dl, c0 + dc
                    if 0 <= ll < n_l and 0 <= cc < n_s:
                        wl = fl if dl else 1.0 - fl
                        wc = fc if dc else 1.0 - fc
                        shown[ll * n_s + cc] += wl * wc * area


@nb.njit(cache=True, nogil=True)
def _kernel_read(lo, hi, image, line, col, valid, out):
    """Rows ``lo … hi − 1``: ``image`` bilinearly at each valid pixel's (line, column)."""
    n_l, n_s = image.shape
    for i in range(lo, hi):
        for j in range(out.shape[1]):
            if not valid[i, j]:
                continue
            l0 = min(max(int(np.floor(line[i, j])), 0), n_l - 2)
            c0 = min(max(int(np.floor(col[i, j])), 0), n_s - 2)
            fl, fc = line[i, j] - l0, col[i, j] - c0
            out[i, j] = (1.0 - fl) * ((1.0 - fc) * image[l0, c0] + fc * image[l0, c0 + 1]) + fl * (
                (1.0 - fc) * image[l0 + 1, c0] + fc * image[l0 + 1, c0 + 1]
            )


def terrain_flattening(g: Geocoded, image: SarImage) -> NDArray[np.float32]:
    """γ⁰ of each output pixel of a GTC by radiometric terrain flattening (Small 2011,
    "Flattening Gamma", IEEE TGRS 49(8); what sarsen does): the slant image's intensity (σ⁰
    reckoned on the ellipsoid's nominal cell, :func:`nominal_cell_m2`) times that cell's
    area over the area the terrain presents to the radar in it, ``A_γ = Σ A·cos θ_loc``
    over the terrain imaged there; on flat ground ``σ⁰ / cos θ``. The terrain is the
    output's pixels over the DEM (``g.height_m``), each of area ``A = px² · |n|`` with
    ``n = (−∂h/∂E, −∂h/∂N, 1)``, so that ``A·cos θ_loc = px² · n · l`` (``l`` the unit
    vector to the antenna, exact at the anchors); facets turned away or in shadow count
    nothing; each is added into the cells about its (line, column) bilinearly
    (:func:`_kernel_facets`). The flattened image is then read at each pixel's (line,
    column) as the intensity is. NaN where the GTC is, or where a cell shows less than
    ``FLATTEN_MIN_AREA`` of its nominal area."""
    ann, grid = image.annotation, g.grid
    n_l, n_s = ann.shape
    step = g.model.step
    ai, aj = np.meshgrid(
        *(np.arange(n, dtype=np.float64) * step for n in g.model.coef.shape[2:]), indexing="ij"
    )
    x, y = grid.map_of(ai, aj)
    lon, lat = (np.radians(v) for v in _to_geo(grid).transform(np.ravel(x), np.ravel(y)))
    p = WGS84.to_ecef(lat, lon, np.full(lat.shape, g.model.h_mid))
    _, r, _, s = ann._solve(p, None)
    to_antenna = (s - p) / r[:, None]
    east = np.stack([-np.sin(lon), np.cos(lon), np.zeros_like(lon)], axis=-1)
    north = np.stack([-np.sin(lat) * np.cos(lon), -np.sin(lat) * np.sin(lon), np.cos(lat)], axis=-1)
    los = np.stack(
        [
            np.sum(to_antenna * axis, axis=1).reshape(ai.shape)
            for axis in (east, north, WGS84.up(lat, lon))
        ]
    )
    shown = np.zeros(n_l * n_s)
    _kernel_facets(
        np.asarray(g.height_m, dtype=np.float32),
        g.shadow,
        g.line,
        g.column,
        np.ascontiguousarray(los),
        int(step),
        float(grid.pixel_size_m),
        n_l,
        n_s,
        shown,
    )
    cell = nominal_cell_m2(ann, g.model.h_mid)[None, :]
    a_gamma = shown.reshape(n_l, n_s)
    flat = np.full((n_l, n_s), np.nan)
    np.divide(image.intensity * cell, a_gamma, out=flat, where=a_gamma > FLATTEN_MIN_AREA * cell)
    out = np.full(grid.shape, np.nan, dtype=np.float32)
    over_blocks(
        _kernel_read, grid.n_rows, flat, g.line, g.column, np.isfinite(g.intensity), out, grain=64
    )
    return out
