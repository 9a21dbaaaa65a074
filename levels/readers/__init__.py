"""Readers of metadata and data files made outside this project (DIMAP, DEM formats)."""

from levels.readers.dimap import DimapScene, read_dimap

__all__ = ["DimapScene", "read_dimap"]
