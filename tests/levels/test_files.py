"""Directories published whole (``levels.files.staged_dir``)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from levels.files import staged_dir


def _tree(d: Path) -> dict[str, str]:
    return {p.name: p.read_text() for p in sorted(d.iterdir())}


def test_a_directory_is_replaced_whole_only_on_success(tmp_path) -> None:
    out = tmp_path / "out"
    out.mkdir()
    (out / "old.txt").write_text("old")
    with pytest.raises(RuntimeError) as caught, staged_dir(out) as stage:
        (stage / "half.txt").write_text("half")
        raise RuntimeError("disk full")
    assert _tree(out) == {"old.txt": "old"}
    assert f"{out} left as it was" in caught.value.__notes__
    with staged_dir(out) as stage:
        (stage / "new.txt").write_text("new")
    assert _tree(out) == {"new.txt": "new"}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]  # nothing staged left


def test_a_swap_killed_halfway_is_put_back(tmp_path) -> None:
    """A process killed between its two renames left the previous directory aside (its
    pid gone): the next call puts it back before anything else."""
    out = tmp_path / "out"
    aside = tmp_path / ".out.999999999.previous"
    aside.mkdir()
    (aside / "run.txt").write_text("the good run")
    (tmp_path / ".out.999999999.staging").mkdir()
    with pytest.raises(ValueError), staged_dir(out):
        raise ValueError("fails at once")
    assert _tree(out) == {"run.txt": "the good run"}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def test_a_link_keeps_pointing(tmp_path) -> None:
    real = tmp_path / "real"
    real.mkdir()
    (real / "old.txt").write_text("old")
    os.symlink(real, tmp_path / "link")
    with staged_dir(tmp_path / "link") as stage:
        (stage / "new.txt").write_text("new")
    assert (tmp_path / "link").is_symlink() and _tree(tmp_path / "link") == {"new.txt": "new"}
