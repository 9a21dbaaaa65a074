"""Locate the frame of a real SPOT scene from its DIMAP metadata and compare with the producer.

This is the check a photogrammetrist runs before trusting the model: the four
``Dataset_Frame`` corners and the scene centre, predicted on the ellipsoid (height 0) by the
rigorous model of ``levels.geometry``, against the producer's own coordinates. A SPOT 6/7
(or Pléiades) DIMAP v2 ``DIM_*.XML`` has no model to rebuild: its producer's RPC is the
model (:mod:`levels.readers.dimap2`), its ``Dataset_Extent`` the frame, at the heights the
file gives.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from pyproj import Geod

from levels.errors import OptionsError
from levels.readers.dimap import AttitudeChoice, read_dimap
from levels.readers.dimap2 import Dimap2Scene, is_dimap2, read_dimap2
from levels.readers.envisat import is_envisat

__all__ = [
    "FrameCheck",
    "GcpCheck",
    "check_frame",
    "check_gcps",
    "write_rpc",
]

_GEOD = Geod(ellps="WGS84")


@dataclass(frozen=True)
class FrameCheck:
    """Producer's and predicted frame points (4 corners then the centre), and their distance."""

    scene: str
    attitude: str
    row: np.ndarray
    col: np.ndarray
    lat_deg: np.ndarray
    lon_deg: np.ndarray
    predicted_lat_deg: np.ndarray
    predicted_lon_deg: np.ndarray
    error_m: np.ndarray
    roundtrip_px: np.ndarray

    def as_dict(self) -> dict:
        return {
            "scene": self.scene,
            "attitude": self.attitude,
            "points": [
                {
                    "row": int(r),
                    "col": int(c),
                    "lat_deg": float(la),
                    "lon_deg": float(lo),
                    "predicted_lat_deg": float(pla),
                    "predicted_lon_deg": float(plo),
                    "error_m": float(e),
                    "roundtrip_px": float(rt),
                }
                for r, c, la, lo, pla, plo, e, rt in zip(
                    self.row,
                    self.col,
                    self.lat_deg,
                    self.lon_deg,
                    self.predicted_lat_deg,
                    self.predicted_lon_deg,
                    self.error_m,
                    self.roundtrip_px,
                    strict=True,
                )
            ],
            "max_error_m": float(np.nanmax(self.error_m))
            if np.isfinite(self.error_m).any()
            else None,
            "points_not_located": int(np.sum(~np.isfinite(self.error_m))),
        }


def check_frame(path: str | Path, attitude: AttitudeChoice = "auto") -> FrameCheck:
    """Predict the Dataset_Frame corners and centre of a DIMAP scene and measure the misses.

    ``roundtrip_px`` is the image → ground → image closure at each point (pixels).
    """
    if is_envisat(path):
        return check_sar_grid(path)
    if is_dimap2(path):
        v2 = read_dimap2(path)
        model: Any = v2.model()
        name, used = v2.name, _PRODUCER_RPC
        row, col, h = v2.frame_row, v2.frame_col, v2.frame_h_m
        lat, lon = v2.frame_lat_deg, v2.frame_lon_deg
    else:
        scene = read_dimap(path)
        model, name, used = scene.model(attitude=attitude), scene.name, _said(scene, attitude)
        row = np.append(scene.frame_row, scene.center_row)
        col = np.append(scene.frame_col, scene.center_col)
        lat = np.append(scene.frame_lat_deg, scene.center_lat_deg)
        lon = np.append(scene.frame_lon_deg, scene.center_lon_deg)
        h = np.zeros(row.shape)  # SPOT 1–5 frames lie on the ellipsoid
    ground = model.image_to_ground(row - 1.0, col - 1.0, h)  # DIMAP is 1-based
    plat, plon = np.degrees(ground.lat_rad), np.degrees(ground.lon_rad)
    _, _, dist = _GEOD.inv(lon, lat, plon, plat)
    back = model.ground_to_image(ground.lat_rad, ground.lon_rad, h)
    roundtrip = np.hypot(back.line - (row - 1.0), back.column - (col - 1.0))
    return FrameCheck(name, used, row, col, lat, lon, plat, plon, dist, roundtrip)


#: What ``attitude`` says for a SAR frame: its model is the range–Doppler equations.
_RANGE_DOPPLER = "range–Doppler on the state vectors"


def check_sar_grid(path: str | Path) -> FrameCheck:
    """An ERS (ASAR) frame of ESA's format (:mod:`levels.readers.envisat`): each tie point
    of its geolocation grid predicted on the ellipsoid from the frame's state vectors,
    timing and range by the range–Doppler equations (:mod:`levels.sar`), against ESA's
    latitude and longitude; rows and columns 1-based, as the file numbers them."""
    from levels.readers.envisat import read_envisat

    frame = read_envisat(path)
    grid, ann = frame.grid, frame.sar.annotation
    plat, plon = ann.ground_of_image(grid.line, grid.slant_column, 0.0)
    line, col = ann.image_of(plat, plon, np.zeros_like(plat))
    plat_deg, plon_deg = np.degrees(plat), np.degrees(plon)
    _, _, dist = _GEOD.inv(grid.lon_deg, grid.lat_deg, plon_deg, plat_deg)
    return FrameCheck(
        f"{frame.instrument} {frame.product_type} {frame.name}",
        _RANGE_DOPPLER,
        (grid.line + 1).astype(int),
        (grid.column + 1).astype(int),
        grid.lat_deg,
        grid.lon_deg,
        plat_deg,
        plon_deg,
        np.asarray(dist),
        np.hypot(line - grid.line, col - grid.slant_column),
    )


#: What ``attitude`` says for a DIMAP v2 scene, whose model is its producer's RPC.
_PRODUCER_RPC = "the producer's RPC"


def _scene_model(path: str | Path, attitude: AttitudeChoice) -> tuple[str, Any, str]:
    """A scene's name, model and the attitude it was built with: DIMAP v1's rigorous
    model, or DIMAP v2's RPC."""
    if is_dimap2(path):
        v2: Dimap2Scene = read_dimap2(path)
        return v2.name, v2.model(), _PRODUCER_RPC
    scene = read_dimap(path)
    return scene.name, scene.model(attitude=attitude), _said(scene, attitude)


def _said(scene: Any, attitude: AttitudeChoice) -> str:
    """The attitude as a report says it: ``auto`` with what it chose for this file."""
    return f"auto: {scene.auto_attitude}" if attitude == "auto" else str(attitude)


@dataclass(frozen=True)
class GcpCheck:
    """Control points of a real scene against its DIMAP model (before any refinement):
    where the model puts each point in the image, and on the ground at the point's height."""

    scene: str
    attitude: str
    id: tuple[str, ...]
    line: np.ndarray  # measured, 0-based
    column: np.ndarray
    predicted_line: np.ndarray  # the model's ground → image of the point
    predicted_column: np.ndarray
    ground_miss_m: np.ndarray  # the model's image → ground of the measurement vs the point
    model: str = "rigorous"  # which model made the predictions: "rigorous" or "rpc"
    #: with ``model="rpc"``: the RPC's fit error, and its predictions against the rigorous
    #: model's at these very points (pixels)
    rpc_fit_error_px: dict | None = None
    rpc_vs_rigorous_px: float | None = None

    @property
    def image_miss_px(self) -> np.ndarray:
        return np.hypot(self.line - self.predicted_line, self.column - self.predicted_column)

    @property
    def within_reach(self) -> np.ndarray:
        """Points the model could miss by what it missed them (finite, within
        ``REACH_SIGMAS`` of ``DIMAP_MODEL_SIGMA_M``): the others are not of this scene."""
        return (
            np.isfinite(self.ground_miss_m)
            & (self.ground_miss_m <= REACH_SIGMAS * DIMAP_MODEL_SIGMA_M)
            & np.isfinite(self.image_miss_px)
        )

    def as_dict(self) -> dict:
        d_px = self.image_miss_px
        ok = self.within_reach
        return {
            "scene": self.scene,
            "attitude": self.attitude,
            "points": [
                {
                    "id": i,
                    "line": float(a),
                    "column": float(b),
                    "predicted_line": float(c),
                    "predicted_column": float(d),
                    "miss_px": float(e),
                    "ground_miss_m": float(f),
                    "within_reach": bool(g),
                }
                for i, a, b, c, d, e, f, g in zip(
                    self.id,
                    self.line,
                    self.column,
                    self.predicted_line,
                    self.predicted_column,
                    d_px,
                    self.ground_miss_m,
                    ok,
                    strict=True,
                )
            ],
            "points_within_reach": int(ok.sum()),
            "rms_px": float(np.sqrt(np.mean(d_px[ok] ** 2))),
            "rms_ground_m": float(np.sqrt(np.mean(self.ground_miss_m[ok] ** 2))),
            "max_ground_m": float(np.max(self.ground_miss_m[ok])),
            "model": self.model,
            "rpc_fit_error_px": self.rpc_fit_error_px,
            "rpc_vs_rigorous_px": self.rpc_vs_rigorous_px,
        }


#: A priori 1σ of a SPOT 1–5 level-1A DIMAP model's location, per axis (m): SPOT 1–4
#: systems were specified to 350 m rms, SPOT 5 to 50 m; the larger holds for every
#: generation this reads.
DIMAP_MODEL_SIGMA_M = 350.0
#: Misses beyond this many a priori σ are out of the model's reach (``levels.adjust``).
REACH_SIGMAS = 10.0
#: Confidence of the χ² test of the misses against their a priori σ.
GCP_TEST_CONFIDENCE = 0.999

#: Height margin of the RPCs fitted for ``check_gcps(..., model="rpc")`` beyond the
#: control points' own heights (m).
GCP_RPC_MARGIN_M = 500.0


def check_gcps(
    path: str | Path,
    gcp_path: str | Path,
    attitude: AttitudeChoice = "auto",
    model: str = "rigorous",
) -> GcpCheck:
    """How far a real scene's DIMAP model misses the user's control points
    (``docs/gcp.md``; lines and columns 0-based in the scene's raw image): the residuals a
    refinement (level 2) starts from.

    ``model="rpc"`` makes the ground → image step through RPCs fitted to the rigorous
    model over the points' heights ± ``GCP_RPC_MARGIN_M`` (PHOTOMOD's comparison of the
    physical and the algebraic model, paper ``003_…``), and says how far they land from
    the rigorous model's predictions."""
    from levels.geo.rpc import rpc_of_model
    from levels.readers.gcp import read_gcps

    if model not in ("rigorous", "rpc"):
        raise OptionsError(f"model {model!r}: expected 'rigorous' or 'rpc'")
    if is_envisat(path):
        return _sar_gcps(path, gcp_path)
    name, rigorous, used = _scene_model(path, attitude)
    g = read_gcps(gcp_path, rigorous.n_lines, rigorous.n_columns)
    back = rigorous.ground_to_image(g.lat_rad, g.lon_rad, g.h_m, first_line=g.line)
    line, column = back.line, back.column
    extra: dict = {}
    if model == "rpc" and used != _PRODUCER_RPC:  # a DIMAP v2 model is an RPC already
        heights = (float(g.h_m.min()) - GCP_RPC_MARGIN_M, float(g.h_m.max()) + GCP_RPC_MARGIN_M)
        rpc = rpc_of_model(rigorous, heights)
        line, column = rpc.image_of(np.degrees(g.lat_rad), np.degrees(g.lon_rad), g.h_m)
        extra = {
            "rpc_fit_error_px": rpc.fit_error_px,
            "rpc_vs_rigorous_px": float(np.max(np.hypot(line - back.line, column - back.column))),
        }
    ground = rigorous.image_to_ground(g.line, g.column, g.h_m)
    plat, plon = np.degrees(ground.lat_rad), np.degrees(ground.lon_rad)
    _, _, dist = _GEOD.inv(np.degrees(g.lon_rad), np.degrees(g.lat_rad), plon, plat)
    check = GcpCheck(
        name, used, g.id, g.line, g.column, line, column, np.asarray(dist), model, **extra
    )
    _judge(check, g.sigma_ground_m)
    return check


def _sar_gcps(path: str | Path, gcp_path: str | Path) -> GcpCheck:
    """:func:`check_gcps` of a SAR frame of ESA's format: each point located in the image
    by the range–Doppler equations at its height, and its measured pixel on the ground at
    that height."""
    from levels.readers.envisat import read_envisat
    from levels.readers.gcp import read_gcps

    frame = read_envisat(path)
    ann = frame.sar.annotation
    g = read_gcps(gcp_path, *ann.shape)
    line, column = ann.image_of(g.lat_rad, g.lon_rad, g.h_m)
    plat, plon = ann.ground_of_image(g.line, g.column, g.h_m)
    _, _, dist = _GEOD.inv(
        np.degrees(g.lon_rad), np.degrees(g.lat_rad), np.degrees(plon), np.degrees(plat)
    )
    name = f"{frame.instrument} {frame.product_type} {frame.name}"
    check = GcpCheck(name, _RANGE_DOPPLER, g.id, g.line, g.column, line, column, np.asarray(dist))
    _judge(check, g.sigma_ground_m)
    return check


def _judge(check: GcpCheck, sigma_ground_m: np.ndarray) -> None:
    """:class:`GcpError` when no point is within the model's reach (another scene's
    points), or when the misses fail the χ² test against their a priori σ: per axis the
    model's and the point's, ``Σ miss² / σ² > χ²_2n(GCP_TEST_CONFIDENCE)``."""
    from scipy.stats import chi2

    from levels.errors import GcpError

    ok = check.within_reach
    miss = np.nan_to_num(check.ground_miss_m, nan=np.inf)
    worst = np.argsort(-miss)[:3]
    named = ", ".join(f"{check.id[k]} {miss[k]:.0f} m" for k in worst)
    if not ok.any():
        raise GcpError(
            f"none of the {len(check.id)} control points is within reach of the model of "
            f"{check.scene} ({REACH_SIGMAS:g} × {DIMAP_MODEL_SIGMA_M:g} m): {named}; are they "
            "this scene's points, in its 0-based lines and columns?"
        )
    var = DIMAP_MODEL_SIGMA_M**2 + sigma_ground_m[ok] ** 2
    stat, dof = float(np.sum(miss[ok] ** 2 / var)), 2 * int(ok.sum())
    limit = float(chi2.ppf(GCP_TEST_CONFIDENCE, dof))
    if stat > limit:
        raise GcpError(
            f"the model of {check.scene} misses its control points beyond their a priori σ "
            f"(χ² {stat:.0f} > {limit:.0f}, {GCP_TEST_CONFIDENCE:.1%}, {dof} degrees of "
            f"freedom): worst {named}"
        )


def write_rpc(
    path: str | Path,
    out: str | Path,
    heights_m: tuple[float, float],
    attitude: AttitudeChoice = "auto",
) -> dict:
    """Fit RPCs to a real scene's model (:mod:`levels.geo.rpc`), from its DIMAP or from
    OSSIM's keyword list of it (``.geom``), and write them as the sidecar GDAL reads beside
    an image (``_RPC.TXT``, or ``.RPB`` if ``out`` ends so); returns what was written and
    the fit's error."""
    from levels.files import atomic_path, writable_dir
    from levels.geo.rpc import rpc_of_model

    writable_dir(Path(out).parent)  # before the fit, not after
    if Path(path).suffix.lower() == ".geom":  # OSSIM's keyword list of a SPOT 5 scene
        from levels.readers.ossim import read_ossim_geom

        ossim = read_ossim_geom(path)
        name, model = f"{ossim.sensor} ({Path(path).name})", ossim.model
        used = "ossim"  # the keyword list's own attitude samples
    elif is_dimap2(path):  # its model is an RPC: written as it is
        v2 = read_dimap2(path)
        name, used, rpc = v2.name, _PRODUCER_RPC, v2.rpc
    else:
        scene = read_dimap(path)
        name, model, used = scene.name, scene.model(attitude=attitude), str(attitude)
    if used != _PRODUCER_RPC:
        rpc = rpc_of_model(model, heights_m)
    target = Path(out)
    target.parent.mkdir(parents=True, exist_ok=True)
    text = rpc.rpb() if target.suffix.upper() == ".RPB" else rpc.rpc_txt()
    with atomic_path(target) as tmp:
        Path(tmp).write_text(text)
    return {
        "scene": name,
        "attitude": used,
        "path": str(target),
        "fit_error_px": rpc.fit_error_px,
        "gdal_metadata": rpc.gdal_metadata(),
    }
