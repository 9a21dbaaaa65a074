"""``levels`` as a library on its own: the L0 archive shipped with the package (the pass of
``scenarios/warmup.toml``) into products, with no emulator and no ``station``."""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import pytest

from levels.options import ProcessingOptions
from levels.process import ProcessingRequest, process
from levels.products import read_product
from levels.quality import Headline
from levels.readers.l0 import read_l0
from levels.warmup import WARM_UP_ARCHIVE

HERE = Path(__file__).resolve().parent
#: The 2A inverse grid against the rigorous model: INPE's 0.05 px target (DESIGN.md), which
#: the full-size scenes meet with half of it to spare.
INVERSE_MAX_PX = 0.05
#: The 1B polynomials against the model: their cubic misfit of the gyro-integrated attitude
#: is 0.91 px at full size at nadir (docs/levels.md), over 6000 lines; the shipped scene's
#: 200 lines of pixels 30x the P pixel see a thirtieth of that attitude in pixels.
POLYNOMIALS_MAX_PX = 0.1


@pytest.mark.parametrize("path", sorted(HERE.glob("*.py")), ids=lambda p: p.name)
def test_the_library_tests_never_import_station(path: Path) -> None:
    tree = ast.parse(path.read_text())
    names = {a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names}
    names |= {n.module or "" for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)}
    assert not [n for n in names if n.split(".")[0] == "station"]


def test_the_shipped_archive_makes_every_image_level(tmp_path: Path) -> None:
    archive = read_l0(WARM_UP_ARCHIVE)
    options = ProcessingOptions(levels=("1A", "1B", "2A"))
    [made] = process(ProcessingRequest.of(archive, options, tmp_path / "a", "w"))
    # 240 lines of 200 detectors: one square scene, 40 lines of tail
    assert [s.index for s in made.scenes] == [0] and made.tail_lines == 40
    paths = made.scenes[0].paths
    assert list(paths) == ["1A", "1B", "2A"]
    one_a, one_b, two_a = (read_product(paths[lv]) for lv in ("1A", "1B", "2A"))
    assert one_a.bands["P"].image.shape == (200, archive.bands["P"].counts.shape[1])
    assert one_a.map_grid is None and two_a.map_grid is not None
    q = made.scenes[0].quality
    assert q["2A"]["inverse_vs_model/nearest4/max_px"] < INVERSE_MAX_PX
    assert q["1B"]["polynomials_vs_model/max_px"] < POLYNOMIALS_MAX_PX
    assert "checkpoints" not in two_a.quality  # no checkpoint source, no checkpoints
    # the headline figures, read back by the module that flattened them
    h2, h1, ha = (Headline.of(q[lv]) for lv in ("2A", "1B", "1A"))
    assert h2.approx_max_px == q["2A"]["inverse_vs_model/nearest4/max_px"]
    assert h1.approx_max_px == q["1B"]["polynomials_vs_model/max_px"]
    assert h2.los_rms_m is None and ha.approx_max_px is None
    assert ha.band == "P" and ha.stripes_counts == (
        q["1A"]["stripe_level/P/raw_counts"],
        q["1A"]["stripe_level/P/level_1a_counts"],
    )
    # the same request again gives the same images, bit for bit
    [again] = process(ProcessingRequest.of(read_l0(WARM_UP_ARCHIVE), options, tmp_path / "b", "w"))
    for level, path in paths.items():
        a, b = read_product(path).bands["P"], read_product(again.scenes[0].paths[level]).bands["P"]
        assert np.array_equal(a.image, b.image) and np.array_equal(a.valid, b.valid)
    assert one_b.bands["P"].valid.mean() > 0.5
