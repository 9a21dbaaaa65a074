"""The processing library's layers: ``levels`` never imports ``station``; geometry is the
bottom layer; GEO and COR are numerical (no I/O); every module and function stays readable."""

from __future__ import annotations

from pathlib import Path

import pytest
from _source import ROOT, imports, modules, too_long, top


@pytest.mark.parametrize("path", modules("levels"), ids=lambda p: str(p.relative_to(ROOT)))
def test_levels_never_imports_station(path: Path) -> None:
    bad = sorted(n for n in imports(path) if top(n) == "station")
    assert not bad, f"{path.relative_to(ROOT)} imports {bad}: the flow is station → levels only"


@pytest.mark.parametrize("path", modules("levels/geometry"), ids=lambda p: str(p.relative_to(ROOT)))
def test_geometry_is_the_bottom_layer(path: Path) -> None:
    forbidden = ("h5py", "levels.readers", "levels.geo", "levels.cor", "xml", "rasterio")
    bad = sorted(
        n for n in imports(path) if any(n == f or n.startswith(f + ".") for f in forbidden)
    )
    assert not bad, f"{path.relative_to(ROOT)} imports {bad}: geometry is numerical and lowest"


def test_the_walker_sees_a_wrong_way_import(tmp_path: Path) -> None:
    bad = tmp_path / "bad.py"
    bad.write_text("import numpy\nfrom station.cli import main\n")
    assert "station.cli" in imports(bad)


@pytest.mark.parametrize(
    "path", modules("levels/geo") + modules("levels/cor"), ids=lambda p: str(p.relative_to(ROOT))
)
def test_geo_and_cor_are_numerical(path: Path) -> None:
    forbidden = ("h5py", "levels.readers", "levels.products", "rasterio")
    if "levels/geo" in str(path):
        forbidden += ("levels.cor",)  # GEO computes, COR applies: never the other way
    bad = sorted(
        n for n in imports(path) if any(n == f or n.startswith(f + ".") for f in forbidden)
    )
    assert not bad, f"{path.relative_to(ROOT)} imports {bad}: GEO and COR do no I/O"


@pytest.mark.parametrize("path", modules("levels"), ids=lambda p: str(p.relative_to(ROOT)))
def test_levels_modules_stay_readable(path: Path) -> None:
    assert not too_long(path), f"{path.relative_to(ROOT)}: {', '.join(too_long(path))}"
