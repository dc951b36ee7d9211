"""Typed errors of the viz package."""

from __future__ import annotations


class VizError(RuntimeError):
    """Base class of every viz failure."""


class MeshcatServerError(VizError):
    """The meshcat server could not start (ports taken, bad host) or stopped answering."""


class BrowserUnavailable(VizError):
    """No headless Chromium/Chrome was found, so a snapshot cannot be rendered to pixels."""


class ScreenshotError(VizError):
    """The browser ran but produced no screenshot (crash, timeout)."""
