"""`mjnav goal` / `mjnav cancel` / `mjnav pub` on event keys without a stack: argument parsing (negative
coordinates everywhere), the waypoint file, delivery that fails loudly, no router. The goal CLI against a live stack
is in tests/services/test_goal_cli_stack.py."""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest

from mjnav.bus import Bus
from mjnav.cli import build_parser
from mjnav.commands.goal import Waypoint, read_waypoints
from mjnav.services.planner import PlannerService
from tests.conftest import REPO, free_port
from tests.services.harness import Harness


def _mjnav(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "mjnav", *args], cwd=REPO, text=True, capture_output=True, timeout=120, check=False
    )


@pytest.mark.parametrize(
    ("argv", "field", "value"),
    [
        (["demo", "--goal", "-3,2"], "goal", "-3,2"),
        (["demo", "--goal", "-3.5,-2.25"], "goal", "-3.5,-2.25"),
        (["plan", "--map", "m.yaml", "--start", "-1,-2", "--goal", "-1e-1,4"], "goal", (-0.1, 4.0)),
        (["goal", "-3", "-2.5", "--yaw", "-90"], "yaw", -90.0),
        (["goal", "-3", "-2.5"], "y", -2.5),
        (["world", "from-map", "m.yaml", "--out", "s.xml", "--goal", "-1", "-2", "-90"], "goal", [-1.0, -2.0, -90.0]),
    ],
)
def test_negative_numbers_are_values_in_every_command(argv: list[str], field: str, value: object) -> None:
    assert getattr(build_parser().parse_args(argv), field) == value


def test_help_says_coordinates_may_be_negative() -> None:
    assert "--goal -3,2" in build_parser().format_help()


def test_waypoint_file(tmp_path: Path) -> None:
    path = tmp_path / "route.txt"
    path.write_text("# x y [yaw_deg]\n1.0 2.0\n\n-3.5, -1  90  # corner\n0 0 -45\n")
    assert read_waypoints(path) == [Waypoint(1.0, 2.0), Waypoint(-3.5, -1.0, 90.0), Waypoint(0.0, 0.0, -45.0)]
    path.write_text("1 2\n3\n")
    with pytest.raises(ValueError, match=r"route.txt:2: expected 'X Y \[YAW_DEG\]'"):
        read_waypoints(path)
    path.write_text("# nothing\n")
    with pytest.raises(ValueError, match="no waypoints"):
        read_waypoints(path)


@pytest.mark.e2e
def test_pub_on_an_event_key_confirms_delivery_or_fails_loudly(peer: Callable[..., Bus], router_endpoint: str) -> None:
    goal = "{header: {frame_id: map}, pose: {position: {x: 1.0, y: 1.0}}}"
    viewer = peer()
    viewer.subscribe("goal")  # a subscriber, but not the one the topic table names
    lost = _mjnav("pub", "robot0/goal", "--yaml", goal, "--timeout", "2", "--connect", router_endpoint)
    assert lost.returncode == 1 and "NOT DELIVERED" in lost.stderr and "planner 0/1" in lost.stderr
    Harness(PlannerService, peer, ())
    burst = ["--count", "30", "--rate", "200", "--timeout", "60"]  # --timeout: a guard for a loaded machine
    done = _mjnav("pub", "/robot0/goal", "--yaml", goal, *burst, "--connect", router_endpoint)
    assert done.returncode == 0, done.stderr
    assert "received by planner (30)" in done.stderr


@pytest.mark.e2e
def test_goal_and_cancel_without_a_router_exit_3_and_say_so() -> None:
    nobody = f"tcp/127.0.0.1:{free_port()}"
    for argv in (["goal", "1", "1", "--wait"], ["cancel"]):
        proc = _mjnav(*argv, "--connect", nobody)
        assert proc.returncode == 3 and "no Zenoh router reachable" in proc.stderr, proc.stderr
    for argv in (["echo", "robot0/odom"], ["topics"], ["pub", "robot0/cancel"]):
        proc = _mjnav(*argv, "--connect", nobody)
        assert proc.returncode == 1 and "no Zenoh router reachable" in proc.stderr, proc.stderr


@pytest.mark.e2e
def test_goal_rejects_bad_arguments() -> None:
    for argv in (["goal"], ["goal", "1", "2", "--waypoints", "w.txt"], ["goal", "1", "nan"]):
        proc = _mjnav(*argv, "--connect", "tcp/127.0.0.1:1")
        assert proc.returncode == 2, proc.stderr


@pytest.mark.e2e
def test_a_closed_pipe_ends_a_command_quietly(tmp_path: Path) -> None:
    grid = tmp_path / "open.map"
    grid.write_text("type octile\nheight 20\nwidth 20\nmap\n" + ("." * 20 + "\n") * 20)
    proc = subprocess.Popen(
        [sys.executable, "-m", "mjnav", "plan", "--map", str(grid), "--start", "0,0", "--goal", "19,19"],
        cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    assert proc.stdout is not None
    proc.stdout.close()  # the reader is gone before the first line (`| head -0`)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 0 and "Traceback" not in err and "BrokenPipe" not in err, err


def test_echo_names_states_and_error_codes() -> None:
    from mjnav.commands.bustools import with_constant_names
    from mjnav.geometry import Pose2D
    from mjnav.msgs import msg_class, ros, to_dict

    status = msg_class("mjnav_msgs/msg/GoalStatus")
    goal = ros.pose_stamped(0.0, "map", Pose2D())
    msg = status(header=ros.header(1.0, "map"), goal_id=3, state=status.STATE_FAILED,
                 error_code=status.ERROR_NO_PATH, error_text="walled in", goal=goal)  # fmt: skip
    data = with_constant_names(msg, to_dict(msg))
    assert (data["state"], data["state_name"]) == (5, "FAILED")
    assert (data["error_code"], data["error_code_name"]) == (4, "ERROR_NO_PATH")
    assert list(data)[:6] == ["header", "goal_id", "state", "state_name", "error_code", "error_code_name"]
