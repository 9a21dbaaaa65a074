"""The truth: what the emulated world, satellite and instrument really were, and each
product held to it. Optical passes (:mod:`~station.truth.optical`: where each raw pixel
truly looks and what it sees, checkpoints of every level, true tie points), stereo pairs
(:mod:`~station.truth.stereo`: the exact disparity, the DEM against the terrain,
PHOTOMOD's checkpoints) and SAR frames (:mod:`~station.truth.sar`: checkpoints, relief
displacement, masks, γ⁰). Only the station imports it; ``levels`` never sees it.
"""

from station.truth.optical import Truth, truth_for

__all__ = ["Truth", "truth_for"]
