"""A SPOT 1–4 level-1A DIMAP scene as the processing centre's input: SPOT World Heritage's
archive processed to every level.

CNES's SPOT World Heritage (SWH) delivers the SPOT 1–4 archive as level-1A scenes: a zip
holding ``METADATA.DIM`` (DIMAP v1, :mod:`levels.readers.dimap`) and ``IMAGERY.TIF`` (8-bit
counts in the raw geometry, the detectors already equalised). :func:`read_scene_1a` reads
one, the zip in place (GDAL's ``/vsizip/``: nothing unpacked to disk), a scene directory
or its ``METADATA.DIM``, and gives it as an :class:`~levels.readers.l0.L0Archive` of one
scene, so that GEO and COR make its levels exactly as they make an L0 archive's:

- **counts** the 1A's, read by rows when a scene task asks (:class:`TiffRows`), with an
  identity calibration (gain 1, offset 0): the producer equalised the detectors, so
  level 1A is the image as delivered and 1B, 2A, 2, 3 resample it;
- **validity** a whole row per segment: a row of zeros is a line the producer did not
  have (SWH fills lost lines with 0); every other pixel is valid;
- **time** each row at ``SCENE_CENTER_TIME + (row − SCENE_CENTER_LINE) · LINE_PERIOD``,
  counted from the scene centre (the archive's epoch);
- **ephemeris** the file's points, velocities as given (inertial in ECEF axes for
  SPOT 1–4);
- **attitude** the gyro record GEO integrates from a null first record and zeroes at the
  scene centre (INPE, paper ``004_…`` §2.1): the file's ``Angular_Speeds`` when its
  ``attitude`` choice is the integrated rates, zero rates for the null attitude; ``auto``
  is the reader's (:attr:`~levels.readers.dimap.DimapScene.auto_attitude`: the one that
  reproduces the producer's frame), so that the products' model is the one ``station
  locate`` checks;
- **look angles** each band's table, mirror included;
- **radiance** each band's ``PHYSICAL_GAIN`` and ``PHYSICAL_BIAS`` (``L = (X − bias) /
  gain``) in the provenance the products carry, with the mission, instrument, imaging
  date, the source file and the route (``"DIMAP 1A scene"``).

What it refuses, in one line naming the file: a frame-only DIMAP (no model), a level 1B or
2A scene (its geometry is no longer raw), a SPOT 5 scene (its absolute, star-tracker
attitude is not the gyro-relative one GEO integrates: ``station locate`` reads it), an
image whose size or type is not the metadata's.
"""

from __future__ import annotations

import json
import warnings
import zipfile
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath
from typing import Any

import numpy as np
from numpy.typing import NDArray

from levels.choices import Level
from levels.errors import DimapError
from levels.readers.bounded import gdal_image_alone
from levels.readers.dimap import AttitudeChoice, DimapScene, dimap_member, read_dimap
from levels.readers.l0 import L0Archive, L0Band
from levels.spot import MODES

__all__ = [
    "ROUTE",
    "TiffRows",
    "band_names_of",
    "is_dimap_scene",
    "read_scene_1a",
]

#: The provenance's ``route`` of products made from a DIMAP 1A scene.
ROUTE = "DIMAP 1A scene"
#: Rows a scene may have per column of an HRV line at most: a 1A scene is about square
#: (6000 × 6000 P); ten of them, a whole segment, is the most anyone delivers as one.
_MAX_ROWS_PER_COLUMN = 10
#: Gyro records per second written for the null attitude (the files' own rate, 8 Hz).
_NULL_RATE_HZ = 8.0


def is_dimap_scene(path: str | Path) -> bool:
    """Whether ``path`` is a DIMAP scene :func:`read_scene_1a` opens: a ``METADATA.DIM``
    (or any ``.DIM``), a directory holding one, or a zip holding one."""
    p = Path(path)
    if p.is_dir():
        return (p / "METADATA.DIM").is_file()
    if p.suffix.upper() == ".DIM":
        return True
    if p.suffix.lower() == ".zip" and zipfile.is_zipfile(p):
        with zipfile.ZipFile(p) as z:
            return any(PurePosixPath(n).name.upper() == "METADATA.DIM" for n in z.namelist())
    return False


@dataclass(frozen=True)
class TiffRows:
    """One band of a scene's image left in its file, read by rows when sliced (what a scene
    task holds: a few bytes to send to another process). ``uri`` is GDAL's name of the
    file (``/vsizip/…`` inside a zip); ``band`` 1-based."""

    uri: str
    band: int
    shape: tuple[int, int]
    dtype: np.dtype = field(default=np.dtype(np.uint8))

    @property
    def ndim(self) -> int:
        return 2

    def __getitem__(self, rows: slice) -> NDArray[np.uint8]:
        import rasterio
        from rasterio.windows import Window

        if not isinstance(rows, slice):
            raise TypeError(f"a scene's counts are read by rows: a slice, not {rows!r}")
        start, stop, step = rows.indices(self.shape[0])
        if step != 1:
            raise TypeError("a scene's counts are read by contiguous rows")
        with _quiet(), gdal_image_alone(), rasterio.open(self.uri) as ds:
            window = Window(0, start, self.shape[1], max(stop - start, 0))
            return np.ascontiguousarray(ds.read(self.band, window=window))

    def __array__(self, dtype: Any = None, copy: Any = None) -> NDArray[Any]:
        a = self[:]
        return a if dtype is None else a.astype(dtype)


@contextmanager
def _quiet() -> Iterator[None]:
    """A raw 1A has no georeferencing (GDAL's DIMAP driver gives it the frame's GCPs):
    rasterio's warning of it is noise here."""
    from rasterio.errors import NotGeoreferencedWarning

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NotGeoreferencedWarning)
        yield


def band_names_of(scene: DimapScene) -> list[str]:
    """The project's name of each band of the image, in its order: SPOT 1–3 ``P`` and XS
    (``X``: XS1, XS2, XS3), SPOT 4 HRVIR ``M`` (its red band at 10 m) and XI (``I``: XS1,
    XS2, XS3, SWIR); otherwise by the bands' count."""
    by_code = {
        "P": ["P"],
        "M": ["M"],
        "X": ["XS1", "XS2", "XS3"],
        "I": ["XS1", "XS2", "XS3", "SWIR"],
    }
    names = by_code.get(scene.sensor_code.upper())
    if names is None or len(names) != scene.n_bands:
        names = {1: ["P"], 3: ["XS1", "XS2", "XS3"], 4: ["XS1", "XS2", "XS3", "SWIR"]}.get(
            scene.n_bands, [f"B{k + 1}" for k in range(scene.n_bands)]
        )
    return names


def _image_uri(path: Path, scene: DimapScene) -> str:
    """GDAL's name of the scene's image: beside its ``METADATA.DIM``, or in its zip."""
    if path.is_file() and zipfile.is_zipfile(path):
        folder = PurePosixPath(dimap_member(path)).parent
        return f"/vsizip/{path.resolve()}/{folder / scene.image_file}"
    dim = path / "METADATA.DIM" if path.is_dir() else path
    return str(dim.parent / scene.image_file)


def _check_scene(path: Path, scene: DimapScene) -> None:
    """Refuse, in one line, a scene the chain cannot make levels of (module docstring)."""
    level = scene.processing_level.upper()
    if level and level != Level.L1A:
        raise DimapError(
            f"{path}: a level {scene.processing_level} scene: the processing centre makes its "
            "levels from a level 1A scene (raw geometry); this one is resampled already"
        )
    if scene.mission_index == 5 or scene.instrument.upper() == "HRG":
        raise DimapError(
            f"{path}: a SPOT 5 scene ({scene.name}): its attitude is absolute (star "
            "trackers), not the gyro-relative one GEO integrates for SPOT 1–4; station locate "
            "reads it"
        )
    most_cols = max(m.detectors for m in MODES.values())
    if scene.n_cols > most_cols or scene.n_rows > _MAX_ROWS_PER_COLUMN * most_cols:
        raise DimapError(
            f"{path}: {scene.n_rows} rows × {scene.n_cols} columns: a SPOT 1–4 level 1A scene "
            f"has at most {most_cols} columns (an HRV line) and {_MAX_ROWS_PER_COLUMN * most_cols} "
            "rows; not a scene the processing centre makes levels of"
        )
    scene.model()  # a frame-only file is refused here, saying what it lacks


def _counts(path: Path, scene: DimapScene, names: list[str]) -> dict[str, TiffRows]:
    """Each band's counts, left in the file; the image's size and type checked."""
    import rasterio
    from rasterio.errors import RasterioIOError

    uri = _image_uri(path, scene)
    try:
        with _quiet(), gdal_image_alone(), rasterio.open(uri) as ds:
            shape, count, dtypes = (ds.height, ds.width), ds.count, set(ds.dtypes)
    except RasterioIOError as exc:
        raise DimapError(f"{path}: its image {scene.image_file} cannot be read ({exc})") from None
    want = (scene.n_rows, scene.n_cols)
    if shape != want or count != len(names) or dtypes != {"uint8"}:
        raise DimapError(
            f"{path}: {scene.image_file} is {count} band(s) of {shape[0]} × {shape[1]} "
            f"{'/'.join(sorted(dtypes))}; the metadata says {len(names)} of {want[0]} × "
            f"{want[1]} uint8"
        )
    return {name: TiffRows(uri, k + 1, want) for k, name in enumerate(names)}


def _rows_present(counts: TiffRows) -> NDArray[np.bool_]:
    """Which rows of a band hold data: not all zeros (a line the producer did not have),
    read in blocks of rows."""
    n = counts.shape[0]
    step = max(1, (1 << 24) // max(counts.shape[1], 1))  # about 16 MB at a time
    return np.concatenate([counts[a : min(a + step, n)].any(axis=1) for a in range(0, n, step)])


def _gyro(scene: DimapScene, choice: AttitudeChoice) -> tuple[NDArray, NDArray]:
    """The gyro record GEO integrates (times from the scene centre, rates): the file's
    angular speeds for INPE's integrated attitude, zero rates for the null one."""
    if choice == "auto":
        choice = scene.auto_attitude
    if choice == "integrated_zeroed":
        assert scene.angular_speeds_t_s is not None and scene.angular_speeds_rad_per_s is not None
        return scene.angular_speeds_t_s, scene.angular_speeds_rad_per_s
    if choice != "none":
        raise DimapError(
            f"attitude {choice!r}: a scene is processed with the null attitude or with its "
            "gyro rates integrated and zeroed at the centre ('none', 'integrated_zeroed', "
            "'auto')"
        )
    assert scene.line_period_s is not None and scene.scene_center_line is not None
    half = (scene.n_rows * scene.line_period_s) / 2 + 2.0  # the scene and 2 s around it
    t = np.arange(-half, half + 1.0 / _NULL_RATE_HZ, 1.0 / _NULL_RATE_HZ)
    return t, np.zeros((t.size, 3))


def read_scene_1a(path: str | Path, attitude: AttitudeChoice = "auto") -> L0Archive:
    """A SPOT 1–4 level-1A DIMAP scene (a zip, a directory or its ``METADATA.DIM``) as an
    archive of one scene (module docstring); its counts stay in the file until a scene
    task reads them.

    Raises
    ------
    DimapError
        What the module docstring lists, naming the file.
    """
    source = Path(path)
    scene = read_dimap(source)
    _check_scene(source, scene)
    names = band_names_of(scene)
    counts = _counts(source, scene, names)
    assert scene.epoch is not None and scene.ephemeris is not None
    assert scene.line_period_s is not None and scene.scene_center_line is not None
    period = scene.line_period_s
    rows = np.arange(scene.n_rows, dtype=np.float64)
    line_t = (rows - (scene.scene_center_line - 1.0)) * period
    gyro_t, gyro = _gyro(scene, attitude)
    bands = {
        name: L0Band(
            name=name,
            counts=counts[name],  # type: ignore[arg-type]
            valid=_rows_present(counts[name])[:, None],
            look=scene.look_angles.get(k + 1) or scene.look_angles[min(scene.look_angles)],
            gain=np.ones(scene.n_cols),
            offset_counts=np.zeros(scene.n_cols),
            segment_first_detector=np.zeros(1, dtype=np.int64),
        )
        for k, name in enumerate(names)
    }
    return L0Archive(
        path=source,
        epoch=scene.epoch,
        hrv=scene.instrument_index or 1,
        mode=scene.sensor_code or ("P" if len(names) == 1 else "XS"),
        mirror_step=scene.mirror_step if scene.mirror_step is not None else 48,
        twin=False,
        bands=bands,
        line_counter=np.arange(scene.n_rows, dtype=np.int64),
        line_t_s=line_t,
        line_period_s=period,
        aux_t_s=gyro_t,
        aux_line_counter=np.round(gyro_t / period + scene.scene_center_line - 1.0).astype(np.int64),
        gyro_rates_rad_per_s=gyro,
        ephemeris=scene.ephemeris,
        attrs={
            "provenance": json.dumps(_provenance(source, scene, names, attitude)),
            "scene_cut": json.dumps({"scene_lines": scene.n_rows, "overlap_lines": 0}),
        },
    )


def _provenance(
    source: Path, scene: DimapScene, names: list[str], attitude: AttitudeChoice
) -> dict[str, object]:
    """What the products say of the scene they were made from (module docstring)."""
    radiance = {}
    for k, name in enumerate(names):
        cal = scene.calibration.get(k + 1)
        if cal is not None and cal.physical_gain:
            radiance[name] = {
                "physical_gain": cal.physical_gain,
                "physical_bias": cal.physical_bias or 0.0,
                "rule": "L = (counts - physical_bias) / physical_gain, W m-2 sr-1 um-1",
            }
    return {
        "route": ROUTE,
        "source": source.name,
        "mission": f"{scene.mission} {scene.mission_index or ''}".strip(),
        "instrument": f"{scene.instrument}{scene.instrument_index or ''}",
        "sensor_code": scene.sensor_code,
        "imaging_date": scene.imaging_date,
        "dataset_name": scene.dataset_name,
        "attitude": scene.auto_attitude if attitude == "auto" else attitude,
        "radiance": radiance,
    }
