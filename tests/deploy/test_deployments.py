"""Every deployment navigates: each service of services/stack.toml run alone (`mjnav run SERVICE`, its TOML and
nothing else, the way a container runs it) beside a router, and the commands docker compose would run, as local
processes on loopback. The robot and the world reach the services over the bus; the same seed gives the same
mission as `mjnav up`."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from typing import Any

import pytest

from mjnav.bus import Bus, BusConfig, wait_until
from mjnav.runtime.stack import load_stack
from tests.conftest import REPO, free_port
from tests.deploy.test_compose import resolved_compose

pytestmark = pytest.mark.e2e  # processes or a live stack: see pyproject's markers

GOAL = ("3.8", "2.2")  # the rooms world's goal (services/sim.toml runs rooms)
#: Sim time the goal leaves at (`mjnav goal --at`): the services are up well before at rtf 1 (sim.toml).
GOAL_AT_S = "10"


def _env(port: int) -> dict[str, str]:
    """A container's environment: a Zenoh client of the router on ``port``, headless."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("MJNAV_")}
    env |= {"MJNAV_ZENOH_MODE": "client", "MJNAV_ZENOH_CONNECT": f"tcp/127.0.0.1:{port}", "MJNAV_HEADLESS": "1"}
    env["MJNAV_TEST_SESSION"] = os.environ["MJNAV_TEST_SESSION"]
    return env


@contextmanager
def _processes(commands: Sequence[Sequence[str]], env: dict[str, str]) -> Iterator[list[str]]:
    """Run ``commands`` (``mjnav …`` argument lists) as processes from the repository; yields their merged output
    lines; stops them all with SIGTERM (SIGKILL after 15 s)."""
    lines: list[str] = []
    procs: list[subprocess.Popen[str]] = []
    readers = []
    try:
        for cmd in commands:
            assert cmd[0] == "mjnav", cmd
            proc = subprocess.Popen(
                [sys.executable, "-m", "mjnav", *cmd[1:]], cwd=REPO, env=env, text=True,
                stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
            )  # fmt: skip
            procs.append(proc)
            name = cmd[2] if len(cmd) > 2 else cmd[1]
            reader = threading.Thread(
                target=lambda p=proc, n=name: lines.extend(f"[{n}] {line}" for line in p.stdout),  # type: ignore[union-attr]
                daemon=True,
            )
            reader.start()
            readers.append(reader)
        yield lines
    finally:
        for proc in reversed(procs):
            if proc.poll() is None:
                proc.send_signal(signal.SIGTERM)
        for proc in procs:
            try:
                proc.wait(15)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait(5)
        for reader in readers:
            reader.join(5)


def _goal(port: int, *extra: str) -> tuple[int, list[dict[str, Any]], str]:
    """`mjnav goal 3.8 2.2 --wait --json EXTRA` on the router at ``port``: exit code, JSON events, stderr."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("MJNAV_ZENOH_")}
    proc = subprocess.run(
        [sys.executable, "-m", "mjnav", "goal", *GOAL, "--wait", "--json", "--timeout", "400", *extra,
         "--connect", f"tcp/127.0.0.1:{port}"],
        cwd=REPO, env=env, capture_output=True, text=True, timeout=500, check=False,
    )  # fmt: skip
    events = [json.loads(line) for line in proc.stdout.splitlines() if line.startswith("{")]
    return proc.returncode, events, proc.stderr


def _collisions(port: int) -> int:
    with Bus.open(BusConfig(mode="client", connect=(f"tcp/127.0.0.1:{port}",), listen=())) as bus:
        status = bus.subscribe("sim_status").wait(10.0)
        assert status is not None, "no sim_status"
        return int(status.collisions)


def _alive(port: int, services: Sequence[str], lines: list[str]) -> None:
    with Bus.open(BusConfig(mode="client", connect=(f"tcp/127.0.0.1:{port}",), listen=())) as bus:
        assert wait_until(lambda: set(services) <= set(bus.alive_services(0.5)), 180.0), "".join(lines)[-4000:]


def test_every_service_run_alone_navigates_as_mjnav_up_does() -> None:
    """`mjnav run SERVICE` with the stack's TOML and nothing else, for every service, beside a router: the goal is
    reached without a collision, at the same sim time as under `mjnav up` with the same seed."""
    stack = load_stack()
    port = free_port()
    commands = [["mjnav", "router", "--listen", f"tcp/127.0.0.1:{port}"]]
    commands += [["mjnav", "run", name] for name in stack.names()]
    with _processes(commands, _env(port)) as lines:
        _alive(port, stack.names(), lines)
        code, events, err = _goal(port, "--at", GOAL_AT_S)
        assert code == 0, (events, err, "".join(lines)[-4000:])
        assert _collisions(port) == 0
    alone = events[-1]
    assert alone["state"] == "REACHED" and alone["time_s"] > 5.0, alone
    # The same seed under `mjnav up` (services forked from the launcher, an embedded router): the same mission.
    up_port = free_port()
    up_env = {k: v for k, v in os.environ.items() if not k.startswith("MJNAV_ZENOH_")}
    with _processes([["mjnav", "up", "--port", str(up_port), "--headless"]], up_env) as lines:
        _alive(up_port, stack.names(), lines)
        code, events, err = _goal(up_port, "--at", GOAL_AT_S)
        assert code == 0, (events, err, "".join(lines)[-4000:])
    up = events[-1]
    assert (up["state"], up["time_s"], up["t"]) == (alone["state"], alone["time_s"], alone["t"])


def _local(arg: str, port: int) -> str:
    """A compose command argument with the router's network address made local."""
    return arg.replace("tcp/router:7447", f"tcp/127.0.0.1:{port}").replace("tcp/0.0.0.0:7447", f"tcp/127.0.0.1:{port}")


def test_the_compose_commands_run_as_local_processes_navigate() -> None:
    """What `docker compose up` runs (the default profile: the router and the ground stack), each command as
    docker-compose resolves it, with its container's environment, on loopback: the services report healthy and
    lacking nothing, and the goal is reached."""
    services = resolved_compose()
    default = {name: svc for name, svc in services.items() if not svc.get("profiles")}
    assert set(default) == {"router", *load_stack().names()}
    port = free_port()
    env = _env(port)
    for svc in default.values():
        for key, value in (svc.get("environment") or {}).items():
            env[key] = _local(str(value), port)
    commands = [[_local(str(a), port) for a in default["router"]["command"]]]
    commands += [[_local(str(a), port) for a in svc["command"]] for name, svc in default.items() if name != "router"]
    names = [name for name in default if name != "router"]
    with _processes(commands, env) as lines:
        _alive(port, names, lines)
        code, events, err = _goal(port)
        assert code == 0, (events, err, "".join(lines)[-4000:])
        assert events[-1]["state"] == "REACHED"
        assert _collisions(port) == 0
        # Each container's healthcheck, as compose runs it: alive, stepping, lacking no input.
        for name in names:
            test = [_local(str(a), port) for a in default[name]["healthcheck"]["test"][1:]]
            health = subprocess.run(
                [sys.executable, "-m", "mjnav", *test[1:], "--connect", f"tcp/127.0.0.1:{port}"],
                cwd=REPO, env=env, capture_output=True, text=True, timeout=60, check=False,
            )  # fmt: skip
            assert health.returncode == 0, (name, health.stdout, health.stderr)


def test_health_names_the_input_a_service_lacks() -> None:
    """slam without an initialpose and the mapper without a pose are alive and stepping, and unhealthy: the health
    check names what each lacks; once the pose is given, both are healthy."""
    port = free_port()
    commands = [
        ["mjnav", "router", "--listen", f"tcp/127.0.0.1:{port}"],
        ["mjnav", "run", "sim", "--set", "announce_spawn=false", "--set", 'lockstep_participants=["slam", "mapper"]'],
        ["mjnav", "run", "slam"],
        ["mjnav", "run", "mapper"],
    ]
    env = _env(port)

    def health() -> subprocess.CompletedProcess[str]:
        return subprocess.run(
            [sys.executable, "-m", "mjnav", "health", "slam", "mapper", "--status", "--timeout", "5"],
            cwd=REPO, env=env, capture_output=True, text=True, timeout=60, check=False,
        )  # fmt: skip

    with _processes(commands, env) as lines:
        _alive(port, ["sim", "slam", "mapper"], lines)
        assert wait_until(lambda: "waiting for initialpose" in health().stderr, 60.0), "".join(lines)[-3000:]
        res = health()
        assert res.returncode == 1, res.stdout
        assert "slam: waiting for initialpose on robot0/initialpose" in res.stderr, res.stderr
        assert "mapper: waiting for the robot's pose at the scans' times" in res.stderr, res.stderr
        assert any("[slam] " in line and "waiting for initialpose" in line for line in lines)  # said in its log
        pose = json.dumps({"header": {"frame_id": "map"}, "pose": {"pose": {"position": {"x": -3.5, "y": -3.5}}}})
        sent = subprocess.run(
            [sys.executable, "-m", "mjnav", "pub", "robot0/initialpose", "--yaml", pose],
            cwd=REPO, env=env, capture_output=True, text=True, timeout=60, check=False,
        )  # fmt: skip
        assert sent.returncode == 0, sent.stderr
        assert wait_until(lambda: health().returncode == 0, 60.0), health().stderr
