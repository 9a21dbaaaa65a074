"""What the command-line tests check alike: one line on stderr with the documented exit
code, and a directory's files byte for byte."""

from __future__ import annotations

from pathlib import Path


def one_line(capsys, code: int, expected: int, *words: str) -> str:
    """The one stderr line of a command that exited ``expected`` (the "running …" banner
    aside), holding each of ``words``, never a traceback."""
    err = capsys.readouterr().err
    assert code == expected, err
    lines = [ln for ln in err.splitlines() if not ln.startswith("running ")]
    assert len(lines) == 1 and "Traceback" not in err, err
    for w in words:
        assert w in lines[0], lines[0]
    return lines[0]


def tree(d: Path) -> dict[str, bytes]:
    """Every file under ``d`` and its bytes."""
    return {str(p.relative_to(d)): p.read_bytes() for p in sorted(d.rglob("*")) if p.is_file()}
