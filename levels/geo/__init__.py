"""GEO: the geometric parameters of every scene of a pass (INPE paper ``004_…`` §§2.1, 3).

Numerical only, no file I/O: :mod:`~levels.geo.scenes` (pass set-up, scene cutting,
centre and corners), :mod:`~levels.geo.level1b` (tangent plane, polynomials f, g, h),
:mod:`~levels.geo.level2a` (direct grid, inverse polynomials and grid, map grid).
"""

from levels.geo.level1b import Level1BGeometry, TangentPlane, level1b_geometry
from levels.geo.level2a import INVERSE_METHODS, Level2AGeometry, level2a_geometry, map_crs
from levels.geo.polynomial import Poly1D, Poly2D
from levels.geo.scenes import PassGeometry, SceneCut, SceneGeometry, cut_scenes, pass_geometry

__all__ = [
    "INVERSE_METHODS",
    "Level1BGeometry",
    "Level2AGeometry",
    "PassGeometry",
    "Poly1D",
    "Poly2D",
    "SceneCut",
    "SceneGeometry",
    "TangentPlane",
    "cut_scenes",
    "level1b_geometry",
    "level2a_geometry",
    "map_crs",
    "pass_geometry",
]
