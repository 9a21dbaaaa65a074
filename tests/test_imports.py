"""The station's imports: the receiving station never imports the emulator, which takes only
primitives from ``levels``; no import circle; the command line imports nothing from
``levels`` but its errors; only the skeleton publishes and only the drivers make products
(``levels``' own layers: ``tests/levels/test_layers.py``)."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest
from _source import ROOT, imports, modules, too_long, top


@pytest.mark.parametrize("path", modules("station/srrs"), ids=lambda p: str(p.relative_to(ROOT)))
def test_the_receiving_station_never_imports_the_emulator(path: Path) -> None:
    """The SRRS sees bytes, as a real station does: the chain that feeds it the emulator's
    passes lives in ``station.chain``."""
    bad = sorted(n for n in imports(path) if n.startswith("station.spacecraft"))
    assert not bad, f"{path.relative_to(ROOT)} imports {bad}: the station sees bytes only"


#: What the emulator may take from ``levels``: checked primitives only (geometry, threads,
#: files, SPOT's facts, and the SAR annotation: the range–Doppler frame geometry the
#: emulator writes as ERS's annotation and the processing reads). Never a processing
#: stage: the truth must not be the model it checks.
EMULATOR_MAY_IMPORT = (
    "levels.geometry",
    "levels.threads",
    "levels.files",
    "levels.spot",
    "levels.sar.annotation",
)


@pytest.mark.parametrize(
    "path", modules("station/spacecraft"), ids=lambda p: str(p.relative_to(ROOT))
)
def test_the_emulator_takes_only_primitives_from_levels(path: Path) -> None:
    bad = sorted(
        n
        for n in imports(path)
        if top(n) == "levels"
        and not any(n == a or n.startswith(a + ".") for a in EMULATOR_MAY_IMPORT)
    )
    assert not bad, f"{path.relative_to(ROOT)} imports {bad}: the emulator takes primitives only"


def test_the_emulator_imported_alone_loads_no_processing_stage() -> None:
    """Its primitives are its only imports at run time too: the SAR annotation's package
    face loads no geocoding, masks nor radiometry (checked in a fresh interpreter)."""
    import subprocess
    import sys

    code = (
        "import sys, station.spacecraft.emulator, station.spacecraft.sar; "
        "print(' '.join(sorted(m for m in sys.modules if m.startswith('levels.'))))"
    )
    loaded = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=120
    ).stdout.split()
    stages = ("levels.sar.geocoding", "levels.sar.masks", "levels.sar.radiometry", "levels.cor")
    assert not [m for m in loaded if m.startswith(stages) or m.startswith("levels.makers")]


def _module_graph() -> dict[str, set[str]]:
    """Every module of levels and station and the modules of the two it imports anywhere
    (at the top, inside functions, under TYPE_CHECKING): a lazy import is an arrow too."""
    mods = {}
    for path in modules("levels") + modules("station"):
        name = ".".join(path.relative_to(ROOT).with_suffix("").parts)
        mods[name.removesuffix(".__init__")] = path
    graph: dict[str, set[str]] = {}
    for name, path in mods.items():
        tree = ast.parse(path.read_text(), filename=str(path))
        seen: set[str] = set()
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                seen.update(a.name for a in node.names)
            elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                seen.add(node.module)
                seen.update(f"{node.module}.{a.name}" for a in node.names)
        graph[name] = {m for m in seen if m in mods and m != name and mods[m].name != "__init__.py"}
    return graph


def test_no_import_circle_lazy_imports_counted() -> None:
    """No module reaches itself through the imports of others (issue 58: the house has
    floors; a package's face, which only hands names on, is not a room)."""
    graph = _module_graph()
    circles = []
    state: dict[str, int] = {}  # 1: on the path, 2: done

    def visit(m: str, path: list[str]) -> None:
        state[m] = 1
        for n in sorted(graph[m]):
            if state.get(n) == 1:
                circles.append([*path[path.index(n) :], n])
            elif n not in state:
                visit(n, [*path, n])
        state[m] = 2

    for m in sorted(graph):
        if m not in state:
            visit(m, [m])
    assert not circles, " ; ".join(" -> ".join(c) for c in circles[:5])


@pytest.mark.parametrize("path", modules("station/cli"), ids=lambda p: str(p.relative_to(ROOT)))
def test_the_command_line_imports_nothing_from_levels_but_its_errors(path: Path) -> None:
    """The CLI parses, calls one function of the station and prints (issue 58)."""
    bad = sorted(n for n in imports(path) if top(n) == "levels" and n != "levels.errors")
    assert not bad, f"{path.relative_to(ROOT)} imports {bad}"


#: What only the run skeleton (station/flow.py) calls: publishing a directory, writing its
#: catalogue, a report's header (issue 58: one skeleton, not seven publish sites).
SKELETON_ONLY = ("published_dir", "write_catalog", ".header")
#: The drivers of levels: the only callers of the makers and writers of products (the
#: plan, the scene driver, the frame's, and the pair's DEM maker writing its own).
PRODUCT_WRITERS = {"levels/work.py", "levels/process.py", "levels/frame.py", "levels/makers/dem.py"}


def _calls(path: Path) -> set[str]:
    """The names called in ``path``: ``f`` of ``f(...)``, ``.f`` of ``x.f(...)``."""
    tree = ast.parse(path.read_text(), filename=str(path))
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Call):
            f = node.func
            out.add(
                f.id if isinstance(f, ast.Name) else f.attr if isinstance(f, ast.Attribute) else ""
            )
    return out


@pytest.mark.parametrize("path", modules("station"), ids=lambda p: str(p.relative_to(ROOT)))
def test_only_the_skeleton_publishes_catalogues_and_heads_reports(path: Path) -> None:
    if path.relative_to(ROOT).as_posix() == "station/flow.py":
        return
    assert not _calls(path) & set(SKELETON_ONLY), f"{path.relative_to(ROOT)}: station.flow's"


@pytest.mark.parametrize(
    "path", modules("levels") + modules("station"), ids=lambda p: str(p.relative_to(ROOT))
)
def test_only_the_drivers_make_and_write_products(path: Path) -> None:
    if path.relative_to(ROOT).as_posix() in PRODUCT_WRITERS:
        return
    called = _calls(path) & {"write_product", ".write_product", ".make", "make_scene"}
    assert not called, f"{path.relative_to(ROOT)} calls {sorted(called)}: the drivers' own"


@pytest.mark.parametrize("path", modules("station"), ids=lambda p: str(p.relative_to(ROOT)))
def test_station_modules_stay_readable(path: Path) -> None:
    assert not too_long(path), f"{path.relative_to(ROOT)}: {', '.join(too_long(path))}"
