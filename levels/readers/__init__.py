"""Readers of files made outside ``levels``: DIMAP metadata, and the station's L0 archive."""

from levels.readers.dimap import DimapScene, read_dimap
from levels.readers.l0 import L0Archive, L0Band, read_l0

__all__ = ["DimapScene", "L0Archive", "L0Band", "read_dimap", "read_l0"]
