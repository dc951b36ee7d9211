"""Lockstep: the same seed gives the same mission to the last bit, on an idle machine and beside CPU hogs, whether
the services share processes (the stack's containers) or run one per process."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from typing import Any

import pytest

from mjnav.bus import Bus, BusConfig, wait_until
from mjnav.msgs import ros
from tests.conftest import free_port
from tests.services.test_navigation import _mjnav, up_process

pytestmark = pytest.mark.e2e  # processes or a live stack: see pyproject's markers

#: Figures that depend on the machine (wall time), not on the mission.
WALL_KEYS = {"wall_s", "achieved_rtf"}


def _demo(seed: int, *extra: str) -> dict[str, Any]:
    proc = _mjnav(
        "demo", "--world", "rooms", "--rtf", "max", "--seed", str(seed), "--json", "--headless",
        "--port", str(free_port()), *extra,
    )  # fmt: skip
    stdout, _ = proc.communicate(timeout=600)
    # On failure: the demo's own lines (goal outcomes, errors) wherever they are, then the end of the log.
    own = "\n".join(line for line in stdout.splitlines() if line.startswith(("mjnav demo", "Traceback", "{")))
    assert proc.returncode == 0, f"{own[-3000:]}\n...\n{stdout[-2000:]}"
    summary: dict[str, Any] = json.loads(stdout.strip().splitlines()[-1])
    return summary


def test_same_seed_same_mission_whatever_the_packing_and_the_load() -> None:
    """Composed (the stack file's containers) on an idle machine, then one service per process beside two busy
    loops: the same mission to the last bit."""
    idle = _demo(3)
    hogs = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(2)]
    try:
        busy = _demo(3, "--process-per-service")
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
    assert busy["time_s"] == idle["time_s"] and busy["path_length_m"] == idle["path_length_m"]
    assert len(idle["final_pose"]) == 3 and idle["time_s"] > 0 and idle["achieved_rtf"] > 0


def test_a_stalled_or_killed_participant_never_hangs_sim_time() -> None:
    """SIGSTOP a service: after lockstep_timeout_s the sim names it and goes on; SIGCONT: it rejoins. SIGKILL it:
    the sim goes on at once; the launcher restarts it and it joins again."""
    sets = ("sim.world=empty", "sim.rtf=0", "sim.lockstep_timeout_s=1.0")
    with (
        # --hung-timeout: the launcher must not replace the stopped smoother; this is the barrier's test.
        up_process(
            "--only", "sim,smoother", "--hung-timeout", "600", *(x for item in sets for x in ("--set", item))
        ) as (port, _, lines),
        Bus.open(BusConfig(mode="client", connect=(f"tcp/127.0.0.1:{port}",))) as bus,
    ):
        clock = bus.subscribe("clock")
        status = bus.subscribe("status", service="smoother")
        first = status.wait(60.0)
        assert first is not None, "".join(lines)[-2000:]

        def sim_time_passes(after: float) -> bool:
            return clock.wait(30.0, lambda c: ros.seconds(c.clock) > after + 5.0) is not None

        os.kill(first.pid, signal.SIGSTOP)
        try:
            assert wait_until(lambda: any("smoother has not finished its step" in x for x in lines), 30.0)
            assert sim_time_passes(ros.seconds(clock.latest().clock))
        finally:
            os.kill(first.pid, signal.SIGCONT)
        assert wait_until(lambda: any("smoother reports again and rejoins" in x for x in lines), 30.0)
        os.kill(first.pid, signal.SIGKILL)
        assert wait_until(lambda: any("smoother left" in x for x in lines), 30.0)
        assert sim_time_passes(ros.seconds(clock.latest().clock))
        again = status.wait(60.0, lambda s: s.pid != first.pid)
        assert again is not None, "the launcher did not restart the smoother"
        assert wait_until(lambda: sum("smoother joined" in x for x in lines) >= 2, 30.0)
