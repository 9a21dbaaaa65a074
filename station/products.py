"""What the station does with products and real metadata on their own (``station tie``,
``inspect``, ``export``, ``locate``): tie points between two passes' map products, a
product's summary, a product as a GeoTIFF, a real scene's frame located by its model
(:mod:`levels.locate`), each a function the command line calls and prints."""

from __future__ import annotations

from pathlib import Path

from levels.locate import check_frame, check_gcps, write_rpc
from station.errors import StationError

__all__ = [
    "check_frame",
    "check_gcps",
    "export_geotiff",
    "inspect_product",
    "parse_heights",
    "tie_products",
    "write_rpc",
]


def tie_products(
    a: str | Path, b: str | Path, band: str | None, out: str | Path
) -> dict[str, object]:
    """Tie points between two passes' map products (:func:`levels.tiepoints.match_views`),
    written as ``<pass>.tie.csv`` into ``out``: the files, the points kept and the
    matcher's counts."""
    from levels.products import read_product
    from levels.readers.gcp import write_gcps
    from levels.tiepoints import MapView, match_views

    va, vb = (MapView.of_product(read_product(p), band) for p in (a, b))
    if va.name == vb.name and va.hrv == vb.hrv:
        raise StationError(f"{a} and {b} are the same pass ({va.name}, HRV{va.hrv})")
    tp = match_views(va, vb)
    where = Path(out)
    where.mkdir(parents=True, exist_ok=True)
    files = []
    for which, view in (("a", va), ("b", vb)):
        tag = view.name  # the archive's name: station process --ties looks for it
        comment = f"tie points of {va.name} HRV{va.hrv} and {vb.name} HRV{vb.hrv} (docs/gcp.md)"
        files.append(str(write_gcps(where / f"{tag}.tie.csv", tp.control_points(which), comment)))
    return {"files": files, "points": len(tp), "counts": tp.counts}


def inspect_product(path: str | Path) -> tuple[dict[str, object], str]:
    """A product's summary (:func:`levels.inspect.product_summary`) and its text."""
    from levels.inspect import product_summary, summary_text
    from levels.products import read_product

    summary = product_summary(read_product(path), path)
    return summary, summary_text(summary)


def export_geotiff(src: Path, out: str | Path | None) -> Path:
    """A product as a GeoTIFF (:func:`levels.export.write_geotiff`) at ``out`` (a file, or
    a directory to hold it; by default here, never into a run directory the station
    replaces whole), replacing only an earlier export of the same product."""
    from levels.export import export_identity, exported_identity, write_geotiff
    from levels.products import read_product
    from station.outdir import replaceable_file

    target = Path(out) if out else Path(src.with_suffix(".tif").name)
    if target.is_dir():  # a directory: the product's name in it
        target = target / src.with_suffix(".tif").name
    above = next((d for d in target.parents if d.exists()), None)
    if above is not None and not above.is_dir():
        raise StationError(f"--out {target}: {above} is a file, not a directory")
    product = read_product(src)
    identity = export_identity(product)
    replaceable_file(target, exported_identity, identity, _an_export)
    return write_geotiff(product, target)


def _an_export(identity: object) -> str:
    name, scene, level = (str(x) for x in identity) if isinstance(identity, tuple) else ("",) * 3
    return f"a GeoTIFF export of {name} scene {scene} level {level}"


def parse_heights(text: str) -> tuple[float, float]:
    """``LO,HI`` (m above the ellipsoid): finite, LO < HI, both on Earth
    (:data:`levels.readers.dem.EARTH_HEIGHTS_M`); :class:`StationError` otherwise."""
    from levels.readers.dem import EARTH_HEIGHTS_M

    try:
        lo, hi = (float(x) for x in text.split(","))
    except ValueError:
        raise StationError(f"--heights {text!r}: expected LO,HI in metres") from None
    a, b = EARTH_HEIGHTS_M
    if not (a <= lo < hi <= b):
        raise StationError(
            f"--heights {text!r}: expected LO < HI within {a:g}–{b:g} m (heights on Earth, "
            "in metres above the ellipsoid)"
        )
    return lo, hi
