"""DESIGN.md's dependency rule: the pure packages import in a process where the I/O layers cannot be imported."""

from __future__ import annotations

import subprocess
import sys

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
