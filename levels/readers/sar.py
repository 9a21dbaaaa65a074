"""A SAR frame as the processing centre reads it: the house frame file (``SAR-FRAME``).

Every reader of a SAR frame gives a :class:`SarFrame`, in the shape of sarsen's product
protocol (``sarsen.datamodel.SarProduct``: a product type, its state vectors, its
backscatter), plus :meth:`SarFrame.image`: the detected slant-range image with the
annotation the range–Doppler geocoding needs (:class:`levels.sar.SarImage`). The geocoding
(:mod:`levels.sar`) and the frame's driver (:mod:`levels.frame`) know frames only through
it, so a reader of another format (ESA's ENVISAT ``SAR_IMP_1P``, issue 50) is one more
reader, not a change to them.

The house file (:func:`levels.writers.sar.write_sar_frame`, :func:`read_sar_frame`;
``docs/sar.md``) is HDF5, written whole and checksummed like the products
(:mod:`levels.hdf5`): root attributes ``format = "SAR-FRAME"``, ``format_version``,
``name``, ``instrument``, ``epoch_utc``, ``first_line_s``, ``line_interval_s``,
``near_range_m``, ``range_spacing_m``, ``wavelength_m``, ``looks``, ``right_looking``;
datasets ``intensity`` (float32, lines × samples, linear), ``state_t_s``, ``state_r_m``,
``state_v_m_per_s`` (ECEF, Earth-fixed velocity), ``doppler_hz`` (the centroid's
polynomial in ``(R − r0) / 1 km``). The station's emulator writes one per SAR run
(``<name>.frame.h5``) and the run processes it from the file.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

import h5py
import numpy as np
from numpy.typing import NDArray

from levels.errors import ProductError
from levels.geometry.times import Epoch
from levels.hdf5 import all_attrs, check_attrs_digest, damage_as
from levels.sar import SarAnnotation, SarImage

__all__ = [
    "FRAME_FORMAT",
    "FRAME_VERSION",
    "HouseFrame",
    "ImageFrame",
    "SarFrame",
    "is_sar_frame",
    "read_sar_frame",
]

FRAME_FORMAT = "SAR-FRAME"
FRAME_VERSION = 1
#: The annotation's numbers kept as root attributes, and its arrays as datasets.
SCALARS = (
    "first_line_s",
    "line_interval_s",
    "near_range_m",
    "range_spacing_m",
    "wavelength_m",
    "looks",
)
ARRAYS = ("state_t_s", "state_r_m", "state_v_m_per_s", "doppler_hz")


class SarFrame(Protocol):
    """What a reader of a SAR frame gives (module docstring)."""

    @property
    def product_type(self) -> str:
        """What the frame is: ``"slant range, detected"`` for the house frame."""
        ...

    @property
    def name(self) -> str:
        """The frame's name: its products are named after it."""
        ...

    @property
    def instrument(self) -> str:
        """The instrument, as the products' attributes name it."""
        ...

    @property
    def path(self) -> Path | None:
        """The file it was read from (the products' ``inputs`` name it), if any."""
        ...

    def state_vectors(self) -> tuple[NDArray[np.float64], ...]:
        """Times (s since the annotation's epoch), ECEF positions and Earth-fixed
        velocities of the orbit's state vectors."""
        ...

    def beta_nought(self) -> NDArray[np.float32]:
        """The detected image, lines × slant-range samples, linear."""
        ...

    def image(self) -> SarImage:
        """The image and its annotation, as :mod:`levels.sar` geocodes them."""
        ...


class ImageFrame:
    """What every reader's frame gives alike from its :class:`levels.sar.SarImage`
    (``sar``): the state vectors, the detected image, the image with its annotation."""

    sar: SarImage

    def state_vectors(self) -> tuple[NDArray[np.float64], ...]:
        a = self.sar.annotation
        return a.state_t_s, a.state_r_m, a.state_v_m_per_s

    def beta_nought(self) -> NDArray[np.float32]:
        return self.sar.intensity

    def image(self) -> SarImage:
        return self.sar


@dataclass(frozen=True, eq=False)
class HouseFrame(ImageFrame):
    """A frame of the house format (:func:`read_sar_frame`)."""

    name: str
    instrument: str
    sar: SarImage
    path: Path | None = None

    @property
    def product_type(self) -> str:
        return "slant range, detected"


def is_sar_frame(path: str | Path) -> bool:
    """Whether ``path`` is a house SAR frame file (its ``format`` attribute)."""
    try:
        with h5py.File(path, "r") as f:
            return bool(f.attrs.get("format") == FRAME_FORMAT)
    except OSError:
        return False


def read_sar_frame(path: str | Path) -> HouseFrame:
    """Read and check a house SAR frame file (module docstring); :class:`ProductError`
    naming what is wrong."""
    where = Path(path)
    if not where.is_file():
        raise ProductError(f"{where}: no such SAR frame file")
    with damage_as(ProductError, where), h5py.File(where, "r") as f:
        if f.attrs.get("format") != FRAME_FORMAT:
            raise ProductError(
                f"{where}: format {f.attrs.get('format')!r}, expected {FRAME_FORMAT!r}; "
                "not a SAR frame file"
            )
        if int(f.attrs.get("format_version", -1)) != FRAME_VERSION:
            raise ProductError(
                f"{where}: SAR frame format version {f.attrs.get('format_version')!r}; this "
                f"reader knows version {FRAME_VERSION}"
            )
        every = all_attrs(f)
        try:
            check_attrs_digest(f, required=True, attrs=every)
        except ValueError as exc:
            raise ProductError(f"{where}: {exc}") from None
        attrs: dict[str, Any] = every[""]
        arrays = {k: np.asarray(f[k][()], dtype=np.float64) for k in ARRAYS}
        intensity = np.asarray(f["intensity"][()], dtype=np.float32)
        annotation = SarAnnotation(
            epoch=Epoch(np.datetime64(str(attrs["epoch_utc"]), "ns"), "frame day"),
            state_t_s=arrays["state_t_s"],
            state_r_m=arrays["state_r_m"],
            state_v_m_per_s=arrays["state_v_m_per_s"],
            first_line_s=float(attrs["first_line_s"]),
            line_interval_s=float(attrs["line_interval_s"]),
            near_range_m=float(attrs["near_range_m"]),
            range_spacing_m=float(attrs["range_spacing_m"]),
            wavelength_m=float(attrs["wavelength_m"]),
            doppler_hz=tuple(float(v) for v in arrays["doppler_hz"]),
            shape=(int(intensity.shape[0]), int(intensity.shape[1])),
            looks=float(attrs["looks"]),
            right_looking=bool(attrs["right_looking"]),
        )
        sar = SarImage(annotation, intensity)
        return HouseFrame(str(attrs["name"]), str(attrs["instrument"]), sar, where)
