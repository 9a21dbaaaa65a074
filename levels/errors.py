"""Exceptions of the ``levels`` package.

One root, :class:`LevelsError`; each subclass also inherits the builtin a caller would
expect (the rasterio habit), so ``except ValueError`` still works.
"""

__all__ = [
    "AdjustmentError",
    "DemError",
    "DimapError",
    "GcpError",
    "GeometryError",
    "L0Error",
    "LevelsError",
    "OptionsError",
    "ProductError",
]


class LevelsError(Exception):
    """Root of every error raised by ``levels``."""


class GeometryError(LevelsError, ValueError):
    """A geometric model was built from inconsistent or out-of-range inputs."""


class AdjustmentError(GeometryError):
    """Level 2's fit cannot be trusted: its control points are out of the model's reach or
    fail the χ² test of the fit (``levels.adjust``); no product is made of it."""


class FitRefused(AdjustmentError):
    """Level 2's fit fails its χ² test: the points do not fit the model within their σ.
    ``sigma0`` is the fit's a posteriori σ0 (its a priori: 1)."""

    def __init__(self, message: str, sigma0: float) -> None:
        super().__init__(message)
        self.sigma0 = sigma0


class DimapError(LevelsError, ValueError):
    """A DIMAP metadata file is not DIMAP, lacks a needed element, or is inconsistent."""


class L0Error(LevelsError, ValueError):
    """An L0 pass archive that is missing, truncated, of another format, or inconsistent."""


class ProductError(LevelsError, ValueError):
    """A level product file that is missing, truncated, of another format, or inconsistent."""


class OptionsError(LevelsError, ValueError):
    """Processing options (a ``[processing]`` table) that cannot be used as given."""


class GcpError(LevelsError, ValueError):
    """A control-point file that is missing, malformed, or inconsistent with its image."""


class DemError(LevelsError, ValueError):
    """A DEM that cannot be read or used as declared."""
