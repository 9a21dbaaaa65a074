"""What the tests read of the source: each module's imports, the modules of a package,
and the size bounds of the house (issue 48)."""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def imports(path: Path) -> set[str]:
    """The absolute imports of a module (``import a.b``, ``from a.b import c``), lazy ones
    included."""
    tree = ast.parse(path.read_text(), filename=str(path))
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.add(node.module)
    return names


def modules(package: str) -> list[Path]:
    """Every module under ``package`` (a directory of the repository)."""
    files = sorted((ROOT / package).rglob("*.py"))
    assert files, f"no modules found under {package}/"
    return files


def top(name: str) -> str:
    return name.split(".")[0]


#: Size bounds of the house (issue 48): a function a reader takes in at once, a module
#: a reader can hold; numba kernels (one loop nest each, split only at a cost) excepted.
MAX_FUNCTION_LINES = 80
MAX_MODULE_LINES = 800


def _is_kernel(node: ast.FunctionDef | ast.AsyncFunctionDef) -> bool:
    for d in node.decorator_list:
        f = d.func if isinstance(d, ast.Call) else d
        if isinstance(f, ast.Attribute) and f.attr == "njit":
            return True
    return False


def too_long(path: Path) -> list[str]:
    """What in a module is over the house's bounds: the module, or its functions."""
    text = path.read_text()
    out = [f"{path.relative_to(ROOT)}: over {MAX_MODULE_LINES} lines"] * (
        text.count("\n") > MAX_MODULE_LINES
    )
    return out + [
        f"{n.name} ({n.end_lineno - n.lineno + 1} lines, over {MAX_FUNCTION_LINES})"
        for n in ast.walk(ast.parse(text))
        if isinstance(n, ast.FunctionDef | ast.AsyncFunctionDef)
        and n.end_lineno is not None
        and n.end_lineno - n.lineno + 1 > MAX_FUNCTION_LINES
        and not _is_kernel(n)
    ]
