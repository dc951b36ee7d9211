"""Typed errors of the bag package."""

from __future__ import annotations


class BagError(RuntimeError):
    """A bag cannot be recorded or played (bad key expression, unwritable file, …)."""


class BagFormatError(BagError):
    """The file is not an MCAP file mjnav can read (not MCAP, truncated header, no ROS 2 channels)."""
