"""``station compare``, ``inspect`` and ``export``: what users do with level products."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

from station.cli._options import add_json, add_out, emit
from station.errors import StationError

if TYPE_CHECKING:
    from station.cli._options import Subparsers

__all__ = ["register"]


def register(sub: Subparsers) -> None:
    comp = sub.add_parser(
        "compare",
        help="compare two products or two run directories (exit 0 within "
        "tolerances, 1 outside, 2 on bad input)",
        description="Compare two level products, or two run directories (their products "
        "matched by name, and their reports' decode statistics), with named "
        "tolerances (docs/compare.md). Exit 0 within the tolerances, 1 outside, "
        "naming each difference; 2 on bad input.",
    )
    comp.add_argument("a", help="a product (.nc, .h5) or a run, process or campaign directory")
    comp.add_argument("b", help="the product or run directory to compare it with")
    comp.add_argument(
        "--tolerances", help="TOML file overriding the default tolerances (docs/compare.md)"
    )
    add_json(comp)
    comp.set_defaults(func=_compare)
    insp = sub.add_parser(
        "inspect",
        help="what a level product holds, at a glance",
        description="Summarise a level product: its bands, scene, map grid, headline "
        "quality figures and provenance.",
    )
    insp.add_argument("product", help="a level product (.nc or .h5)")
    add_json(insp)
    insp.set_defaults(func=_inspect)
    _add_export(sub)
    tie = sub.add_parser(
        "tie",
        help="tie points between two passes' 2A products, written as each pass's tie file",
        description="Find the same ground in two overlapping 2A (or 2) products of different "
        "passes (or of a twin) and write the tie points, measured in each raw image, as "
        "control points of kind 'tie' (docs/gcp.md): <name>.tie.csv for each pass.",
    )
    tie.add_argument("a", help="the first pass's 2A product (its map grid is the common one)")
    tie.add_argument("b", help="the second pass's 2A product")
    tie.add_argument("--band", help="the band matched (default: the first)")
    tie.add_argument("--out", required=True, help="directory of the two tie files")
    add_json(tie)
    tie.set_defaults(func=_tie)


def _add_export(sub: Subparsers) -> None:
    expo = sub.add_parser(
        "export",
        help="export a product as a GeoTIFF, or a 1A as a SPOT DIMAP scene with its truth",
        description="--geotiff: write a product as a tiled, compressed GeoTIFF with its "
        "validity mask, for GDAL and QGIS: a map level (2A, 2, 3) with its CRS and "
        "geotransform, an image-geometry level (1A, 1B) with the RPCs fitted to its rigorous "
        "model (gdalwarp -rpc -to RPC_DEM=dem.tif orthorectifies it). --dimap DIR: write a 1A "
        "as a SPOT 1-4 DIMAP v1 scene (METADATA.DIM + IMAGERY.TIF) with the truth to score a "
        "processing against (the terrain, checkpoints, control points, true orbit and "
        "attitude: docs/benchmark.md).",
    )
    expo.add_argument("product", help="a level product (.nc or .h5), or an L0 archive (--packets)")
    fmt = expo.add_mutually_exclusive_group(required=True)
    fmt.add_argument("--geotiff", action="store_true", help="GeoTIFF through GDAL")
    fmt.add_argument(
        "--dimap",
        metavar="DIR",
        help="a 1A as a SPOT DIMAP v1 scene and its truth in DIR (replaced whole)",
    )
    fmt.add_argument(
        "--packets",
        metavar="DIR",
        help="an L0 archive's lines and auxiliary records as CCSDS space packets, one file "
        "per APID with its packet definition (ccsdspy's CSV) in DIR (docs/l0.md)",
    )
    expo.add_argument(
        "--scenario",
        help="with --dimap: the scenario that made the product, for the truth (default: the "
        "one the run's report.json names, when it is found)",
    )
    expo.add_argument(
        "--mission-index",
        type=int,
        default=2,
        choices=(1, 2, 3),
        help="with --dimap: the SPOT written as MISSION_INDEX (the emulated HRV flies SPOT "
        "1-3's orbit; default 2)",
    )
    add_out(
        expo,
        "with --geotiff: output file or directory (default: the product's name with .tif, "
        "in the current directory)",
    )
    expo.set_defaults(func=_export)


def _tie(args: argparse.Namespace) -> int:
    from station.products import tie_products

    result = tie_products(args.a, args.b, args.band, args.out)
    emit(
        args,
        result,
        lambda r: (
            f"{r['points']} tie points (of {r['counts']['candidates']} candidates; "
            + ", ".join(
                f"{k} {v}" for k, v in r["counts"].items() if k not in ("candidates", "kept")
            )
            + ") in "
            + ", ".join(r["files"])
        ),
    )
    return 0 if result["points"] else 2


def _compare(args: argparse.Namespace) -> int:
    from station.compare import compare_inputs, tolerances_of

    result = compare_inputs(args.a, args.b, tolerances_of(args.tolerances))
    emit(args, result.as_dict() if args.json else result, lambda r: r.text())
    return 0 if result.ok else 1


def _inspect(args: argparse.Namespace) -> int:
    from station.products import inspect_product

    summary, text = inspect_product(args.product)
    emit(args, summary, lambda _: text)
    return 0


def _export(args: argparse.Namespace) -> int:
    from station.products import export_geotiff

    src = Path(args.product)
    if args.packets:
        from station.l0_packets import export_packets

        if args.out or args.scenario:
            raise StationError("--packets names its own directory: no --out, no --scenario")
        listing = export_packets(src, args.packets)
        for f in listing["files"]:  # type: ignore[attr-defined]
            print(
                f"wrote {Path(args.packets) / f['file']}: APID {f['apid']}, {f['packets']} packets"
            )
        return 0
    if args.dimap:
        from station.benchmark_pack import write_pack

        if args.out:
            raise StationError("--out goes with --geotiff; --dimap names its own directory")
        result = write_pack(
            src, args.dimap, scenario=args.scenario, mission_index=args.mission_index
        )
        print(result.text())
        return 0
    if args.scenario:
        raise StationError("--scenario goes with --dimap")
    print(f"wrote {export_geotiff(src, args.out)}")
    return 0
