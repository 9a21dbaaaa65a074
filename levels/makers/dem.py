"""A stereo pair's DEM (:mod:`levels.stereo`): heights above the ellipsoid triangulated from
two scenes of two passes over one ground, on a map grid of their own, declared once.

Its products carry the pair's geometry (``geometry/stereo``: the epipolar frame, B/H) and
the DEM's (``geometry/dem``: cell, stride, matcher); their headline figures are the heights
against the truth (RMSE, bias, NMAD, coverage) and the disparity's RMS, when the station
measured them.
"""

from __future__ import annotations

import datetime as dt
from pathlib import Path

import numpy as np

from levels import __version__
from levels.choices import Level
from levels.errors import GeometryError
from levels.kinds import (
    BandSpec,
    Browse,
    Export,
    Figure,
    Inspection,
    ProductKind,
    Unit,
    headline,
)
from levels.makers.pairs import PairMade, PairMaker, PairMeasure, PairScene
from levels.products import BandImage, Product
from levels.quality import DemHeadline
from levels.stereo import REFINE_WINDOW_PX, StereoDem, StereoPoints

__all__ = ["KIND", "dem_name", "dem_product"]


def _inspect(product: Product) -> Inspection:
    a, pair = product.attrs, product.geometry["stereo"]
    views = [str(pair["view_a"]), str(pair["view_b"])]
    section: dict[str, object] = {
        "views": views,
        "base_to_height": round(float(pair["base_to_height"]), 4),
        "epipolar_error_px": round(float(pair["epipolar_error_px"]), 4),
        "cell_m": float(product.geometry.get("dem", {}).get("cell_m", np.nan)),
    }
    title = (
        f"level {a.get('level')} of the pair {' + '.join(views)}, B/H "
        f"{section['base_to_height']:.2f}, epipolar error {section['epipolar_error_px']:.3f} "
        f"px, {a.get('n_rows')} × {a.get('n_cols')} cells of {section['cell_m']:g} m, "
        f"heights above the {a.get('vertical', 'ellipsoid')}"
    )
    return Inspection(title, {"stereo": section})


def _stac(product: Product) -> dict[str, object]:
    """A pair's Item spans its two dates (``datetimes_utc``)."""
    times = sorted(
        dt.datetime.fromisoformat(t[:26]).replace(tzinfo=dt.UTC)
        for t in str(product.attrs["datetimes_utc"]).split()
    )
    return {
        "datetime": None,
        "start_datetime": times[0],
        "end_datetime": times[-1],
        "constellation": "spot",
        "processing:level": "DEM",
        "title": str(product.attrs.get("name", "")),
        "description": "a stereo pair's DEM",
    }


def _make(a: PairScene, b: PairScene, out: Path, measure: PairMeasure | None) -> PairMade | None:
    """The DEM of two scenes (their level 2 and 1A products, their passes' tie points) into
    ``out``, with its GeoTIFF; None when their epipolar frames do not overlap."""
    from levels.export import write_geotiff
    from levels.products import read_product, write_product
    from levels.stereo import StereoView, disparity_range, epipolar_pair, stereo_dem

    va, vb = (
        StereoView.of_products(
            read_product(s.products[Level.L2]), read_product(s.products[Level.L1A])
        )
        for s in (a, b)
    )
    try:
        pair = epipolar_pair(va, vb)
    except GeometryError:  # these two scenes do not overlap
        return None
    dem = stereo_dem(pair, disparity_range(pair, a.ties, b.ties))
    quality = measure(dem) if measure is not None else {}
    name = dem_name(dem)
    inputs = [s.products[Level.L2].name for s in (a, b)]
    product = dem_product(dem, quality, inputs=inputs)
    path = write_product(out / name, product)
    tif = write_geotiff(product, out / name.replace(".nc", ".tif"))
    return PairMade(path, tif, quality, dict(dem.timings_s))


KIND = ProductKind(
    name="DEM",
    doc="a stereo pair's DEM: heights above the ellipsoid, triangulated",
    unit=Unit.PAIR,
    on_map=True,
    geometry_trees=("stereo", "dem"),
    export=Export.MAP,
    inspect=_inspect,
    bands=(
        BandSpec(
            "height_m", "height above the WGS84 ellipsoid", "height_above_reference_ellipsoid"
        ),
        BandSpec("points", "points triangulated in the cell", dtype="uint16", fill=None),
        BandSpec("sigma_m", "predicted 1 sigma of the cell's height"),
    ),
    # the raster level 3 and any GIS read as a DEM: its heights alone, NaN GDAL's nodata
    export_bands=("height_m",),
    export_tags=("vertical",),
    requires=(Level.L1A, Level.L2),
    figures=(
        # against the true terrain: as made (its datum from the control points), and its
        # own error with the datum (bias and tilt) taken off; the disparity's own error
        Figure("RMSE m", "8.2f", headline(DemHeadline.of, "rmse_m")),
        Figure("bias m", "8.2f", headline(DemHeadline.of, "bias_m")),
        Figure("less datum m", "13.2f", headline(DemHeadline.of, "less_datum_rmse_m")),
        Figure("NMAD m", "8.2f", headline(DemHeadline.of, "nmad_m")),
        Figure("coverage", "9.3f", headline(DemHeadline.of, "coverage")),
        Figure("disparity rms px", "17.3f", headline(DemHeadline.of, "disparity_rms_px")),
    ),
    browse=Browse("height_m", "terrain", "height above the WGS84 ellipsoid (m)"),
    stac=_stac,
    maker=PairMaker(_make),
    # heights in metres: a different CPU's last bits, never a centimetre
    tolerances={"pixels": {"quantity_max_abs": 0.01, "quantity_rms": 0.001}},
)


def dem_name(dem: StereoDem) -> str:
    """A pair's product name, as its tie points are named: ``<a>_s<k>_<b>_s<k>_DEM.nc``."""
    a, b = dem.pair.a, dem.pair.b
    return f"{a.name}_s{a.scene:03d}_{b.name}_s{b.scene:03d}_{KIND.name}.nc"


def _miss_stats(points: StereoPoints) -> dict[str, float]:
    m = points.miss_m[np.isfinite(points.miss_m)]
    return {
        "rms_m": float(np.sqrt(np.mean(m**2))) if m.size else float("nan"),
        "p99_abs_m": float(np.percentile(np.abs(m), 99)) if m.size else float("nan"),
    }


def dem_product(
    dem: StereoDem, quality: dict[str, object] | None = None, inputs: list[str] | None = None
) -> Product:
    """The pair's DEM as a map product (``docs/stereo.md``): bands ``height_m`` (above the
    ellipsoid, NaN in holes), ``points`` and ``sigma_m``; the pair's geometry; its quality
    (the matching's counts, the rays' miss, and what ``quality`` adds: the truth's). Its
    wall times are not in it (:attr:`levels.stereo.StereoDem.timings_s`): a rerun makes
    the same bytes."""
    valid = np.isfinite(dem.height_m)
    bands = {
        "height_m": BandImage(dem.height_m, valid),
        "points": BandImage(dem.count, valid),
        "sigma_m": BandImage(dem.sigma_m, valid),
    }
    a, b = dem.pair.a, dem.pair.b
    q = {
        "matching": dict(dem.disparity.counts),
        "disparity_range_px": np.array(dem.disparity_range_px),
        "ray_miss": _miss_stats(dem.points),
        "triangulation_anchor_error_m": dem.anchor_error_m,
        "valid_cell_fraction": float(valid.mean()),
        "predicted_sigma_rms_m": float(np.sqrt(np.nanmean(dem.sigma_m.astype(np.float64) ** 2))),
        **(quality or {}),
    }
    return Product(
        attrs={
            "level": KIND.name,
            "name": f"{a.name}_s{a.scene:03d}_{b.name}_s{b.scene:03d}",
            "vertical": "ellipsoid",
            "datetimes_utc": f"{a.time_utc} {b.time_utc}",
            "n_rows": dem.grid.n_rows,
            "n_cols": dem.grid.n_cols,
        },
        bands=bands,
        geometry={
            "stereo": dem.pair.tree(),
            "dem": {
                "cell_m": float(abs(dem.grid.geotransform[1])),
                "stride_px": dem.points.stride,
                "matcher": "OpenCV StereoSGBM + least-squares refinement",
                "refine_window_px": REFINE_WINDOW_PX,
            },
        },
        quality=q,
        provenance={"software": f"levels {__version__}", "inputs": ", ".join(inputs or [])},
        map_grid=dem.grid,
    )
