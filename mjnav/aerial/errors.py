"""Typed errors of `mjnav.aerial`: every failure subclasses `AerialError`."""

from __future__ import annotations


class AerialError(Exception):
    """Base class of every error raised by `mjnav.aerial`."""


class GimbalLockError(AerialError, ValueError):
    """ZYX Euler rates are undefined: the pitch is too close to ±90° (cos(pitch) below the tolerance)."""


class InvalidParameterError(AerialError, ValueError):
    """A parameter is out of range (negative mass, non-positive rate, wrong array shape, ...)."""


class DesignError(AerialError, ValueError):
    """A controller synthesis failed (no stabilising Riccati solution, infeasible γ, unstable result)."""


class LoopSeparationError(AerialError, ValueError):
    """An outer loop is too fast for its inner loop: its poles come within the separation factor of the inner
    loop's bandwidth."""


class StaleMeasurementError(AerialError, ValueError):
    """A delayed measurement is older than the filter's history (or newer than its current time)."""
