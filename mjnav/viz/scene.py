"""A meshcat scene held as a tree of drawing commands.

:class:`Scene` records every ``set_object`` / ``set_transform`` / ``set_property`` / ``delete`` the way the meshcat
server does (one object, one transform and the latest value of each property per path), forwards each command to an
optional *sink* (a live meshcat server, see :class:`mjnav.viz.server.MeshcatClient`), and can turn its current state
into a self-contained HTML page (:meth:`Scene.static_html`): the meshcat viewer script inlined, the commands embedded
as base64 msgpack and replayed on load, so the file opens offline in any browser with WebGL.

Paths are meshcat paths: ``"/meshcat/mjnav/robot"``, ``"/Cameras/default"``, ``"/Background"``.
"""

from __future__ import annotations

import base64
import html
import json
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path
from typing import Any

import numpy as np
import umsgpack
from meshcat.commands import Delete, SetObject, SetProperty, SetTransform
from meshcat.path import Path as MeshcatPath
from numpy.typing import ArrayLike

#: CSS colour behind the 3D view of a snapshot (the scene hides meshcat's gradient background).
PAGE_BACKGROUND = "#202226"
#: ``sink(command_type, path, packed_command)``: receives every command as it is made.
Sink = Callable[[str, str, bytes], None]


def _parts(path: str) -> tuple[str, ...]:
    parts = tuple(p for p in path.split("/") if p)
    if not parts:
        raise ValueError(f"empty meshcat path {path!r}")
    return parts


@dataclass
class _Node:
    object: bytes | None = None
    transform: bytes | None = None
    properties: dict[str, bytes] = field(default_factory=dict)


@cache
def viewer_script() -> str:
    """The meshcat viewer's JavaScript bundle (``main.min.js`` of the installed meshcat package)."""
    import meshcat

    path = Path(meshcat.__file__).parent / "viewer" / "dist" / "main.min.js"
    # "</script" inside an inline script would end it early; "<\/script" means the same to JavaScript.
    return path.read_text(encoding="utf-8").replace("</script", "<\\/script")


class Scene:
    """The scene as drawing commands, optionally mirrored to a live meshcat server.

    Not thread-safe: one thread (the viz service's loop) draws.

    Args:
        sink: receives every command as it is made (e.g. ``MeshcatClient.send``); ``None`` keeps the scene offline.
    """

    def __init__(self, sink: Sink | None = None) -> None:
        self.sink = sink
        self._nodes: dict[tuple[str, ...], _Node] = {}
        self.commands_sent = 0

    # ----------------------------------------------------------------------------------------------- drawing

    def set_object(self, path: str, obj: Any, material: Any = None) -> None:
        """Put a meshcat object at ``path`` (replacing what was there and its properties).

        Args:
            path: meshcat path, e.g. ``"/meshcat/mjnav/map"``.
            obj: a ``meshcat.geometry`` Object (Mesh, Points, Line …) or a Geometry (then ``material`` applies).
            material: material for a Geometry; ignored for Objects.
        """
        parts = _parts(path)
        cmd = SetObject(obj, material, MeshcatPath(parts)).lower()
        packed = umsgpack.packb(cmd)
        node = self._nodes.setdefault(parts, _Node())
        node.object = packed
        node.properties.clear()
        self._send("set_object", path, packed)

    def set_transform(self, path: str, matrix: ArrayLike) -> None:
        """Set the (4, 4) homogeneous transform of ``path`` relative to its parent (metres); the same transform
        again sends nothing."""
        parts = _parts(path)
        mat = np.asarray(matrix, dtype=np.float64)
        if mat.shape != (4, 4) or not np.all(np.isfinite(mat)):
            raise ValueError(f"transform of {path} must be a finite (4, 4) matrix, got shape {mat.shape}")
        packed = umsgpack.packb(SetTransform(mat, MeshcatPath(parts)).lower())
        node = self._nodes.setdefault(parts, _Node())
        if node.transform == packed:
            return  # unchanged (a robot standing still): nothing to send
        node.transform = packed
        self._send("set_transform", path, packed)

    def set_property(self, path: str, name: str, value: Any) -> None:
        """Set property ``name`` (``visible``, ``position``, ``top_color`` …) of the object at ``path``."""
        parts = _parts(path)
        packed = umsgpack.packb(SetProperty(name, value, MeshcatPath(parts)).lower())
        self._nodes.setdefault(parts, _Node()).properties[name] = packed
        self._send("set_property", path, packed)

    def delete(self, path: str) -> None:
        """Remove ``path`` and everything below it."""
        parts = _parts(path)
        for key in [k for k in self._nodes if k[: len(parts)] == parts]:
            del self._nodes[key]
        self._send("delete", path, umsgpack.packb(Delete(MeshcatPath(parts)).lower()))

    def _send(self, kind: str, path: str, packed: bytes) -> None:
        if self.sink is not None:
            self.sink(kind, "/" + "/".join(_parts(path)), packed)
            self.commands_sent += 1

    # ----------------------------------------------------------------------------------------------- state

    def paths(self) -> list[str]:
        """Every path that holds an object, a transform or a property, in drawing order."""
        return ["/" + "/".join(k) for k in self._nodes]

    def has_object(self, path: str) -> bool:
        """Whether an object is drawn at ``path``."""
        node = self._nodes.get(_parts(path))
        return node is not None and node.object is not None

    def _packed(self) -> Iterator[tuple[str, str, bytes]]:
        for parts, node in self._nodes.items():
            path = "/" + "/".join(parts)
            if node.object is not None:
                yield "set_object", path, node.object
            for packed in node.properties.values():
                yield "set_property", path, packed
            if node.transform is not None:
                yield "set_transform", path, node.transform

    def commands(self) -> list[bytes]:
        """The msgpack-packed commands that rebuild the current scene from an empty viewer, in order."""
        return [packed for _, _, packed in self._packed()]

    def replay(self, sink: Sink) -> int:
        """Send the whole current scene to ``sink`` (e.g. a server that restarted); returns the command count."""
        count = 0
        for kind, path, packed in self._packed():
            sink(kind, path, packed)
            count += 1
        return count

    # ----------------------------------------------------------------------------------------------- snapshot

    def static_html(self, title: str = "mjnav") -> str:
        """A self-contained HTML page showing the current scene (viewer script and data inlined, no network)."""
        encoded = json.dumps([base64.b64encode(c).decode("ascii") for c in self.commands()])
        return _PAGE.format(
            title=html.escape(title), script=viewer_script(), commands=encoded, background=PAGE_BACKGROUND
        )

    def write_static_html(self, path: str | Path, title: str = "mjnav") -> Path:
        """Write :meth:`static_html` to ``path`` atomically (a reader never sees half a file); returns the path."""
        out = Path(path)
        out.parent.mkdir(parents=True, exist_ok=True)
        tmp = out.with_name(out.name + ".tmp")
        tmp.write_text(self.static_html(title), encoding="utf-8")
        tmp.replace(out)
        return out


_PAGE = """<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<title>{title}</title>
<style>
html, body {{ margin: 0; height: 100%; overflow: hidden; background: {background}; }}
#meshcat-pane {{ width: 100vw; height: 100vh; overflow: hidden; }}
</style>
</head>
<body>
<div id="meshcat-pane"></div>
<script>
{script}
</script>
<script>
(function () {{
  const viewer = new MeshCat.Viewer(document.getElementById("meshcat-pane"));
  const commands = {commands};
  for (const text of commands) {{
    const raw = atob(text);
    const bytes = new Uint8Array(raw.length);
    for (let i = 0; i < raw.length; i++) {{ bytes[i] = raw.charCodeAt(i); }}
    viewer.handle_command_bytearray(bytes);
  }}
  window.viewer = viewer;
  window.mjnavCommands = commands.length;
}})();
</script>
</body>
</html>
"""
