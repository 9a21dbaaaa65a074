"""Levels declared once: a level written in a test module alone is registered, planned with
the levels it requires, and made by the unit of work (:mod:`levels.work`) from the shipped
L0 archive without a change to the driver."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

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
from levels.readers.l0 import read_l0
from levels.registry import level_names
from levels.warmup import WARM_UP_ARCHIVE
from levels.work import Pass, Request, plan, run


def _mean_image(work: SceneWork, band: str, px: BandPixels) -> BandImage:
    """The toy level's image: one pixel, the mean of the 1A image's valid counts."""
    made = work.images[Level.L1A][band]  # the level it requires, made before it
    mean = float(made.image[made.valid].mean())
    work.figures.setdefault("mean_counts", {})[band] = mean
    return BandImage(np.array([[round(mean)]], np.uint8), np.ones((1, 1), bool))


def _mean_quality(work: SceneWork) -> dict[str, object]:
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


def _made(levels: tuple[str, ...], out: Path) -> list[Path]:
    one = Pass((read_l0(WARM_UP_ARCHIVE),), ("w",))
    result = run(plan(Request(ProcessingOptions(levels=levels), out, (one,))))
    return [m.path for m in result.products]


def test_the_unit_of_work_makes_a_registered_level(mean_level: LevelMaker, tmp_path: Path) -> None:
    """The toy level's products come out of the plan; the 1A it requires is made for it
    and not written, and its figure is the mean of the 1A product's image."""
    made = _made(("mean",), tmp_path / "m")
    assert [p.name for p in made] == ["w_s000_mean.h5"]
    assert sorted(p.name for p in (tmp_path / "m").glob("*.h5")) == ["w_s000_mean.h5"]
    (one_a_path,) = _made(("1A",), tmp_path / "a")
    product = read_product(made[0])
    one_a = read_product(one_a_path).bands["P"]
    mean = float(one_a.image[one_a.valid].mean())
    assert product.level == "mean"
    assert product.quality["mean_counts"]["P"] == mean  # the same counts, the same sum
    assert product.bands["P"].image[0, 0] == round(mean)
