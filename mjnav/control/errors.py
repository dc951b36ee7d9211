"""Typed errors of the control algorithms."""

from __future__ import annotations

from mjnav.smoothing.errors import PathError


class ControlDesignError(ValueError):
    """A controller cannot be designed from the given model (bad shapes, not stabilisable, ...)."""


__all__ = ["ControlDesignError", "PathError"]
