"""Exceptions of the station package: one root, subclasses that are also builtins."""

from __future__ import annotations

__all__ = ["OrbitError", "ScenarioError", "StationError"]


class StationError(Exception):
    """Root of every error the station raises on bad input."""


class ScenarioError(StationError, ValueError):
    """A scenario file or table that cannot be used as given."""


class OrbitError(StationError, ValueError):
    """An orbit that cannot be set up as asked (no solution, a bad TLE)."""
