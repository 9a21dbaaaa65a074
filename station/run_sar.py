"""``station run`` of an ERS-1 SAR frame (issue 38; ADRIN, paper ``001_…`` §5): a scenario
with a ``[sar]`` table emulates one frame in slant range over the world, geocodes it onto
the ellipsoid (GEC) and over a DEM (GTC), and measures each product against the truth.

A SAR scenario names the frame (``[sar]``: where, when, its size and looks, the state
vectors' errors, the levels and their pixel), the world (``[world]``, as a pass's) and,
for GTC, the DEM the station is handed (``[dem]``, as a pass's: the world's terrain with
errors of a known size, written as ``<name>.dem.tif``). The run directory holds that
DEM, the products (``<name>_GEC.nc``, ``<name>_GTC.nc``, the house format), their STAC
catalogue and ``report.json``; it replaces an earlier run of the scenario whole, as a
pass's run does. Each product's report row gives:

* ``checkpoints``: terrain points across the frame, where the product puts them against
  where they are (output pixels and metres; the truth's own (line, column) of each,
  taken back through the product's per-pixel (line, column)), with the relief
  displacement ``Δh / tan θ`` a GEC predicts for them;
* ``masks``: layover and shadow against the truth's (IoU, and the pixels of each);
* the anchor grid's error and the time each stage took.
"""

from __future__ import annotations

import dataclasses
import logging
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from station.errors import ScenarioError, StationError
from station.flow import ScenarioRun
from station.reports import SAR_RUN
from station.sar_scenario import SarScenario

if TYPE_CHECKING:
    from levels.readers.sar import SarFrame
    from levels.sar import SarAnnotation, SarImage
    from levels.work import Made, Result
    from station.flow import FlowRun
    from station.spacecraft.sar import SarTruth
    from station.spacecraft.world import World

_log = logging.getLogger(__name__)

__all__ = ["SarRun", "frame_options", "frame_quality", "run_sar", "scenario_provenance"]


def _world(scn: SarScenario) -> Any:
    from station.spacecraft.hgt import read_hgt
    from station.spacecraft.world import World

    wc = scn.world
    grid = read_hgt(scn.path(wc.dem_path)) if wc.kind == "dem" else None
    return World(np.radians(scn.sar.target_lon_deg), wc.base_height_m, wc.relief_m, wc.seed, grid)


def _frame(scn: SarScenario) -> Any:
    from station.spacecraft.sar import ErsFrame

    c = scn.sar
    return ErsFrame(
        date_utc=c.date_utc,
        target_lat_deg=c.target_lat_deg,
        target_lon_deg=c.target_lon_deg,
        n_lines=c.lines,
        n_samples=c.samples,
        azimuth_looks=c.azimuth_looks,
        range_looks=c.range_looks,
        speckle_looks=c.speckle_looks,
        state_error_m=c.state_error_m,
        state_error_m_per_s=1e-3 * c.state_error_m,
        state_bias_m=c.state_bias_m,
        state_drift_m_per_s=c.state_drift_m_per_s,
        seed=scn.seed,
        backscatter=c.backscatter,
    )


def _footprint_rad(
    ann: SarAnnotation, heights: tuple[float, float]
) -> tuple[float, float, float, float]:
    """(south, north, west, east) of the frame's footprint over a span of heights."""
    lat, lon = (np.concatenate(a) for a in zip(*map(ann.edge_ground, heights), strict=True))
    return float(lat.min()), float(lat.max()), float(lon.min()), float(lon.max())


#: The instrument a frame's file and products name.
ERS_INSTRUMENT = "ERS-1 AMI SAR"
#: What the report keeps of a product's quality: the truth's figures (the product holds
#: more: its anchors' error, the masks' shares).
_TRUTH_KEYS = ("checkpoints", "relief_displacement", "masks", "gamma0")


def frame_options(scn: SarScenario) -> Any:
    """The processing of a scenario's frame (:class:`levels.frame.FrameOptions`): its
    ``[sar]`` levels, pixel, reference height and flattening; the grid's margin three
    times the world's relief (how far relief can move a pixel and more)."""
    from levels.frame import FrameOptions

    return FrameOptions(
        levels=tuple(scn.sar.levels),
        pixel_size_m=scn.sar.pixel_size_m,
        reference_height_m=scn.reference_height_m,
        margin_m=3.0 * _world(scn).relief_m,
        flatten=scn.sar.flatten,
    )


def scenario_provenance(scn: SarScenario) -> dict[str, object]:
    """What a SAR product records of the scenario behind its frame."""
    return {
        "scenario": scn.name,
        "scenario_file": Path(scn.source).name,
        "scenario_sha256": scn.source_sha256,
        "seed": scn.seed,
    }


def frame_quality(scn: SarScenario, frame: SarFrame) -> Any:
    """The truth of the frame a SAR scenario made, as a frame's ``measure``
    (:data:`levels.frame.Measure`): the scenario's frame emulated again (its geometry
    alone), checked to be the frame given (its annotation), and each product held to it."""
    from station.spacecraft.sar import emulate_frame

    image = frame.image()
    emulated, truth = emulate_frame(_frame(scn), _world(scn), render=False)
    a, b = emulated.annotation, image.annotation
    # the first lines' UTC (ESA's format dates it to the microsecond, from its own epoch)
    first_a, first_b = (x.epoch.utc(np.array([x.first_line_s]))[0] for x in (a, b))
    if a.shape != b.shape or abs((first_a - first_b) / np.timedelta64(1, "us")) > 1.0:
        raise StationError(
            f"{frame.path or frame.name} was not made by scenario {scn.name!r} "
            f"(its frame {b.shape[0]} × {b.shape[1]} from {b.first_line_s:.3f} s; the "
            f"scenario's {a.shape[0]} × {a.shape[1]} from {a.first_line_s:.3f} s): give the "
            "scenario that made it"
        )
    return _measure(scn, image, truth)


def _measure(scn: SarScenario, image: SarImage, truth: SarTruth) -> Any:
    """Each product of the scenario's frame held to its truth (a frame's ``measure``)."""
    from station.truth.sar import frame_truth

    return lambda level, g, gamma0: frame_truth(
        level, g, gamma0, image, truth, scn.reference_height_m, scn.sar.backscatter
    )


def run_sar(scn: SarScenario, out_dir: str | Path, *, quicklooks: bool = False) -> dict[str, Any]:
    """Run a SAR scenario into ``out_dir`` (module docstring); returns the report (also in
    ``report.json``). Built in a staging directory that replaces ``out_dir`` only when
    complete: a failure leaves the previous run as it was."""
    from station.flow import run_flow

    return run_flow(SarRun(scn), out_dir, quicklooks=quicklooks)


class SarRun(ScenarioRun):
    """The flow of ``station run`` of a SAR frame (:class:`station.flow.Flow`): the frame
    emulated, written in ESA's format and read back, its DEM exported, its products."""

    report = SAR_RUN

    def __init__(self, scn: SarScenario) -> None:
        super().__init__(scn)
        self.scn = scn
        self._truth: Any = None
        self._frame: dict[str, object] = {}
        self._dem_row: dict[str, Any] = {}

    def check(self, out: Path) -> None:
        for p in self.scn.inputs():
            if not p.is_file():
                raise ScenarioError(f"{self.scn.name}: {p} not found")

    def catalog(self) -> tuple[str, str]:
        name = self.scn.name
        return name, f"the products of a run of SAR scenario {name} (spot-station)"

    def measure(self) -> Any:
        return self._truth

    def acquire(self, stage: Path, state: FlowRun) -> Any:
        """The frame emulated over the world, its DEM exported, the frame written in the
        house format and in ESA's, and read back from ESA's (so that its reader is on every
        run's path; the house file keeps it exact)."""
        from levels.options import ProcessingOptions
        from levels.readers.envisat import read_envisat
        from levels.work import Frame, Request
        from levels.writers.envisat import write_envisat
        from levels.writers.sar import write_sar_frame
        from station.spacecraft.sar import emulate_frame
        from station.truth.measure import StationTruth

        scn, clock, timings = self.scn, time.perf_counter, state.timings
        t = clock()
        world = _world(scn)
        image, truth = emulate_frame(_frame(scn), world)
        timings["emulate"] = clock() - t
        _log.info("SAR frame %s emulated in %.1f s", scn.name, timings["emulate"])
        ann = image.annotation
        t = clock()
        dem, self._dem_row = _exported_dem(scn, world, ann, stage)
        if dem is not None:
            timings["dem_export"] = clock() - t
        t = clock()
        house = write_sar_frame(stage / f"{scn.name}.frame.h5", image, scn.name, ERS_INSTRUMENT)
        frame_path = write_envisat(stage / f"{scn.name}.E1", image)
        frame = read_envisat(frame_path)
        timings["frame_file"] = clock() - t
        self._truth = StationTruth({}, frame=_measure(scn, image, truth))
        self._frame = {
            "file": frame_path.name,
            "house_file": house.name,
            "instrument": ERS_INSTRUMENT,
            "lines": ann.shape[0],
            "samples": ann.shape[1],
            "line_interval_s": ann.line_interval_s,
            "range_spacing_m": ann.range_spacing_m,
            "near_range_m": ann.near_range_m,
            "state_error_m": scn.sar.state_error_m,
            "state_bias_m": list(scn.sar.state_bias_m),
            "state_drift_m_per_s": list(scn.sar.state_drift_m_per_s),
            "reference_height_m": scn.reference_height_m,
        }
        return Request(
            ProcessingOptions(),
            stage,
            frames=(Frame(frame),),
            frame_options=frame_options(scn),
            dem=dem,
            dem_source=self._dem_row.get("file", ""),
            provenance=scenario_provenance(scn),
        )

    def sections(self, stage: Path, result: Result, state: FlowRun) -> dict[str, Any]:
        from station.catalog import CATALOG_FILE
        from station.reports import scenario_entry

        timings = state.timings
        rows = []
        for m in result.products:
            for k, v in m.timings_s.items():
                timings[f"{k}_{m.kind}"] = v
            rows.append(_product_row(m))
        return {
            "header": {"scenario": scenario_entry(self.scn)},
            "frame": self._frame,
            **({"dem": self._dem_row} if self._dem_row else {}),
            "products": rows,
            "catalog": CATALOG_FILE,
            "timings_s": {k: round(v, 3) for k, v in timings.items()},
        }


def _exported_dem(
    scn: SarScenario, world: World, ann: SarAnnotation, out: Path
) -> tuple[Any, dict[str, Any]]:
    """With ``[dem]``: the world's terrain over the frame (and as far as its relief can
    reach) exported as ``<name>.dem.tif``, read back as the station is handed it, and what
    the report says of it; else nothing."""
    from levels.readers.dem import read_dem
    from station.spacecraft.dem import export_dem_over

    if scn.dem is None:
        return None, {}
    ref = scn.reference_height_m
    lo, hi = (ref - 3.0 * world.relief_m - 500.0, ref + 3.0 * world.relief_m + 500.0)
    dem_path = export_dem_over(
        world, _footprint_rad(ann, (lo, hi)), scn.dem, scn.seed, out / f"{scn.name}.dem.tif"
    )
    return read_dem(dem_path, "ellipsoid"), {"file": dem_path.name, **dataclasses.asdict(scn.dem)}


def _product_row(m: Made) -> dict[str, Any]:
    """What a SAR run's report says of a product (a :class:`levels.work.Made`): its size,
    valid share, anchors' error and the truth's figures."""
    from levels.products import read_product

    attrs = read_product(m.path, images=False).attrs
    return {
        "level": m.kind,
        "file": m.path.name,
        "n_rows": int(attrs["n_rows"]),
        "n_cols": int(attrs["n_cols"]),
        "pixel_size_m": float(attrs["pixel_size_m"]),
        "valid_fraction": round(float(m.quality["valid_fraction"]), 6),
        "size_mb": round(m.path.stat().st_size / 1e6, 3),
        "anchor_error_px": m.quality["anchor_error_px"],
        "quality": {k: v for k, v in m.quality.items() if k in _TRUTH_KEYS},
    }


def sar_summary(report: dict[str, Any], out: Path) -> str:
    """The run's table: each product, its checkpoints and masks against the truth
    (:func:`station.tables.product_table`: the figures their kinds declare)."""
    from station.tables import product_table

    f = report["frame"]
    rows = [{**p, "valid": p.get("valid_fraction")} for p in report["products"]]
    lines = [f"SAR frame {f['lines']} × {f['samples']} ({f['instrument']}) → {out}/"]
    return "\n".join(lines + product_table(rows, []))
