"""SAR geocoding by range–Doppler (ADRIN, paper ``001_…`` §5): a detected slant-range image
and its annotation onto a map, on the ellipsoid (GEC) or over a DEM (GTC).

The package, by stage (as sarsen splits orbit, geocoding, radiometry):
:mod:`~levels.sar.annotation` (the range–Doppler model of a frame), :mod:`~levels.sar.geocoding`
(GEC and GTC), :mod:`~levels.sar.masks` (layover and shadow), :mod:`~levels.sar.radiometry` (γ⁰).

**Pixel location** (ground → image). A ground point ``p`` (ECEF, fixed on the Earth) is
imaged on the line whose time ``t`` solves the Doppler equation

    Fdc − 2 (p − s)·(ṗ − ṡ) / (λ |p − s|) = 0,        ṗ = 0 in the Earth-fixed frame,

(``s``, ``ṡ`` the satellite's position and Earth-fixed velocity from the annotation's state
vectors, 8-point Lagrange; ``Fdc`` the Doppler centroid the image was focused to, a
polynomial in slant range; ``λ`` the wavelength), and on the column ``j`` of the range
equation ``r0 + mr·j − |p − s(t)| = 0`` (``r0`` the near range, ``mr`` the range spacing).
The time is found by Newton's method (the derivative with the acceleration from the
velocity's difference over 1 ms), from the frame's middle: converged to 1e-10 s (a
millionth of a line) in four to five steps.

**Image location** (image → ground, for footprints): the point at slant range ``R`` on the
Doppler cone of line ``t``, at a given height: its look angle about the velocity found by
Newton's method on the geodetic height.

**Geocoding** (the indirect method, as level 3): an output map grid; at anchors every
``ANCHOR_STEP_PX`` output pixels and at ``HEIGHT_LEVELS`` heights spanning the terrain
(one, the reference height, for GEC), the exact (line, column) of the map point; per
output pixel its height (GEC: the reference; GTC: the DEM bilinearly in its own grid,
:mod:`levels.geo.level3`'s sampling), the anchors bilinearly, the levels by Lagrange in
height (as a polynomial), and the slant image bilinearly there. The anchor grid's error
against the exact location is measured on a lattice between the anchors and returned.

**Layover and shadow** over a DEM (the standard definitions, Kropatsch & Strobl 1990): the
terrain's zero-Doppler profiles sampled along the image's lines (:mod:`levels.sar.masks`),
each output pixel judged against them inside the geocoding kernel; the truth's own, on
continuous profiles of the world's terrain, is the emulator's
(:mod:`station.spacecraft.sar_masks`).

The package's face holds the frame's model alone (:mod:`~levels.sar.annotation`, a primitive
the emulator and the readers share): importing it loads no processing stage; the stages are
imported from their own modules (``from levels.sar.geocoding import geocode``).
"""

from levels.sar.annotation import (
    ANCHOR_STEP_PX,
    HEIGHT_LEVELS,
    MASK_TOLERANCE_PX,
    SPEED_OF_LIGHT_M_PER_S,
    SarAnnotation,
    SarImage,
    frame_grid,
    line_spacing_m,
    nominal_cell_m2,
)

__all__ = [
    "ANCHOR_STEP_PX",
    "HEIGHT_LEVELS",
    "MASK_TOLERANCE_PX",
    "SPEED_OF_LIGHT_M_PER_S",
    "SarAnnotation",
    "SarImage",
    "frame_grid",
    "line_spacing_m",
    "nominal_cell_m2",
]
