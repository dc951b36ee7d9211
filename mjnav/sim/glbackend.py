"""Pick a headless OpenGL backend for offscreen rendering (EGL, then OSMesa) without importing MuJoCo.

MuJoCo's Python package reads ``MUJOCO_GL`` when it is first imported and PyOpenGL fixes its platform when
*it* is first imported, so a failed in-process attempt at EGL would poison a later OSMesa attempt. The probe
therefore runs in a short-lived child process (about half a second, once per process); the result is stored
in ``os.environ["MUJOCO_GL"]`` so later calls and child processes skip probing. An explicit ``MUJOCO_GL`` set
by the user is trusted as is.

:class:`~mjnav.sim.recording.Recorder` creates its OpenGL context from the chosen backend module directly
(``mujoco.egl`` / ``mujoco.osmesa``), so it works even when ``mujoco`` was imported before this ran.
"""

from __future__ import annotations

import ctypes.util
import os
import subprocess
import sys

from mjnav.sim.errors import RenderBackendUnavailableError

#: Backends tried in order, with the Debian packages each needs.
BACKENDS: dict[str, str] = {"egl": "libegl1 libegl-mesa0", "osmesa": "libosmesa6"}
#: Shared library (as ``ctypes.util.find_library`` names it) → Debian package providing it.
_LIBRARIES: dict[str, str] = {"EGL": "libegl1", "EGL_mesa": "libegl-mesa0", "OSMesa": "libosmesa6"}

_VERIFIED: set[str] = set()

_PROBE = """
import os, sys
os.environ["MUJOCO_GL"] = sys.argv[1]
if sys.argv[1] == "egl":
    from mujoco.egl import GLContext
elif sys.argv[1] == "osmesa":
    from mujoco.osmesa import GLContext
else:
    from mujoco.glfw import GLContext
import mujoco
ctx = GLContext(16, 16)
ctx.make_current()
model = mujoco.MjModel.from_xml_string("<mujoco/>")
mujoco.MjrContext(model, mujoco.mjtFontScale.mjFONTSCALE_100).free()
ctx.free()
"""


def missing_packages() -> list[str]:
    """Debian packages of the EGL/OSMesa libraries the dynamic loader cannot find (e.g. ``["libosmesa6"]``)."""
    return [pkg for lib, pkg in _LIBRARIES.items() if ctypes.util.find_library(lib) is None]


def probe_backend(name: str, timeout_s: float = 60.0) -> str | None:
    """Try to create a 16×16 OpenGL context and a MuJoCo render context with backend ``name`` in a child process.

    Args:
        name: ``"egl"``, ``"osmesa"`` or ``"glfw"``.
        timeout_s: give up after this many seconds.

    Returns:
        ``None`` when it works, else the last line of the child's error output.
    """
    env = {k: v for k, v in os.environ.items() if k not in ("MUJOCO_GL", "PYOPENGL_PLATFORM")}
    try:
        proc = subprocess.run(
            [sys.executable, "-c", _PROBE, name],
            capture_output=True,
            text=True,
            timeout=timeout_s,
            env=env,
            check=False,
        )
    except (OSError, subprocess.TimeoutExpired) as exc:
        return f"{type(exc).__name__}: {exc}"
    if proc.returncode == 0:
        return None
    lines = [ln for ln in proc.stderr.strip().splitlines() if ln.strip()]
    return lines[-1] if lines else f"exit code {proc.returncode}"


def select_gl_backend() -> str:
    """Return a working offscreen backend name and export it as ``MUJOCO_GL``.

    An explicit ``MUJOCO_GL`` (``egl``, ``osmesa`` or ``glfw``) is the only one tried (and checked once per
    process, since a broken one even breaks ``import mujoco``); otherwise EGL, then OSMesa are probed.

    Raises:
        RenderBackendUnavailableError: neither works (or ``MUJOCO_GL`` names something else); the message
            names the Debian packages to install and each backend's error.
    """
    explicit = os.environ.get("MUJOCO_GL", "").strip().lower()
    if explicit:
        if explicit not in ("egl", "osmesa", "glfw"):
            raise RenderBackendUnavailableError(
                f"MUJOCO_GL={explicit!r} cannot render offscreen here; unset it or use egl or osmesa"
            )
        if explicit in _VERIFIED:
            return explicit
        err = probe_backend(explicit)
        if err is not None:
            hint = BACKENDS.get(explicit)
            install = f"apt-get install {hint}, or " if hint else ""
            raise RenderBackendUnavailableError(
                f"MUJOCO_GL={explicit} does not work here ({err}); {install}unset MUJOCO_GL to pick "
                "egl or osmesa automatically"
            )
        _VERIFIED.add(explicit)
        return explicit
    errors: dict[str, str] = {}
    for name in BACKENDS:
        err = probe_backend(name)
        if err is None:
            os.environ["MUJOCO_GL"] = name
            _VERIFIED.add(name)
            return name
        errors[name] = err
    detail = "; ".join(f"{name}: {err}" for name, err in errors.items())
    missing = missing_packages()
    options = " or ".join(f"{name} (apt-get install {pkgs})" for name, pkgs in BACKENDS.items())
    lacking = f"Missing here: {', '.join(missing)}. " if missing else ""
    raise RenderBackendUnavailableError(
        f"no headless OpenGL backend works, so nothing can be rendered. {lacking}Install {options}, "
        f"or set MUJOCO_GL. Errors: {detail}"
    )
