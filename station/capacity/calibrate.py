"""Service times of this code's own stages, measured on this machine: ``station capacity
calibrate``.

Two reduced passes (P: 1000 detectors × 1000 lines; XS: 500 × 500, the same swath and
physics) go through the downlink, the L0 archive and GEO/COR for levels 1A, 1B and 2A, after
one untimed run that compiles the numba kernels. The figures are scaled to a full SPOT
scene and channel:

- **ingest**: receiving and recording, per second of one HRV channel at 25 Mbit/s: the wall
  time per bit received, times the full rate;
- **GEO**, per scene: the pass's attitude and the scene's grids. Its work is set by the
  grids' nodes, not the pixels: not scaled;
- **COR**, per scene and level, everything from L0 up (1A: radiometry; 1B: 1A,
  deconvolution, 1B resampling; 2A: 1A, deconvolution, 2A resampling), scaled by the
  pixels of a full scene over the reduced one (6000² in P, 3 × 3000² in XS). The quality
  figures against the truth are the emulator's business, not production: left out;
- **archive**, per product: writing it, scaled by pixels likewise;
- **SAR GTC**, per ERS-1 frame: a reduced frame (600 × 600 samples of 5 azimuth and 2
  range looks; on 300 × 300 the fixed costs, the anchors' and the profiles' lattices,
  weigh: 12 s instead of 7) geocoded over a 1" DEM onto 12.5 m pixels with its masks
  (:func:`levels.sar.geocode`), after an untimed one, scaled by the output pixels of a
  full frame (the north-up grid of 12.5 m over its 100 km × 100 km: 9695 × 9825 pixels)
  over the reduced one's.
"""

from __future__ import annotations

import json
import platform
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from levels.files import write_json
from levels.spot import MODES
from station import __version__
from station.capacity.model import LEVELS

__all__ = [
    "FULL_BIT_RATE_BIT_PER_S",
    "SERVICE_TIMES_FORMAT",
    "calibrate",
    "raw_lines_per_2a_row",
    "sar_gtc_s_per_frame",
    "service_times_format",
    "write_service_times",
]

FULL_BIT_RATE_BIT_PER_S = 25e6  # one HRV channel (docs/telemetry.md)
#: The ``format`` of a service-time table (what ``station capacity`` reads).
SERVICE_TIMES_FORMAT = "spot-station-service-times"
_REDUCED = {  # mode: detectors, lines, bit rate (a share of 25 Mbit/s like the detectors)
    "P": (1000, 1000, 4.0),
    "XS": (500, 500, 4.0),
}
_FULL_PIXELS = {m: MODES[m].pixels_per_scene for m in _REDUCED}
#: A full ERS-1 frame's output pixels: the north-up grid of 12.5 m covering its 100 km ×
#: 100 km (benchmarks/bench_sar.py's, at Cuiabá).
_SAR_FULL_PIXELS = 9695 * 9825


#: A scene's timings that are GEO's (levels.makers.steps): its geometry and RPCs.
_GEO_STEPS = (
    "geometry",
    "common_tree",
    "scene_crs",
    "geometry_1b",
    "geometry_2a",
    "rpc_1a",
    "rpc_1b",
)


def _measure(
    mode: str, detectors: int, lines: int, rate_mbps: float, tmp: Path
) -> dict[str, float]:
    from levels.process import ProcessingRequest, process
    from levels.readers.l0 import read_l0
    from station.chain.session import downlink, record
    from station.scenario import scenario_from_dict
    from station.spacecraft.emulator import emulate

    scn = scenario_from_dict(
        {
            "name": f"calibrate_{mode}",
            "seed": 7,
            "instrument": {"mode": mode, "n_detectors": detectors, "n_lines": lines},
            "downlink": {"bit_rate_mbps": rate_mbps, "preamble_s": 0.1, "postamble_s": 0.1},
            "pass": {"ground_pass_days": 0.0},
            "processing": {"scene_lines": lines},
        }
    )
    acq = emulate(scn)
    result = downlink(acq)
    t = time.perf_counter()
    l0 = record(acq, result, tmp / f"{mode}.l0.h5")
    t_record = time.perf_counter() - t
    bits = result.reception.n_bits
    [products] = process(ProcessingRequest.of(read_l0(l0), scn.processing, tmp, mode))
    (scene,) = products.scenes
    c = scene.timings_s
    n_bands = len(acq.bands)
    return {
        "receive_and_record_s": result.timings_s["receive"] + t_record,
        "bits": float(bits),
        # the scene's geometry steps and RPCs are GEO's work
        "geo_s": products.timings_s["geo"] + sum(c[k] for k in _GEO_STEPS if k in c),
        "1A_s": c["calibration"] + c["1A"],
        "1B_s": c["calibration"] + c["deconvolution"] + c["1B"],
        "2A_s": c["calibration"] + c["deconvolution"] + c["2A"],
        "write_s": c["write"],
        "products": float(len(scene.paths)),
        "pixels": float(detectors * lines * n_bands),
    }


def calibrate() -> dict[str, Any]:
    """Measure the stages (module docstring); returns the service-time table."""
    with tempfile.TemporaryDirectory() as tmp:
        _measure("XS", 100, 100, 0.8, Path(tmp))  # compiles the kernels; not timed
        raw = {m: _measure(m, *spec, Path(tmp)) for m, spec in _REDUCED.items()}
    per_bit = np.mean([r["receive_and_record_s"] / r["bits"] for r in raw.values()])
    scale = {m: _FULL_PIXELS[m] / r["pixels"] for m, r in raw.items()}
    return {
        "format": SERVICE_TIMES_FORMAT,
        "format_version": 1,
        "software": f"spot-station {__version__}",
        "machine": f"{platform.node()}: {platform.processor() or platform.machine()}, "
        f"Python {platform.python_version()}",
        "measured_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        "reduced": {
            m: {"detectors": d, "lines": n, "bit_rate_mbps": b} for m, (d, n, b) in _REDUCED.items()
        },
        "raw": raw,
        "ingest_s_per_signal_s": float(per_bit * FULL_BIT_RATE_BIT_PER_S),
        "geo_s_per_scene": {m: r["geo_s"] for m, r in raw.items()},
        "cor_s": {m: {str(lv): r[f"{lv}_s"] * scale[m] for lv in LEVELS} for m, r in raw.items()},
        "archive_s": {
            m: {str(lv): r["write_s"] / r["products"] * scale[m] for lv in LEVELS}
            for m, r in raw.items()
        },
        "raw_lines_per_2a_row": {m: raw_lines_per_2a_row(m) for m in _REDUCED},
        "sar_gtc_s_per_frame": sar_gtc_s_per_frame(),
    }


def sar_gtc_s_per_frame(n: int = 600) -> float:
    """Seconds to geocode one full ERS-1 frame over a DEM (GTC with its masks), from a
    reduced ``n`` × ``n`` frame (module docstring)."""
    from levels.sar import frame_grid
    from levels.sar.geocoding import geocode
    from station.spacecraft.dem import world_dem
    from station.spacecraft.sar import ErsFrame, emulate_frame
    from station.spacecraft.world import World

    world = World(lon0_rad=np.radians(-56.1), base_height_m=200.0, relief_m=250.0, seed=3)
    image, _ = emulate_frame(ErsFrame(n_lines=n, n_samples=n), world, render=False)
    lat0, lon0 = np.radians(-15.6), np.radians(-56.1)
    span = 1e-5 * n + 0.003  # radians: the frame and the relief's displacement
    dem = world_dem(
        world, (lat0 - span, lat0 + span), (lon0 - span, lon0 + span), 1 / 3600, 0.0,
        np.random.default_rng(0),
    )  # fmt: skip
    grid = frame_grid(image.annotation, 12.5, world.base_height_m)
    geocode(image, grid, dem=dem)  # compiles the kernels; not timed
    t = time.perf_counter()
    geocode(image, grid, dem=dem)
    return (time.perf_counter() - t) * _SAR_FULL_PIXELS / (grid.n_rows * grid.n_cols)


def raw_lines_per_2a_row(mode: str) -> float:
    """Raw lines the middle row of a full-size, north-up 2A scene at nadir near Cuiabá
    reads (INPE: 950 in P, 475 in XS): the window COR's resampling must hold. Geometry
    only, from this code's GEO on the emulated SPOT 1–4 (inertial attitude frame)."""
    from levels.geo.level2a import level2a_geometry
    from levels.geo.maps import map_crs
    from station.fixtures import emulated_scene
    from station.scenario import scenario_from_dict
    from station.spacecraft.emulator import emulate

    scn = scenario_from_dict({"instrument": {"mode": mode}, "pass": {"ground_pass_days": 0.0}})
    _pg, scene, res = emulated_scene(emulate(scn, render=False))
    crs = map_crs("utm", scene.centre_lat_rad, scene.centre_lon_rad)
    return round(level2a_geometry(scene, res, crs).raw_line_span()[0], 1)


def service_times_format(path: Path) -> str | None:
    """The ``format`` a JSON file declares (a service-time table's is
    :data:`SERVICE_TIMES_FORMAT`), read from a file of at most 1 MB; None for another."""
    if path.stat().st_size > 2**20:
        return None
    data = json.loads(path.read_text(encoding="utf-8"))
    return str(data["format"]) if isinstance(data, dict) and "format" in data else None


def write_service_times(path: str | Path, table: dict[str, Any]) -> Path:
    """Write a service-time table as JSON (atomically)."""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    return write_json(p, table)
