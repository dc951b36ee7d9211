"""Typed errors of the control algorithms."""

from __future__ import annotations

from mjnav.smoothing.errors import PathError


class ControlDesignError(ValueError):
    """A controller cannot be designed from the given model (bad shapes, not stabilisable, ...)."""


class MonitorInputError(ValueError):
    """Input the collision monitor cannot check: a non-finite command, points that are not an (N, 2) array,
    velocities that are not the points' (N, 2) or not finite where the points are, a zone polygon that is not
    convex and counter-clockwise, a zone that is not well formed."""


__all__ = ["ControlDesignError", "MonitorInputError", "PathError"]
