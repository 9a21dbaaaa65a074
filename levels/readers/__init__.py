"""Readers of files made outside ``levels``: the station's L0 archive (``l0``), DIMAP 1A
scenes and metadata (``scene1a``, ``dimap``, ``dimap2``), SAR frames (``sar``: the house
file; ``envisat``: ESA's format), control points (``gcp``), DEMs (``dem``), RPC files
(``rpc``), OSSIM keyword lists (``ossim``); every file from outside read within bounds
(``bounded``); ``formats``: which of them opens a path."""

from levels.readers.dimap import DimapScene, read_dimap
from levels.readers.l0 import L0Archive, L0Band, read_l0

__all__ = ["DimapScene", "L0Archive", "L0Band", "read_dimap", "read_l0"]
