"""SHA-256 of every dataset and attribute set of every product under a directory.

A refactoring that must not change any result is checked with it: run the scenarios before
and after, then ``python tools/product_hashes.py BEFORE AFTER`` names every dataset whose
bytes (or attributes) differ, and exits 1 if any does. With one directory it prints the
hashes. Attributes that record the software version are left out (a version bump is not a
change of results).

    python tools/product_hashes.py runs_before/ runs_after/
"""

from __future__ import annotations

import hashlib
import sys
from pathlib import Path

import h5py
import numpy as np

from levels.products import is_product_file

#: Attributes that name the software, not the result.
_IGNORED_ATTRS = {"software"}


def _plain(value: object, f: h5py.File) -> str:
    """An attribute's value as text, HDF5 object references (the dimension scales' lists)
    as the names of the objects they point to, not their addresses in memory."""
    if isinstance(value, h5py.Reference):
        return str(f[value].name)
    if isinstance(value, np.void | tuple):
        return "(" + ",".join(_plain(v, f) for v in tuple(value)) + ")"
    if isinstance(value, np.ndarray) and value.dtype.kind in "OV":
        return "[" + ",".join(_plain(v, f) for v in value.ravel()) + "]"
    if isinstance(value, np.ndarray):
        return f"{value.dtype}{value.shape}:{hashlib.sha256(value.tobytes()).hexdigest()}"
    return repr(value)


def _attrs_digest(obj: h5py.HLObject) -> str:
    h = hashlib.sha256()
    for key in sorted(obj.attrs):
        if key in _IGNORED_ATTRS:
            continue
        h.update(key.encode())
        h.update(_plain(obj.attrs[key], obj.file).encode())
    return h.hexdigest()


def product_hashes(path: Path) -> dict[str, str]:
    """``{"<dataset path>": sha256, "<group path>@attrs": sha256}`` of one product file."""
    out: dict[str, str] = {}
    with h5py.File(path, "r") as f:
        out["/@attrs"] = _attrs_digest(f)

        def visit(name: str, obj: h5py.HLObject) -> None:
            if isinstance(obj, h5py.Dataset):
                out[name] = hashlib.sha256(np.ascontiguousarray(obj[()]).tobytes()).hexdigest()
            out[f"{name}@attrs"] = _attrs_digest(obj)

        f.visititems(visit)
    return out


def tree_hashes(root: Path) -> dict[str, str]:
    """Every product under ``root`` (``*_s*_*.h5``), keyed by its path relative to ``root``."""
    out: dict[str, str] = {}
    for p in sorted(q for q in root.rglob("*") if is_product_file(q)):
        if p.name.endswith(".l0.h5"):
            continue
        rel = p.relative_to(root).as_posix()
        for key, digest in product_hashes(p).items():
            out[f"{rel}:{key}"] = digest
    return out


def main(argv: list[str]) -> int:
    if len(argv) == 1:
        for key, digest in tree_hashes(Path(argv[0])).items():
            print(digest, key)
        return 0
    a, b = (tree_hashes(Path(d)) for d in argv[:2])
    bad = sorted(k for k in a.keys() | b.keys() if a.get(k) != b.get(k))
    for k in bad:
        print(f"differs: {k} ({'only in one' if k not in a or k not in b else 'bytes'})")
    n_files = len({k.split(":")[0] for k in a})
    print(f"{len(a)} datasets and attribute sets in {n_files} products; {len(bad)} differ")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
