"""The benchmarks' smoke mode: ``BENCH_SMOKE=1 python benchmarks/bench_X.py`` runs a
benchmark end to end on reduced sizes (the same code, the same figures printed) in seconds,
so that CI runs every one of them (``tests/test_benchmarks.py``) and none can rot. Its
figures say nothing of speed: the full sizes are the measurement.
"""

from __future__ import annotations

import os

__all__ = ["SMOKE", "size"]

#: Whether this run is a smoke run (``BENCH_SMOKE`` set to anything but ``0``).
SMOKE = os.environ.get("BENCH_SMOKE", "0") not in ("", "0")


def size(full: int, smoke: int) -> int:
    """``full``, or ``smoke`` in a smoke run."""
    return smoke if SMOKE else full
