"""The processing library's tests: ``levels`` alone, fed by outside references (pyproj,
analytic orbits, real DIMAP metadata) and the L0 archive shipped with the package; nothing
here imports ``station`` (``test_library.py`` holds them to it)."""

from __future__ import annotations

import sys
from pathlib import Path

# the shared helpers (_orbits.py) sit one level up, with the station's tests
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
