"""What the command-line tests check alike: one line on stderr with the documented exit
code, and a directory's files byte for byte."""

from __future__ import annotations

import signal
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

#: What "a second" means against a hang: a refusal reads a header, not the file; 30 s is
#: 30× that, and far below the minutes a loop over a forged count takes.
HANG_S = 30


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


@contextmanager
def bounded(seconds: int = HANG_S) -> Iterator[None]:
    """Fail the block (TimeoutError) when it runs longer than ``seconds``: a hang caught as
    a failure, not a CI run that never ends."""

    def _alarm(signum, frame):
        raise TimeoutError(f"still running after {seconds} s: a hang")

    old = signal.signal(signal.SIGALRM, _alarm)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)
