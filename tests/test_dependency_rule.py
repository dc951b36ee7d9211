"""DESIGN.md's dependency rule: the pure packages import in a process where the I/O layers cannot be imported."""

from __future__ import annotations

import ast
import re
import subprocess
import sys
from pathlib import Path

import pytest

from tests.conftest import REPO

PURE = ["geometry", "motion", "mapping", "planning", "smoothing", "control", "estimation", "aerial", "robot"]
BLOCKED = ["zenoh", "mujoco", "meshcat", "rosbags"] + [
    f"mjnav.{m}" for m in ("msgs", "bus", "runtime", "services", "sim", "viz", "bag", "commands", "cli")
]

# Imports the package and every submodule with a finder that refuses the blocked modules.
PROBE = """
import importlib, importlib.abc, pkgutil, sys
BLOCKED = {blocked!r}

class Block(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path=None, target=None):
        if any(name == b or name.startswith(b + ".") for b in BLOCKED):
            raise ImportError(f"pure package imported blocked module {{name}}")
        return None

sys.meta_path.insert(0, Block())
mod = importlib.import_module("mjnav.{name}")
if hasattr(mod, "__path__"):
    for info in pkgutil.walk_packages(mod.__path__, prefix="mjnav.{name}."):
        importlib.import_module(info.name)
"""


def _existing() -> list[str]:
    return [n for n in PURE if (REPO / "mjnav" / n).is_dir() or (REPO / "mjnav" / f"{n}.py").is_file()]


@pytest.mark.e2e
@pytest.mark.parametrize("name", _existing())
def test_pure_package_imports_without_io_layers(name: str) -> None:
    code = PROBE.format(blocked=BLOCKED, name=name)
    proc = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]


def test_the_probe_catches_a_violation() -> None:
    """The check itself can fail: importing an I/O layer under the same finder is refused."""
    code = PROBE.format(blocked=BLOCKED, name="bus")
    proc = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, timeout=300)
    assert proc.returncode != 0 and "blocked module" in proc.stderr


# ------------------------------------------------------------------------------------------ the allow-list

#: What each pure package may import besides the standard library and itself (top-level third-party modules and
#: mjnav packages), as DESIGN.md and docs/architecture.md's package table say.
ALLOWED: dict[str, set[str]] = {
    "geometry": {"numpy"},
    "robot": {"numpy", "mjnav.geometry"},
    "motion": {"numpy", "numba", "mjnav.geometry"},
    "mapping": {"numpy", "scipy", "numba", "mjnav.geometry"},
    "planning": {"numpy", "scipy", "numba", "mjnav.geometry", "mjnav.mapping"},
    "smoothing": {"numpy", "scipy", "numba", "osqp", "casadi", "mjnav.geometry"},
    "control": {"numpy", "scipy", "numba", "mjnav.geometry", "mjnav.smoothing"},
    "estimation": {"numpy", "scipy", "numba", "sksparse", "mjnav.geometry", "mjnav.motion", "mjnav.mapping"},
    "aerial": {"numpy", "scipy", "numba"},
}
#: Single modules allowed one more import, each for a reason: file formats live at their package's edge, and a numba
#: intrinsic is written in numba's own IR layer.
ALLOWED_IN_MODULE: dict[str, set[str]] = {
    # the ROS map file reader (YAML + an image: PNG, BMP, JPEG, ... through Pillow), the mapping package's edge
    "mjnav.mapping.ros_map": {"yaml", "PIL"},
    "mjnav.planning._kernels": {"llvmlite"},  # an @intrinsic (unsigned heap index) builds LLVM IR
}
#: Layers above the algorithms that must not reach up: the runtime runs services, it never imports the command
#: line (the launcher's forked processes used to run mjnav.cli, which imports the commands, which import the runtime).
FORBIDDEN_FOR_LAYER: dict[str, set[str]] = {
    "runtime": {"mjnav.cli", "mjnav.commands", "mjnav.services"},
    "bus": {"mjnav.runtime", "mjnav.services", "mjnav.commands", "mjnav.cli"},
    "msgs": {"mjnav.bus", "mjnav.runtime", "mjnav.services", "mjnav.commands", "mjnav.cli"},
    "sim": {"zenoh", "mjnav.bus", "mjnav.services", "mjnav.commands", "mjnav.cli"},
}


def imports_in(path: Path) -> set[str]:
    """What the module at ``path`` imports (top-level modules; ``mjnav.<pkg>`` for the project), read from the
    source, so imports inside functions count too."""
    names: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            targets = [node.module]
        else:
            continue
        for name in targets:
            parts = name.split(".")
            names.add(".".join(parts[:2]) if parts[0] == "mjnav" and len(parts) > 1 else parts[0])
    return names


def imports_of(package: str) -> dict[str, set[str]]:
    """Every module of ``mjnav.<package>`` → what it imports (:func:`imports_in`)."""
    root = REPO / "mjnav"
    files = [root / f"{package}.py"] if (root / f"{package}.py").is_file() else sorted((root / package).rglob("*.py"))
    return {".".join(p.relative_to(REPO).with_suffix("").parts).removesuffix(".__init__"): imports_in(p) for p in files}


def _outside(package: str, names: set[str]) -> set[str]:
    std = set(sys.stdlib_module_names) | {"__future__"}
    return {n for n in names if n not in std and n != f"mjnav.{package}"}


@pytest.mark.parametrize("name", sorted(ALLOWED))
def test_a_pure_package_imports_only_what_it_is_allowed(name: str) -> None:
    bad = {
        module: sorted(_outside(name, names) - ALLOWED[name] - ALLOWED_IN_MODULE.get(module, set()))
        for module, names in imports_of(name).items()
    }
    assert not {m: b for m, b in bad.items() if b}, "imports outside the allow-list (DESIGN.md's dependency rule)"


def test_every_pure_package_has_an_allow_list() -> None:
    assert set(ALLOWED) == set(_existing())


@pytest.mark.parametrize("name", sorted(FORBIDDEN_FOR_LAYER))
def test_a_layer_does_not_import_the_layers_above_it(name: str) -> None:
    bad = {m: sorted(names & FORBIDDEN_FOR_LAYER[name]) for m, names in imports_of(name).items()}
    assert not {m: b for m, b in bad.items() if b}


def test_one_transport_only_the_bus_drives_zenoh() -> None:
    """Relays, recorders, tools and the launcher reach Zenoh through mjnav.bus (its config, QoS, thread handling and
    clean-up), never through a session of their own."""
    files = [p for p in (REPO / "mjnav").rglob("*.py") if p.relative_to(REPO / "mjnav").parts[0] != "bus"]
    assert [str(p.relative_to(REPO)) for p in files if "zenoh" in imports_in(p)] == []
    session = re.compile(r"\.session\b")
    raw = [
        f"{p.relative_to(REPO)}:{i}"
        for p in files
        for i, line in enumerate(p.read_text(encoding="utf-8").splitlines(), 1)
        if session.search(line)
    ]
    assert raw == []


def test_the_reader_sees_an_import_inside_a_function(tmp_path: Path) -> None:
    """A lazy import (inside a function) is still an import."""
    module = tmp_path / "lazy.py"
    module.write_text("import numpy as np\n\ndef f():\n    import yaml\n    from mjnav.bus.config import X\n")
    assert imports_in(module) == {"numpy", "yaml", "mjnav.bus"}
