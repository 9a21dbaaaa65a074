"""ERS SAR frames in ESA's ENVISAT format (``levels.readers.envisat``,
``levels.writers.envisat``), ``levels`` alone: a synthetic frame (``_orbits.synthetic_frame``)
written as ``SAR_IMP_1P`` (slant and ground range) and ``SAR_IMS_1P``, opened by GDAL's ESAT
driver with ESA's geolocation grid where ``levels.sar`` locates it, read back the same, its
Doppler centroid through the format. The station's commands on such files are
``tests/test_envisat.py``'s."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest
from _frames import ENVISAT_VARIANTS
from _orbits import synthetic_frame

#: GDAL's GCPs (ESA's grid) against where levels.sar locates their ground: the issue's
#: 0.1 px; they differ by the grid's 1e-6° rounding (0.11 m, 0.014 px).
GCP_PX = 0.1
#: The near range through the file's float32 two-way time in ns (0.5 ns: 7.5 cm).
NEAR_RANGE_M = 0.1
#: The amplitude's 16-bit counts, the median at 1000: an intensity's relative error
#: 2 × 0.5 / 1000 at the median (measured 5e-4).
INTENSITY_REL = 1e-3
#: The five state vectors' centimetre and 10 µm/s, and their re-interpolation (m).
ORBIT_M = 0.02

VARIANTS = ENVISAT_VARIANTS


@pytest.fixture(scope="module")
def frame():
    return synthetic_frame(120, 100)


@pytest.fixture(scope="module")
def files(frame, tmp_path_factory) -> dict[str, Path]:
    from levels.writers.envisat import write_envisat

    d = tmp_path_factory.mktemp("envisat")
    return {k: write_envisat(d / f"{k}.E1", frame, **kw) for k, kw in VARIANTS.items()}


@pytest.mark.parametrize("variant", list(VARIANTS))
def test_gdal_opens_the_file_with_its_size_metadata_and_grid(frame, files, variant) -> None:
    import rasterio

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with rasterio.open(files[variant]) as ds:
            assert ds.driver == "ESAT" and (ds.height, ds.width) == frame.annotation.shape
            assert ds.dtypes[0] == ("complex_int16" if variant == "ims" else "uint16")
            tags = ds.tags()
            gcps = ds.gcps[0]
    product = "SAR_IMS_1P" if variant == "ims" else "SAR_IMP_1P"
    assert tags["MPH_PRODUCT"].startswith(product) and tags["MPH_PRODUCT"].endswith(".E1")
    assert int(tags["SPH_LINE_LENGTH"]) == frame.annotation.shape[1]
    assert len(gcps) == 11 * (20 + 1)  # 20 granules' first lines, the last one's last
    lat = np.radians([g.y for g in gcps])
    lon = np.radians([g.x for g in gcps])
    line, _ = frame.annotation.image_of(lat, lon, np.zeros_like(lat))
    assert np.max(np.abs(line + 0.5 - np.array([g.row for g in gcps]))) <= GCP_PX
    if variant != "imp_ground":  # on slant range, GDAL's columns are levels.sar's too
        _, col = frame.annotation.image_of(lat, lon, np.zeros_like(lat))
        assert np.max(np.abs(col + 0.5 - np.array([g.col for g in gcps]))) <= GCP_PX


@pytest.mark.parametrize("variant", list(VARIANTS))
def test_the_reader_gives_the_frame_back(frame, files, variant) -> None:
    from levels.readers.envisat import read_envisat

    e = read_envisat(files[variant])
    a, b = frame.annotation, e.image().annotation
    first_a = a.epoch.utc(np.array([a.first_line_s]))[0]
    first_b = b.epoch.utc(np.array([b.first_line_s]))[0]
    assert abs((first_a - first_b) / np.timedelta64(1, "us")) <= 1.0
    assert b.line_interval_s == pytest.approx(a.line_interval_s, rel=1e-9)
    assert abs(b.near_range_m - a.near_range_m) <= NEAR_RANGE_M
    assert b.range_spacing_m == pytest.approx(a.range_spacing_m, rel=1e-6)
    assert b.wavelength_m == pytest.approx(a.wavelength_m, rel=1e-6)
    assert b.looks == a.looks and b.right_looking
    t = a.first_line_s + np.linspace(0, a.shape[0] - 1, 7) * a.line_interval_s
    ra, _ = a.ephemeris.interpolate(t)
    rb, _ = b.ephemeris.interpolate(b.epoch.seconds(a.epoch.utc(t)))
    assert np.max(np.linalg.norm(ra - rb, axis=1)) <= ORBIT_M
    assert e.instrument == "ERS-1 AMI SAR" and e.name == variant
    if variant != "imp_ground":  # the samples themselves, as written
        assert b.shape == a.shape
        i0, i1 = frame.intensity, e.image().intensity
        keep = i0 > 0
        assert np.median(np.abs(i1[keep] - i0[keep]) / i0[keep]) <= INTENSITY_REL
    else:  # resampled onto ground range and back: the same swath on slant range
        assert abs(b.shape[1] - a.shape[1]) <= 1
        assert np.nanmean(e.image().intensity) == pytest.approx(np.mean(frame.intensity), rel=0.05)


def test_the_doppler_centroid_survives_the_format(frame, tmp_path) -> None:
    """A centroid that varies across the swath, written in two-way slant-range time and
    read back as the house polynomial in (R − r0) / 1 km."""
    import dataclasses

    from levels.readers.envisat import read_envisat
    from levels.sar import SarImage
    from levels.writers.envisat import write_envisat

    ann = dataclasses.replace(frame.annotation, doppler_hz=(120.0, -15.0, 0.8))
    path = write_envisat(tmp_path / "dop.E1", SarImage(ann, frame.intensity))
    back = read_envisat(path).image().annotation
    r = ann.near_range_m + np.linspace(0, 1, 9) * ann.shape[1] * ann.range_spacing_m
    assert np.allclose(back.doppler_at(r), ann.doppler_at(r), atol=1e-3)
