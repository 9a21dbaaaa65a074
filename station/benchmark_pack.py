"""The open SPOT 1–4 benchmark: an emulated level-1A scene as a real SPOT DIMAP v1 scene,
with the truth a user scores their own processing against.

No public SPOT 1–4 scene comes with its true DEM, attitude and ephemeris; an emulated one
does. ``station export P_1A.h5 --dimap DIR`` writes::

    DIR/METADATA.DIM, IMAGERY.TIF   the scene, as SPOT 1–4 deliver it (levels.writers.dimap)
    DIR/control_points.csv          control points as a user gets them (map and measurement
                                    errors of the scenario's [gcps]), scene rows and columns
    DIR/truth/dem.tif               the world's terrain under the strip (GeoTIFF, WGS84,
                                    ellipsoidal heights, 1", no error)
    DIR/truth/checkpoints.csv       a lattice of pixels and the ground each truly sees
    DIR/truth/control_points.csv    the control points' true positions, blunders marked
    DIR/truth/ephemeris.csv         the true orbit every second (ECEF, the file's velocity)
    DIR/truth/attitude.csv          the true absolute attitude every 2 ms (the file's frame)
    DIR/truth/look_angles.csv       each detector's true look angles (mirror included)
    DIR/truth/scenario.toml         the scenario that made it (seed included)
    DIR/README.md, DIR/pack.json    what is where, its conventions, and this station's scores

Rows and columns everywhere are the DIMAP's: 1-based, pixel centres (row 1 is the image's
first line). The truth is the emulator's: the same scenario and seed give the same scene.
"""

from __future__ import annotations

import csv
import json
import shutil
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from levels.choices import Level
from levels.geometry.ellipsoid import WGS84
from levels.products import Product, read_product
from levels.readers.dimap import AttitudeChoice
from station.errors import StationError

if TYPE_CHECKING:
    from station.scenario import Scenario
    from station.spacecraft.emulator import Acquisition

__all__ = ["PACK_FILE", "SCENE_FOLDER", "PackResult", "write_pack", "zip_pack"]

PACK_FILE = "pack.json"
#: The scene's folder in a zipped pack, as SPOT's DIMAP deliveries name it.
SCENE_FOLDER = "SCENE01"
_SCENE_FILES = ("METADATA.DIM", "IMAGERY.TIF")
#: Checkpoints per side of the truth lattice (21 × 21 = 441 points).
CHECKPOINTS_PER_SIDE = 21
#: The truth DEM's spacing and margin around the strip.
DEM_SPACING_ARCSEC = 1.0
DEM_MARGIN_KM = 2.0
#: Spacing of the true ephemeris and attitude tables, and their margin beyond the scene.
EPHEMERIS_STEP_S = 1.0
ATTITUDE_STEP_S = 0.002
TRUTH_MARGIN_S = 2.0


@dataclass(frozen=True)
class PackResult:
    """What was written: the directory, whether the truth is in it, and the scores of this
    station's own system model at the checkpoints (metres; empty without the truth)."""

    directory: Path
    truth: bool
    scores: dict[str, Any]

    def text(self) -> str:
        where = f"{self.directory}" if self.directory.suffix == ".zip" else f"{self.directory}/"
        lines = [f"wrote {where} (METADATA.DIM + IMAGERY.TIF)"]
        if not self.truth:
            lines.append("  no truth written: give --scenario (the scenario that made the run)")
        for name, s in self.scores.items():
            lines.append(
                f"  checkpoints, {name}: RMS {s['rms_m']:.2f} m, max {s['max_m']:.2f} m "
                f"({s['n']} points)"
            )
        return "\n".join(lines)


def _find_scenario(product_path: Path, product: Product) -> Path | None:
    """The run's scenario, when the run's report names one that is still where it was."""
    report = product_path.parent / "report.json"
    try:
        name = json.loads(report.read_text(encoding="utf-8"))["scenario"]["file"]
    except (OSError, ValueError, KeyError, TypeError):
        return None
    for base in (Path.cwd(), product_path.parent, Path.cwd() / "scenarios"):
        if (base / name).is_file():
            return base / name
    return None


def _calibration(product_path: Path, product: Product) -> dict[str, tuple[NDArray, NDArray]]:
    """Each band's detector gains and dark offsets from the L0 archive the product was made
    from, when it lies beside the product; empty otherwise."""
    from levels.errors import ProductError
    from levels.readers.l0 import read_l0

    l0 = product_path.parent / str(product.provenance.get("inputs", ""))
    if not product.provenance.get("inputs") or not l0.is_file():
        return {}
    try:
        archive = read_l0(l0, lazy=True)
    except (OSError, ProductError, ValueError):
        return {}
    return {
        name: (np.asarray(b.gain), np.asarray(b.offset_counts))
        for name, b in archive.bands.items()
        if name in product.bands
    }


def write_pack(
    product_path: str | Path,
    out: str | Path,
    *,
    scenario: str | Path | None = None,
    mission_index: int = 2,
) -> PackResult:
    """Write the benchmark pack of a level-1A product into ``out`` (replaced whole, as
    ``station run`` replaces its output; module docstring). The truth needs the scenario
    that made the product: ``scenario``, or the one the run's ``report.json`` names when it
    is found; its SHA-256 must be the product's.

    ``out`` ending in ``.zip``: the pack as one zip, as SPOT World Heritage delivers a
    scene (:func:`zip_pack`), which ``station process`` reads in place."""
    if Path(out).suffix.lower() == ".zip":
        return zip_pack(product_path, out, scenario=scenario, mission_index=mission_index)
    from levels.files import staged_dir
    from levels.writers.dimap import band_descriptions, dimap_scene_of, write_dimap
    from station.loader import load_scenario
    from station.outdir import replaceable_dir
    from station.spacecraft.instrument import COUNTS_PER_RADIANCE

    src = Path(product_path)
    product = read_product(src)
    if product.level != Level.L1A:
        raise StationError(
            f"{src}: a level {product.level} product; the DIMAP v1 scene is made from a 1A"
        )
    name = f"{product.attrs.get('name', '')} scene {product.attrs.get('scene_index', '')} HRV" + (
        f"{product.attrs.get('hrv', '')}"
    )
    target = replaceable_dir(
        out,
        PACK_FILE,
        lambda d: d["product"],
        name,
        lambda p: f"the DIMAP pack of {p}",
        inputs=[src],
    )
    scn_path = Path(scenario) if scenario is not None else _find_scenario(src, product)
    scn = None
    if scn_path is not None:
        scn = load_scenario(scn_path)
        want = product.provenance.get("scenario_sha256")
        if want and scn.source_sha256 != want:
            raise StationError(
                f"{scn_path} is not the scenario that made {src} (SHA-256 "
                f"{scn.source_sha256[:12]}…, the product's {str(want)[:12]}…)"
            )
    scene = dimap_scene_of(
        product,
        mission_index=mission_index,
        calibration=_calibration(src, product),
        counts_per_radiance=COUNTS_PER_RADIANCE,
    )
    image = np.stack([b.image for b in product.bands.values()])
    production = {
        "DATASET_PRODUCER_NAME": "spot-station (emulated)",
        "SOFTWARE_NAME": str(product.provenance.get("software", "spot-station")),
        "PROCESSING_CENTER": "emulated",
    }
    scores: dict[str, object] = {}
    with staged_dir(target) as stage:
        write_dimap(
            scene, stage, image, band_names=band_descriptions(product), production=production
        )
        if scn is not None and scn_path is not None:
            scores = _truth(stage, scn, scn_path, product, scene)
        manifest = {
            "format": "spot-station DIMAP pack",
            "product": name,
            "from": str(src),
            "scenario": None if scn is None else scn.name,
            "seed": None if scn is None else scn.seed,
            "truth": scn is not None,
            "scores_m": scores,
        }
        (stage / PACK_FILE).write_text(json.dumps(manifest, indent=2) + "\n", encoding="utf-8")
        (stage / "README.md").write_text(_readme(manifest, scene), encoding="utf-8")
    return PackResult(Path(target), scn is not None, scores)


def _truth(stage: Path, scn: Scenario, scn_path: Path, product: Product, scene: Any) -> dict:
    """Write the truth files and return the scores of this station's model at the
    checkpoints (the DIMAP scene read back, INPE's attitude and the null one)."""
    from levels.readers.dimap import read_dimap
    from station.scenario import DemConfig
    from station.spacecraft.dem import export_dem
    from station.spacecraft.emulator import emulate_pass
    from station.spacecraft.imaging import trace_pixels

    hrv = int(product.attrs.get("hrv", 1))
    acqs = emulate_pass(scn, render=False)
    acq = next((a for a in acqs if a.hrv.number == hrv), None)
    if acq is None:
        raise StationError(f"scenario {scn.name} has no HRV{hrv}: not the one that made this")
    period = acq.hrv.line_period_s
    # the acquisition line of the scene's row 1, from the scene's own dating
    t_row1 = float(acq.epoch.seconds(scene.epoch.t0_utc)) - (scene.scene_center_line - 1) * period
    first = int(np.rint((t_row1 - acq.line_times_s[0]) / period))
    truth_dir = stage / "truth"
    truth_dir.mkdir()
    shutil.copyfile(scn_path, truth_dir / "scenario.toml")
    export_dem(
        [acq],
        DemConfig(spacing_arcsec=DEM_SPACING_ARCSEC, margin_km=DEM_MARGIN_KM),
        scn.seed,
        truth_dir / "dem.tif",
    )

    # checkpoints: whole pixels of a lattice, the ground each truly sees
    n = CHECKPOINTS_PER_SIDE
    grid_rows, grid_cols = np.meshgrid(
        np.rint(np.linspace(1, scene.n_rows, n)), np.rint(np.linspace(1, scene.n_cols, n))
    )
    rows, cols = grid_rows.ravel(), grid_cols.ravel()
    t = acq.line_times_s[0] + (first + rows - 1) * period
    pts, ok = trace_pixels(acq.orbit, acq.attitude, acq.hrv.bands[0], acq.world, t, cols - 1)
    lat, lon, h = np.degrees(pts[:, 0]), np.degrees(pts[:, 1]), pts[:, 2]
    k = np.flatnonzero(ok)
    _csv(
        truth_dir / "checkpoints.csv",
        {
            "id": [f"c{i:04d}" for i in k],
            "time_utc": _utc(acq.epoch, t[k]),
            "row": _f(rows[k], ".0f"),
            "col": _f(cols[k], ".0f"),
            "lon_deg": _f(lon[k], ".9f"),
            "lat_deg": _f(lat[k], ".9f"),
            "h_m": _f(h[k], ".3f"),
        },
    )
    _control_points(stage, truth_dir, acq, first, scene, scn)
    _truth_tables(truth_dir, acq, first, scene)
    return _scores(read_dimap(stage / "METADATA.DIM"), pts, ok, rows, cols)


def _utc(epoch: Any, t: NDArray) -> list[str]:
    """Product seconds as UTC strings to the nanosecond."""
    return [str(u) for u in np.datetime_as_string(epoch.utc(t), unit="ns")]


def _truth_tables(truth_dir: Path, acq: Acquisition, first: int, scene: Any) -> None:
    """The true ephemeris, attitude and look angles over the scene (and
    :data:`TRUTH_MARGIN_S` about it) as CSV files in ``truth_dir``."""
    period = acq.hrv.line_period_s

    t_first = acq.line_times_s[0] + first * period
    t_last = t_first + (scene.n_rows - 1) * period
    te = np.arange(t_first - TRUTH_MARGIN_S, t_last + TRUTH_MARGIN_S, EPHEMERIS_STEP_S)
    r, v = acq.orbit.frame_state_ecef(te)
    _csv(
        truth_dir / "ephemeris.csv",
        {"time_utc": _utc(acq.epoch, te)}
        | {f"{x}_m": _f(r[:, i], ".4f") for i, x in enumerate("xyz")}
        | {f"v{x}_m_per_s": _f(v[:, i], ".6f") for i, x in enumerate("xyz")},
    )
    ta = np.arange(t_first - TRUTH_MARGIN_S, t_last + TRUTH_MARGIN_S, ATTITUDE_STEP_S)
    angles = acq.attitude.angles_rad(ta)
    _csv(
        truth_dir / "attitude.csv",
        {"time_utc": _utc(acq.epoch, ta)}
        | {f"{x}_rad": _f(angles[:, i], "+.10e") for i, x in enumerate(("roll", "pitch", "yaw"))},
    )
    det = np.arange(acq.hrv.n_columns, dtype=np.float64)
    looks: dict[str, list[str]] = {n: [] for n in ("band", "detector_id", "psi_x_rad", "psi_y_rad")}
    for band in acq.hrv.bands:
        px, py = band.look_true.angles_rad(det)
        looks["band"] += [band.name] * det.size
        looks["detector_id"] += _f(det + 1, ".0f")
        looks["psi_x_rad"] += _f(px, "+.10e")
        looks["psi_y_rad"] += _f(py, "+.10e")
    _csv(truth_dir / "look_angles.csv", looks)


def _scores(
    back: Any, pts: NDArray, ok: NDArray, rows: NDArray, cols: NDArray
) -> dict[str, dict[str, Any]]:
    """This station's scores at the checkpoints (``pts``: their true latitude, longitude
    and height; ``ok`` those seen): the model of the DIMAP scene read back (``back``),
    with INPE's attitude and with the null one, at the true heights."""
    from levels.geometry.frames import apply, enu_from_ecef

    h = pts[:, 2]
    truth_ecef = WGS84.to_ecef(pts[ok, 0], pts[ok, 1], pts[ok, 2])
    scores = {}
    choices: tuple[tuple[AttitudeChoice, str], ...] = (
        ("integrated_zeroed", "station model (INPE attitude)"),
        ("none", "null attitude (SPOT 1–4 producer)"),
    )
    for choice, label in choices:
        g = back.model(attitude=choice).image_to_ground(rows[ok] - 1, cols[ok] - 1, h[ok])
        d = WGS84.to_ecef(g.lat_rad, g.lon_rad, g.h_m) - truth_ecef
        e = apply(enu_from_ecef(pts[ok, 0], pts[ok, 1]), d)
        dist = np.hypot(e[:, 0], e[:, 1])
        scores[label] = {
            "attitude": choice,
            "rms_m": float(np.sqrt(np.mean(dist**2))),
            "max_m": float(dist.max()),
            "mean_east_m": float(e[:, 0].mean()),
            "mean_north_m": float(e[:, 1].mean()),
            "n": int(dist.size),
        }
    return scores


def _control_points(
    stage: Path, truth_dir: Path, acq: Acquisition, first: int, scene: Any, scn: Scenario
) -> None:
    """The scenario's control points inside the scene: as measured (with the scenario's
    errors, what a user is handed) and their truth."""
    g = acq.gcps
    line, true_line = g.line - first, g.true_line - first
    inside = (line >= -0.5) & (line <= scene.n_rows - 0.5)
    cfg, hrv = scn.gcps, acq.hrv.number
    k = np.flatnonzero(inside)
    # docs/gcp.md's columns first (line, column 0-based: station locate --gcps reads it),
    # then DIMAP's 1-based row and col
    ids = [f"g{i:04d}" for i in k]

    def where(
        lon: NDArray, lat: NDArray, h: NDArray, ln: NDArray, col: NDArray
    ) -> tuple[dict[str, list[str]], dict[str, list[str]]]:
        """A point's ground and image columns: docs/gcp.md's, then DIMAP's row and col."""
        return {
            "lon_deg": _f(np.degrees(lon[k]), ".9f"),
            "lat_deg": _f(np.degrees(lat[k]), ".9f"),
            "h_m": _f(h[k], ".3f"),
            "line": _f(ln[k], ".3f"),
            "column": _f(col[k], ".3f"),
        }, {"row": _f(ln[k] + 1, ".3f"), "col": _f(col[k] + 1, ".3f")}

    ground, dimap = where(g.lon_rad, g.lat_rad, g.h_m, line, g.column)
    sigmas = {
        "sigma_ground_m": [f"{cfg.horizontal_error_m:g}"] * k.size,
        "sigma_h_m": [f"{cfg.vertical_error_m:g}"] * k.size,
        "sigma_px": [f"{cfg.pointing_error_px:g}"] * k.size,
        "hrv": [str(hrv)] * k.size,
    }
    _csv(stage / "control_points.csv", {"id": ids, **ground, **sigmas, **dimap})
    ground, dimap = where(g.true_lon_rad, g.true_lat_rad, g.true_h_m, true_line, g.true_column)
    blunder = {"blunder": ["true" if x else "false" for x in g.blunder[k]]}
    _csv(truth_dir / "control_points.csv", {"id": ids, **ground, **dimap, **blunder})


def _f(values: NDArray, spec: str) -> list[str]:
    return [format(float(x), spec) for x in values]


def _csv(path: Path, columns: dict[str, list[str]]) -> None:
    """A CSV of equal-length columns, header first."""
    with path.open("w", newline="", encoding="utf-8") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(columns)
        w.writerows(zip(*columns.values(), strict=True))


def _readme(manifest: dict[str, Any], scene: Any) -> str:
    scores = "\n".join(
        f"| {k} | {s['rms_m']:.2f} | {s['max_m']:.2f} | {s['mean_east_m']:+.2f} | "
        f"{s['mean_north_m']:+.2f} |"
        for k, s in manifest["scores_m"].items()
    )
    table = (
        "| model | RMS m | max m | mean east m | mean north m |\n|---|---|---|---|---|\n" + scores
        if scores
        else "(no truth in this pack: it was exported without its scenario)"
    )
    return f"""# {manifest["product"]}: an emulated SPOT level-1A scene and its truth

Made by spot-station from scenario `{manifest["scenario"]}` (seed {manifest["seed"]}); every
number here comes from an emulator, whose truth is written beside the scene.

- `METADATA.DIM` + `IMAGERY.TIF`: the scene as SPOT 1–4 deliver a level 1A (DIMAP v1, profile
  SPOTSCENE_1A): {scene.n_rows} rows × {scene.n_cols} columns, mirror step {scene.mirror_step},
  line period {scene.line_period_s * 1e3:.4f} ms, ephemeris points with velocities, AOCS angles
  and angular speeds, look angles per detector, detector gains and dark currents.
- `control_points.csv`: control points as a user is handed them (map and pointing errors of
  the given 1σ), to adjust a model on: `row`, `col` in DIMAP's convention, and `line`,
  `column` 0-based as spot-station's control-point files (`station locate METADATA.DIM
  --gcps control_points.csv` reads it).
- `truth/`: the terrain (`dem.tif`: WGS84 geographic, ellipsoidal heights, no error), the
  checkpoints (`checkpoints.csv`: the ground each pixel truly sees, and when it was truly
  imaged: the DIMAP's dating is the station's, off by its line clock's error), the control points'
  truth (blunders marked), the true orbit (`ephemeris.csv`), absolute attitude
  (`attitude.csv`) and look angles (`look_angles.csv`), and the scenario.

Conventions: rows and columns are DIMAP's, 1-based at pixel centres, row 1 the first line;
heights above the WGS84 ellipsoid; a row's time is `SCENE_CENTER_TIME + (row −
SCENE_CENTER_LINE) · LINE_PERIOD`; velocities are {
        "inertial, in ECEF axes (SPOT 1–4)"
        if (scene.ephemeris and scene.ephemeris.reference_velocity != "earth_fixed")
        else "Earth-fixed"
    };
attitude angles in the DIMAP's frame (roll and pitch with the files' signs). The AOCS angles
and angular speeds are the station's: integrated gyro rates zeroed at the scene centre
(INPE), relative — the absolute attitude is in `truth/attitude.csv` only.

## How to score a model

Locate each checkpoint's (row, col) at its true height `h_m` and compare with its
`lon_deg, lat_deg`; or project the truth into the image and compare rows and columns.
This station's own models, read back from `METADATA.DIM` and scored that way:

{table}
"""


def zip_pack(
    product_path: str | Path,
    out: str | Path,
    *,
    scenario: str | Path | None = None,
    mission_index: int = 2,
) -> PackResult:
    """The pack of :func:`write_pack` as one zip at ``out``: the scene in
    ``SCENE01/`` (``METADATA.DIM``, ``IMAGERY.TIF``), as SPOT's DIMAP deliveries and SPOT
    World Heritage's zips hold it, the rest of the pack (truth, control points, README)
    at the top. A zip that is not a pack is not replaced (it is named); a pack's is,
    atomically."""
    import tempfile
    import zipfile

    from levels.files import atomic_path

    target = Path(out)
    if target.exists():
        is_pack = zipfile.is_zipfile(target) and PACK_FILE in zipfile.ZipFile(target).namelist()
        if not is_pack:
            raise StationError(
                f"{target} exists and is not a DIMAP pack's zip: not replaced (remove it, "
                "or give another name)"
            )
    target.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=target.parent, prefix=f".{target.name}.") as tmp:
        built = write_pack(product_path, Path(tmp) / "pack", scenario=scenario,
                           mission_index=mission_index)  # fmt: skip
        files = sorted(f for f in built.directory.rglob("*") if f.is_file())
        with atomic_path(target) as part, zipfile.ZipFile(part, "w", zipfile.ZIP_DEFLATED) as z:
            for f in files:
                rel = f.relative_to(built.directory).as_posix()
                z.write(f, f"{SCENE_FOLDER}/{rel}" if rel in _SCENE_FILES else rel)
    return PackResult(target, built.truth, built.scores)
