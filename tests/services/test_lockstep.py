"""Lockstep: the same seed gives the same mission to the last bit, on an idle machine and beside CPU hogs."""

from __future__ import annotations

import json
import subprocess
import sys
from typing import Any

from tests.conftest import free_port
from tests.services.test_navigation import _mjnav

#: Figures that depend on the machine (wall time), not on the mission.
WALL_KEYS = {"wall_s", "achieved_rtf"}


def _demo(seed: int) -> dict[str, Any]:
    proc = _mjnav(
        "demo", "--world", "rooms", "--rtf", "max", "--seed", str(seed), "--json", "--headless",
        "--port", str(free_port()),
    )  # fmt: skip
    stdout, _ = proc.communicate(timeout=600)
    assert proc.returncode == 0, stdout[-3000:]
    summary: dict[str, Any] = json.loads(stdout.strip().splitlines()[-1])
    return summary


def test_same_seed_same_mission_whatever_the_load() -> None:
    idle = _demo(seed=3)
    hogs = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(2)]
    try:
        busy = _demo(seed=3)
    finally:
        for hog in hogs:
            hog.kill()
            hog.wait()
    assert idle["lockstep"] is True and idle["seed"] == 3 and idle["reached"] is True and idle["collisions"] == 0
    assert {k: v for k, v in busy.items() if k not in WALL_KEYS} == {
        k: v for k, v in idle.items() if k not in WALL_KEYS
    }
    # Bit for bit: the unrounded figures of the goal and the final pose, not only the rounded summary.
    assert busy["goals"] == idle["goals"] and busy["final_pose"] == idle["final_pose"]
    assert len(idle["final_pose"]) == 3 and idle["time_s"] > 0 and idle["achieved_rtf"] > 0
