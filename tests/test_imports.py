"""Imports go one way: station → levels, never back; geometry below the rest of levels;
numerical modules do no I/O (no h5py, no file readers in levels.geometry)."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _imports(path: Path) -> set[str]:
    tree = ast.parse(path.read_text(), filename=str(path))
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.add(node.module)
    return names


def _modules(package: str) -> list[Path]:
    files = sorted((ROOT / package).rglob("*.py"))
    assert files, f"no modules found under {package}/"
    return files


def _top(name: str) -> str:
    return name.split(".")[0]


@pytest.mark.parametrize("path", _modules("levels"), ids=lambda p: str(p.relative_to(ROOT)))
def test_levels_never_imports_station(path: Path) -> None:
    bad = sorted(n for n in _imports(path) if _top(n) == "station")
    assert not bad, f"{path.relative_to(ROOT)} imports {bad}: the flow is station → levels only"


@pytest.mark.parametrize(
    "path", _modules("levels/geometry"), ids=lambda p: str(p.relative_to(ROOT))
)
def test_geometry_is_the_bottom_layer(path: Path) -> None:
    forbidden = ("h5py", "levels.readers", "levels.geo", "levels.cor", "xml", "rasterio")
    bad = sorted(
        n for n in _imports(path) if any(n == f or n.startswith(f + ".") for f in forbidden)
    )
    assert not bad, f"{path.relative_to(ROOT)} imports {bad}: geometry is numerical and lowest"


def test_the_walker_sees_a_wrong_way_import(tmp_path: Path) -> None:
    bad = tmp_path / "bad.py"
    bad.write_text("import numpy\nfrom station.cli import main\n")
    assert "station.cli" in _imports(bad)


@pytest.mark.parametrize(
    "path", _modules("levels/geo") + _modules("levels/cor"), ids=lambda p: str(p.relative_to(ROOT))
)
def test_geo_and_cor_are_numerical(path: Path) -> None:
    forbidden = ("h5py", "levels.readers", "levels.products", "rasterio")
    if "levels/geo" in str(path):
        forbidden += ("levels.cor",)  # GEO computes, COR applies: never the other way
    bad = sorted(
        n for n in _imports(path) if any(n == f or n.startswith(f + ".") for f in forbidden)
    )
    assert not bad, f"{path.relative_to(ROOT)} imports {bad}: GEO and COR do no I/O"


@pytest.mark.parametrize("path", _modules("station/srrs"), ids=lambda p: str(p.relative_to(ROOT)))
def test_the_receiving_station_never_imports_the_emulator(path: Path) -> None:
    """The SRRS sees bytes, as a real station does: the chain that feeds it the emulator's
    passes lives in ``station.chain``."""
    bad = sorted(n for n in _imports(path) if n.startswith("station.spacecraft"))
    assert not bad, f"{path.relative_to(ROOT)} imports {bad}: the station sees bytes only"
