"""The control points an emulated pass hands its user: what the emulator drew with their
errors (never the truth), written as a user has them (``docs/gcp.md``) and read back
the way the processing centre reads them.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from levels.readers.gcp import ControlPointSet, read_gcps, write_gcps
from levels.readers.l0 import L0Archive
from station.spacecraft.emulator import Acquisition
from station.truth.optical import Truth

__all__ = ["control_points", "measured_control_points"]


def control_points(acq: Acquisition, row_offset: int = 0) -> ControlPointSet:
    """The control points of an acquisition as a user would have them (``docs/gcp.md``):
    the map positions and image measurements the emulator drew with their errors (never
    the truth), their 1σ from the scenario's ``[gcps]``, lines in the L0 archive's rows
    (the emulator's line minus ``row_offset``, ``Truth.row_offset``)."""
    g, cfg, n = acq.gcps, acq.scenario.gcps, acq.gcps.line.size
    return ControlPointSet(
        tuple(f"hrv{acq.hrv.number}_p{k:04d}" for k in range(n)),
        g.lon_rad.copy(),
        g.lat_rad.copy(),
        g.h_m.copy(),
        g.line - row_offset,
        g.column.copy(),
        np.full(n, max(cfg.horizontal_error_m, 0.01)),
        np.full(n, max(cfg.vertical_error_m, 0.01)),
        np.full(n, max(cfg.pointing_error_px, 0.01)),
        np.full(n, acq.hrv.number, np.int64),
    )


def measured_control_points(
    acq: Acquisition, archive: L0Archive, path: str | Path
) -> tuple[Truth, ControlPointSet]:
    """The truth behind a recorded archive, and the acquisition's control points written
    to ``path`` as a user has them (``docs/gcp.md``, lines on the archive's rows) and read
    back the way the processing centre reads them."""
    truth = Truth.of(acq, archive)
    written = write_gcps(
        path,
        control_points(acq, truth.row_offset),
        f"control points of {acq.scenario.name}, HRV{acq.hrv.number}, as measured (docs/gcp.md)",
    )
    return truth, read_gcps(written, archive.n_lines, archive.n_columns)
