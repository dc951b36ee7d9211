"""`mjnav param get|set` against a running service and `mjnav map save` against a running mapper (processes)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from mjnav.bus import Bus, wait_until
from mjnav.msgs import from_dict
from tests.conftest import REPO, free_port

pytestmark = pytest.mark.e2e  # processes or a live stack: see pyproject's markers

STACK = REPO / "tests" / "services" / "stack.toml"


def _env() -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if not k.startswith("MJNAV_ZENOH_")}
    env["PYTHONPATH"] = str(REPO)
    return env


def _cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "mjnav", *args], cwd=REPO, env=_env(), text=True, capture_output=True, timeout=60
    )


def _service(*args: str) -> Iterator[subprocess.Popen[str]]:
    proc = subprocess.Popen(
        [sys.executable, "-m", "mjnav", "run", *args], cwd=REPO, env=_env(), text=True, stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
    )  # fmt: skip
    yield proc
    if proc.poll() is None:
        proc.kill()
    proc.communicate(timeout=10)


@pytest.fixture
def kinematic(router_endpoint: str) -> Iterator[subprocess.Popen[str]]:
    """The fixture robot (``max_speed_mps`` settable at runtime), on wall time."""
    yield from _service("kinematic", "--stack", str(STACK), "--connect", router_endpoint)


def test_param_set_changes_a_running_service_and_validates(
    kinematic: subprocess.Popen[str], peer: Callable[..., Bus], router_endpoint: str
) -> None:
    me = peer()
    assert wait_until(lambda: "kinematic" in me.alive_services(0.5), 30.0)
    bus = ("--connect", router_endpoint)
    got = _cli("param", "get", "kinematic", "max_speed_mps", *bus)
    assert (got.returncode, got.stdout.strip()) == (0, "1.0"), got.stderr
    everything = _cli("param", "get", "kinematic", *bus)
    assert json.loads(everything.stdout)["rate_hz"] == 50.0

    done = _cli("param", "set", "kinematic", "max_speed_mps", "0.25", *bus)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "kinematic.max_speed_mps: 1.0 -> 0.25"
    # Behaviour, not only the echo: a 1 m/s command is now clamped at 0.25 m/s in the odometry.
    odom = me.subscribe("odom")
    cmd = me.publisher("cmd_vel")
    assert cmd.wait_for_subscribers(10.0)
    fast = from_dict("geometry_msgs/msg/Twist", {"linear": {"x": 1.0}})

    def clamped() -> bool:
        cmd.put(fast)
        msg = odom.latest()
        return msg is not None and abs(msg.twist.twist.linear.x - 0.25) < 1e-9

    assert wait_until(clamped, 20.0)
    assert _cli("param", "get", "kinematic", "max_speed_mps", *bus).stdout.strip() == "0.25"

    refused = _cli("param", "set", "kinematic", "max_speed_mps", "-1", *bus)  # __post_init__ rejects it
    assert refused.returncode == 1 and "max_speed_mps must be > 0" in refused.stderr
    wrong_type = _cli("param", "set", "kinematic", "max_speed_mps", "fast", *bus)
    assert wrong_type.returncode == 1 and "expected a number" in wrong_type.stderr
    fixed = _cli("param", "set", "kinematic", "rate_hz", "10", *bus)  # read once at start: not settable
    assert fixed.returncode == 1 and "cannot be set while running; settable: max_speed_mps" in fixed.stderr
    unknown = _cli("param", "get", "kinematic", "nope", *bus)
    assert unknown.returncode == 1 and "no setting 'nope'" in unknown.stderr
    nobody = _cli("param", "get", "planner", *bus, "--timeout", "1")
    assert nobody.returncode == 3 and "nobody answered on robot0/config/planner" in nobody.stderr


def test_bus_commands_without_a_router_fail_clearly() -> None:
    nowhere = ("--connect", f"tcp/127.0.0.1:{free_port()}")
    for args in (["param", "get", "mapper"], ["map", "save", "x.yaml"]):
        res = _cli(*args, *nowhere)
        assert res.returncode == 3 and "no Zenoh router reachable" in res.stderr, res.stderr
    for args in (["topics", "--duration", "1"], ["echo", "/robot0/goal_status", "--count", "1"]):
        res = _cli(*args, *nowhere)  # at once, not after a wait for nothing
        assert res.returncode == 1 and "no Zenoh router reachable" in res.stderr, res.stderr


def test_map_save_writes_inside_the_mappers_folder(
    router_endpoint: str, peer: Callable[..., Bus], tmp_path: Path
) -> None:
    maps = tmp_path / "maps"
    me = peer()
    for _proc in _service("mapper", "--connect", router_endpoint, "--set", f"maps_dir={json.dumps(str(maps))}"):
        assert wait_until(lambda: "mapper" in me.alive_services(0.5), 60.0)
        bus = ("--connect", router_endpoint)
        empty = _cli("map", "save", "first/run.yaml", *bus)  # nothing scanned yet: no map to write
        assert empty.returncode == 1 and "no map yet" in empty.stderr, empty.stderr
        assert not (maps / "first" / "run.yaml").exists()
        outside = _cli("map", "save", "../escape.yaml", *bus)
        assert outside.returncode == 1 and "outside" in outside.stderr
        assert not (tmp_path / "escape.yaml").exists()
