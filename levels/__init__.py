"""Processing library of the SPOT ground segment: geometry, GEO and COR functions, products.

``levels`` runs on real data without the emulator: it never imports ``station``.
"""

__all__ = ["__version__"]

__version__ = "0.1.0"
