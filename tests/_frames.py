"""Control-point files made of a real scene's producer frame corners, for the tests."""

from __future__ import annotations

from pathlib import Path

from levels.readers.dimap import DimapScene

#: The ENVISAT products a frame is written as in the tests: ``SAR_IMP_1P`` on slant and on
#: ground range, and ``SAR_IMS_1P`` (``levels.writers.envisat.write_envisat``'s options).
ENVISAT_VARIANTS: dict[str, dict[str, object]] = {
    "imp": {},
    "ims": {"product": "SAR_IMS_1P"},
    "imp_ground": {"ground_range": True},
}

HEADER = "id,lon_deg,lat_deg,h_m,line,column,sigma_ground_m,sigma_h_m,sigma_px,hrv"


def frame_gcps(scene: DimapScene, path: Path, height_step_m: float = 0.0) -> Path:
    """The four ``Dataset_Frame`` corners as control points (``docs/gcp.md``; 0-based
    lines and columns), the k-th at height ``k · height_step_m``; returns ``path``."""
    rows = [HEADER]
    for k, (r, c, la, lo) in enumerate(
        zip(scene.frame_row, scene.frame_col, scene.frame_lat_deg, scene.frame_lon_deg, strict=True)
    ):
        h = k * height_step_m
        rows.append(f"c{k},{float(lo)!r},{float(la)!r},{h!r},{r - 1.0},{c - 1.0},5,5,0.5,1")
    path.write_text("\n".join(rows) + "\n")
    return path
