"""The processing centre's public face: what a user of ``levels`` alone needs, in one place.

    from pathlib import Path

    from levels.api import Pass, ProcessingOptions, Request, open_archive, plan, run

    archive = open_archive("pass.l0.h5")
    one = Pass((archive,), ("p",))
    request = Request(ProcessingOptions(levels=("1A", "2A")), Path("out"), (one,))
    result = run(plan(request))          # result.products: kind, path, quality, timings

One unit of work (:mod:`levels.work`: a request of passes and SAR frames, its plan, one
result), the inputs (readers, and the registry of formats), its stages (a pass's scenes,
a block of passes with the kinds of a pair, a SAR frame), the product kinds and their
registry, and what reads products (compare, export, inspect). Everything here is
importable from its own module too; this module adds nothing of its own.
``docs/architecture.md`` maps the packages behind it.
"""

from __future__ import annotations

from levels.block import BlockProducts, BlockRequest, PairMaker, process_block
from levels.compare import compare_paths, compare_products, load_tolerances
from levels.export import write_geotiff
from levels.frame import FrameOptions, process_frame
from levels.inspect import product_summary, summary_text
from levels.kinds import BandSpec, Export, ProductKind, Unit
from levels.makers.scene import register_level
from levels.options import ProcessingOptions
from levels.process import PassProducts, ProcessingRequest, process
from levels.products import Product, read_product, write_product
from levels.readers.dem import read_dem
from levels.readers.dimap import read_dimap
from levels.readers.formats import open_archive, open_frame
from levels.readers.gcp import read_gcps, write_gcps
from levels.readers.l0 import read_l0
from levels.readers.sar import SarFrame, read_sar_frame
from levels.registry import kind, kind_names, register_kind
from levels.work import Frame, Made, Measure, Pass, Plan, Request, Result, plan, run

__all__ = [
    "BandSpec",
    "BlockProducts",
    "BlockRequest",
    "Export",
    "Frame",
    "FrameOptions",
    "Made",
    "Measure",
    "PairMaker",
    "Pass",
    "PassProducts",
    "Plan",
    "ProcessingOptions",
    "ProcessingRequest",
    "Product",
    "ProductKind",
    "Request",
    "Result",
    "SarFrame",
    "Unit",
    "compare_paths",
    "compare_products",
    "kind",
    "kind_names",
    "load_tolerances",
    "open_archive",
    "open_frame",
    "plan",
    "process",
    "process_block",
    "process_frame",
    "product_summary",
    "read_dem",
    "read_dimap",
    "read_gcps",
    "read_l0",
    "read_product",
    "read_sar_frame",
    "register_kind",
    "register_level",
    "run",
    "summary_text",
    "write_gcps",
    "write_geotiff",
    "write_product",
]
