"""Processing library of the SPOT ground segment: geometry, GEO and COR functions, products.

``levels`` runs on real data without the emulator: it never imports ``station``. What it
holds, from the ground floor up:

- ``geometry``: time, frames, ellipsoid, ephemeris, attitude, look angles, the
  collinearity model, DEM sampling;
- ``geo``, ``passes``: GEO (the pass set-up and its scenes, 1B polynomials, 2A grids and
  their inverse, level 3 anchors, RPCs, map grids); ``cor``: COR (calibration,
  deconvolution, resampling);
- ``adjust``, ``tiepoints``, ``reference``, ``stereo``, ``sar``: control points and blocks,
  tie points, control points on a reference, dense matching and triangulation, SAR
  geocoding;
- ``kinds``, ``registry``, ``makers``: every product kind declared once and its maker;
- ``work``: one unit of work (a request, its plan of nodes, one result); ``process``,
  ``frame``, ``tasks``: its stages and where their tasks run;
- ``product``, ``products``, ``export``, ``inspect``, ``quicklook``, ``compare``: a product
  in memory, its format and what reads it; ``readers``, ``writers``: the formats in and
  out (``readers.formats``: which reader opens a path);
- ``api``: the public face, everything above a user of the library alone needs.
"""

__all__ = ["__version__"]

__version__ = "0.1.0"
