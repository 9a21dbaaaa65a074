"""Levels declared once: a level written in a test module alone is registered, planned with
the levels it requires, and made by ``station process`` without a change to the driver."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from levels.choices import Level
from levels.errors import OptionsError
from levels.makers.base import BandPixels, LevelMaker, Reads, SceneWork
from levels.makers.scene import register_level, unregister_level
from levels.makers.steps import common_tree
from levels.options import ProcessingOptions
from levels.process import plan_levels
from levels.products import BandImage, read_product
from levels.registry import level_names
from station.cli import main


def _mean_image(work: SceneWork, band: str, px: BandPixels) -> BandImage:
    """The toy level's image: one pixel, the mean of the 1A image's valid counts."""
    made = work.images[Level.L1A][band]  # the level it requires, made before it
    mean = float(made.image[made.valid].mean())
    work.figures.setdefault("mean_counts", {})[band] = mean
    return BandImage(np.array([[round(mean)]], np.uint8), np.ones((1, 1), bool))


def _mean_quality(work: SceneWork) -> dict[str, Any]:
    return {"mean_counts": work.figures["mean_counts"]}


MEAN = LevelMaker(
    name="mean",
    doc="the mean of the 1A image (a toy level)",
    image=_mean_image,
    quality=_mean_quality,
    geometry_tree=common_tree,
    reads=Reads.CALIBRATED,
    requires=(Level.L1A,),
    raw_geometry=True,
)


@pytest.fixture
def mean_level() -> Iterator[LevelMaker]:
    register_level(MEAN)
    try:
        yield MEAN
    finally:
        unregister_level(MEAN.name)


def test_a_registered_level_is_planned_after_what_it_requires(mean_level: LevelMaker) -> None:
    assert level_names()[-1] == "mean"
    assert [m.name for m in plan_levels(("mean",))] == ["1A", "mean"]
    assert [m.name for m in plan_levels(("2A", "mean", "1A"))] == ["1A", "2A", "mean"]
    assert ProcessingOptions(levels=("mean",)).levels == ("mean",)


def test_an_unknown_level_is_refused_by_name() -> None:
    with pytest.raises(OptionsError, match="'mean' is not a level"):
        ProcessingOptions(levels=("mean",))


def test_registering_twice_or_a_bad_name_is_refused(mean_level: LevelMaker) -> None:
    with pytest.raises(ValueError, match="already registered"):
        register_level(MEAN)
    with pytest.raises(ValueError, match="already registered"):
        register_level(LevelMaker("2A", "", _mean_image, _mean_quality, common_tree))
    with pytest.raises(ValueError, match="no '/' or '_'"):
        register_level(LevelMaker("a_b", "", _mean_image, _mean_quality, common_tree))


def test_station_process_makes_a_registered_level(
    mean_level: LevelMaker, run_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The toy level's products come out of ``station process``; the 1A it requires is
    made for it and not written, and its figure is the mean of the 1A product's image."""
    l0 = str(run_dir / "small_test.l0.h5")
    assert main(["process", l0, "--levels", "mean", "--out", str(tmp_path / "m")]) == 0
    made = sorted(p.name for p in (tmp_path / "m").glob("*.h5"))
    assert made == ["small_test_s000_mean.h5"]
    assert main(["process", l0, "--levels", "1A", "--out", str(tmp_path / "a")]) == 0
    capsys.readouterr()
    product = read_product(tmp_path / "m" / made[0])
    one_a = read_product(tmp_path / "a" / "small_test_s000_1A.h5").bands["P"]
    mean = float(one_a.image[one_a.valid].mean())
    assert product.level == "mean"
    assert product.quality["mean_counts"]["P"] == mean  # the same counts, the same sum
    assert product.bands["P"].image[0, 0] == round(mean)
