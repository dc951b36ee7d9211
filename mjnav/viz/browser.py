"""Render an HTML snapshot to pixels with headless Chromium (software WebGL, no display, no GPU).

Used by the browser check of the snapshot and handy for thumbnails. Debian's ``chromium`` package is looked for
first (``$MJNAV_CHROMIUM`` overrides); rendering uses SwiftShader so it works in containers and CI.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import tempfile
from pathlib import Path

from mjnav.viz.errors import BrowserUnavailable, ScreenshotError

#: Executables tried in order (after ``$MJNAV_CHROMIUM``).
CANDIDATES = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable", "chrome")


def find_chromium() -> str:
    """Path of a Chromium/Chrome executable.

    Raises:
        BrowserUnavailable: none found (the message says how to install one).
    """
    env = os.environ.get("MJNAV_CHROMIUM")
    if env:
        found = shutil.which(env)
        if found:
            return found
        raise BrowserUnavailable(f"MJNAV_CHROMIUM={env!r} is not an executable")
    for name in CANDIDATES:
        found = shutil.which(name)
        if found:
            return found
    raise BrowserUnavailable("no headless browser found: install Debian's chromium (apt-get install chromium)")


def screenshot(
    html_file: str | Path,
    png_file: str | Path,
    *,
    width_px: int = 800,
    height_px: int = 600,
    budget_ms: int = 5000,
    timeout_s: float = 60.0,
) -> Path:
    """Open ``html_file`` in headless Chromium and save a ``width_px × height_px`` PNG of the page.

    Args:
        budget_ms: virtual time the page gets to load and render before the capture (scripts, textures).
        timeout_s: wall-clock limit for the browser process.

    Raises:
        BrowserUnavailable: no Chromium found.
        ScreenshotError: the browser failed or wrote no image (its output is in the message).
    """
    browser = find_chromium()
    html = Path(html_file).resolve()
    out = Path(png_file).resolve()
    if not html.is_file():
        raise FileNotFoundError(html)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.unlink(missing_ok=True)
    with tempfile.TemporaryDirectory(prefix="mjnav-chromium-") as profile:
        cmd = [
            browser,
            "--headless",
            "--no-sandbox",  # containers run as root without user namespaces
            "--disable-gpu-sandbox",
            "--use-angle=swiftshader",
            "--enable-unsafe-swiftshader",
            "--no-first-run",
            "--no-default-browser-check",
            "--hide-scrollbars",
            f"--user-data-dir={profile}",
            f"--window-size={width_px},{height_px}",
            f"--virtual-time-budget={budget_ms}",
            f"--screenshot={out}",
            html.as_uri(),
        ]
        try:
            proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout_s, check=False)
        except subprocess.TimeoutExpired as exc:
            raise ScreenshotError(f"{browser} did not finish within {timeout_s} s") from exc
    if proc.returncode != 0 or not out.is_file():
        tail = (proc.stderr or proc.stdout)[-1500:]
        raise ScreenshotError(f"{browser} exited with code {proc.returncode} and no screenshot:\n{tail}")
    return out
