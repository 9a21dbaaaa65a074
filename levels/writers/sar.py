"""The house SAR frame file written (``SAR-FRAME``, :mod:`levels.readers.sar` reads it
back): a detected slant-range frame and its annotation, whole and checksummed."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from levels.hdf5 import checksummed, new_hdf5
from levels.readers.sar import ARRAYS, FRAME_FORMAT, FRAME_VERSION, SCALARS
from levels.sar import SarImage

__all__ = ["write_sar_frame"]


def write_sar_frame(path: str | Path, image: SarImage, name: str, instrument: str) -> Path:
    """Write ``image`` (a detected slant-range frame and its annotation) as a house frame
    file at ``path``, whole and checksummed; returns its path."""
    a = image.annotation
    target = Path(path)
    with new_hdf5(target) as f:
        f.attrs["format"] = FRAME_FORMAT
        f.attrs["format_version"] = FRAME_VERSION
        f.attrs["name"] = name
        f.attrs["instrument"] = instrument
        f.attrs["epoch_utc"] = str(np.asarray(a.epoch.t0_utc).astype("datetime64[ns]"))
        f.attrs["right_looking"] = int(a.right_looking)
        for key in SCALARS:
            f.attrs[key] = float(getattr(a, key))
        intensity = np.ascontiguousarray(image.intensity, dtype=np.float32)
        f.create_dataset("intensity", data=intensity, **checksummed(intensity))
        for key in ARRAYS:
            value = np.asarray(getattr(a, key), dtype=np.float64)
            f.create_dataset(key, data=value, **checksummed(value))
    return target
