"""A plain summary of an emulated acquisition: what an operator checks first."""

from __future__ import annotations

import numpy as np

from levels.geometry.ellipsoid import WGS84
from station.spacecraft.emulator import Acquisition
from station.spacecraft.imaging import trace_pixels

__all__ = ["summarize"]


def _iso(acq: Acquisition, t_s: float) -> str:
    return str(acq.epoch.utc(t_s))[:23]


def summarize(acq: Acquisition) -> dict[str, object]:
    """Orbit, strip, footprint, bands, passes and handovers of an acquisition (JSON-ready;
    angles in degrees, lengths in km or m as named)."""
    hrv = acq.hrv
    n, m = hrv.n_lines, hrv.n_columns
    lines = np.array([0, 0, n - 1, n - 1, (n - 1) / 2])
    cols = np.array([0, m - 1, 0, m - 1, (m - 1) / 2])
    t = acq.line_times_s[0] + lines * hrv.line_period_s
    pts, ok = trace_pixels(acq.orbit, acq.attitude, hrv.bands[0], acq.world, t, cols)
    xyz = WGS84.to_ecef(pts[:, 0], pts[:, 1], pts[:, 2])
    r, _ = acq.orbit.state_ecef([acq.t_centre_s])
    _, _, alt = WGS84.to_geodetic(r)
    return {
        "scenario": acq.scenario.name,
        "strip": {
            "centre_utc": _iso(acq, acq.t_centre_s),
            "first_line_utc": _iso(acq, acq.line_times_s[0]),
            "lines": n,
            "detectors": m,
            "line_period_ms": hrv.line_period_s * 1e3,
            "mode": hrv.mode,
            "hrv": hrv.number,
            "mirror_step": hrv.mirror_step,
            "twin": hrv.twin,
            "satellite_altitude_km": float(alt[0] / 1e3),
        },
        "footprint": {
            "corners_lat_lon_deg": np.round(np.degrees(pts[:4, :2]), 7).tolist(),
            "centre_lat_lon_deg": np.round(np.degrees(pts[4, :2]), 7).tolist(),
            "centre_height_m": round(float(pts[4, 2]), 3),
            "width_first_line_km": float(np.linalg.norm(xyz[1] - xyz[0]) / 1e3),
            "length_first_column_km": float(np.linalg.norm(xyz[2] - xyz[0]) / 1e3),
            "all_located": bool(ok.all()),
        },
        "bands": [
            {
                "name": b.name,
                "mean_counts": float(b.counts.mean()),
                "saturated": int((b.counts == 255).sum()),
                "failed_rays": int(b.failed.sum()),
                "newton_iterations_max": b.newton_max,
            }
            for b in acq.bands
        ],
        "passes": [
            {
                "aos_utc": _iso(acq, p.aos_s),
                "duration_min": round(p.duration_s / 60, 3),
                "max_elevation_deg": round(float(np.degrees(p.max_elevation_rad)), 3),
                "descending": p.descending,
                "daylight": p.daylight,
            }
            for p in acq.passes
        ],
        "handover": {
            "gyro_samples": int(acq.gyros.t_s.size),
            "bulletin_points": int(acq.bulletins.t_s.size),
            "control_points": int(acq.gcps.line.size),
        },
    }
