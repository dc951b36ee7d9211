"""Typed errors raised by :mod:`mjnav.sim`."""

from __future__ import annotations


class SimError(RuntimeError):
    """Base class of every error raised by :mod:`mjnav.sim`."""


class UnknownWorldError(SimError, LookupError):
    """A world name is neither a bundled scene nor an existing MJCF file.

    Attributes:
        world: the name or path that was asked for.
        available: names of the bundled worlds.
    """

    def __init__(self, world: str, available: tuple[str, ...]) -> None:
        self.world = world
        self.available = available
        super().__init__(
            f"unknown world {world!r}: not a bundled world ({', '.join(available) or 'none found'}) "
            "and not an existing MJCF file"
        )


class ModelLoadError(SimError):
    """An MJCF file does not parse or compile; the message carries MuJoCo's own error text."""


class RobotNotFoundError(SimError):
    """The model has no mjnav robot: no body named ``*base_link`` with a free joint, or a part is missing."""


class InvalidCommandError(SimError, ValueError):
    """A velocity command or a simulation argument is not finite or out of its domain."""


class RenderBackendUnavailableError(SimError):
    """Neither EGL nor OSMesa offscreen OpenGL works; the message names the Debian packages to install."""


class RecordingError(SimError):
    """Rendering or video encoding failed (bad camera, size beyond the framebuffer, ffmpeg error)."""


class MapConversionError(SimError, ValueError):
    """An occupancy map cannot be read or converted into a world."""
