"""The receiver's error: a stream with no usable pass in it."""

from __future__ import annotations

from station.errors import StationError

__all__ = ["ReceiverError"]


class ReceiverError(StationError, ValueError):
    """The stream holds no usable pass (no frame, or no auxiliary data to place lines)."""
