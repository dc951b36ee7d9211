"""Navigation end to end: the real stack (`mjnav up` / `mjnav demo`) as processes on loopback Zenoh."""

from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
import pytest

from mjnav.bus import Bus, BusConfig, wait_until
from mjnav.geometry import Pose2D, PoseHistory
from mjnav.mapping import write_ros_map
from mjnav.mapping.frame import GridFrame
from mjnav.msgs import decode, encode, from_dict, msg_class, ros, validate
from mjnav.msgs.codec import MessageError
from mjnav.msgs.ros import seconds as ros_seconds
from mjnav.runtime.mission import MissionClient
from mjnav.runtime.stack import ProcessSpec, load_stack
from mjnav.sim import Simulator
from mjnav.sim.truth import static_occupancy
from mjnav.sim.worlds import world_info
from tests.conftest import REPO, free_port

pytestmark = pytest.mark.e2e  # processes or a live stack: see pyproject's markers

SERVICES = {"sim", "slam", "mapper", "planner", "smoother", "controller", "viz"}
STATUS = msg_class("mjnav_msgs/msg/GoalStatus")
RTF = 4.0


def shipped_processes() -> list[ProcessSpec]:
    """The processes `mjnav up` runs the shipped stack in (its containers, the other services alone)."""
    stack = load_stack()
    return stack.processes(stack.select(None))


def process_of(service: str) -> str:
    """The name the launcher gives the process that hosts ``service`` (its container's, or its own)."""
    return next(p.name for p in shipped_processes() if service in p.service_names())


def _mjnav(*args: str) -> subprocess.Popen[str]:
    env = {k: v for k, v in os.environ.items() if not k.startswith("MJNAV_ZENOH_")}
    return subprocess.Popen(
        [sys.executable, "-m", "mjnav", *args],
        cwd=REPO,
        env=env,
        text=True,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
    )


@contextmanager
def up_process(*args: str) -> Iterator[tuple[int, subprocess.Popen[str], list[str]]]:
    """`mjnav up ARGS` on a free port; yields the port, the process and its output lines (read as they come).
    Stops it with SIGINT at the end and asserts it exited 0."""
    port = free_port()
    proc = _mjnav("up", "--port", str(port), "--headless", *args)
    lines: list[str] = []
    reader = threading.Thread(target=lambda: lines.extend(proc.stdout), daemon=True)  # type: ignore[arg-type]
    reader.start()
    try:
        yield port, proc, lines
    finally:
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
            try:
                proc.wait(30)
            except subprocess.TimeoutExpired:
                proc.kill()
        reader.join(5)
    assert proc.returncode == 0, "".join(lines)[-3000:]


@contextmanager
def running_stack(
    *sets: str, initial_pose: Pose2D | None = None, initial_sigma: tuple[float, float] = (0.05, 0.05)
) -> Iterator[tuple[Bus, MissionClient, subprocess.Popen[str], list[str]]]:
    """`mjnav up` with the shipped stack; yields a bus on its router, a mission client (sending ``initialpose`` when
    given one: the sim announces the world's start itself), the process, its output."""
    args = ["--set", f"sim.rtf={RTF}"]
    for item in sets:
        args += ["--set", item]
    with up_process(*args) as (port, proc, lines):
        bus = Bus.open(BusConfig(connect=(f"tcp/127.0.0.1:{port}",)))
        try:
            client = MissionClient(bus, initial_pose=initial_pose, initial_sigma=initial_sigma)
            assert wait_until(lambda: SERVICES <= set(bus.alive_services(0.5)), 180.0), "".join(lines)[-3000:]
            assert client.truth.wait(60.0) is not None
            yield bus, client, proc, lines
        finally:
            bus.close()


def _true_map(world: str, path: Path) -> Path:
    """The world's static obstacles as a ROS map (what a previous mapping run would have produced)."""
    sim = Simulator(world, lidar=None)
    mujoco.mj_forward(sim.model, sim.data)
    frame = GridFrame(0.05, (-10.0, -10.0), (400, 400))
    occupied = static_occupancy(sim.model, sim.data, frame)
    return write_ros_map(path, np.where(occupied, 100, 0).astype(np.int8), 0.05, (-10.0, -10.0, 0.0))


def test_demo_reaches_two_goals_in_the_rooms_world_from_an_unknown_map(tmp_path: Path) -> None:
    out = tmp_path / "run"
    goals = tmp_path / "goals.json"
    goals.write_text(json.dumps([[-1.0, -3.5], {"x": 3.8, "y": 2.2}]))
    proc = _mjnav(
        "demo",
        "--world",
        "rooms",
        "--goals",
        str(goals),
        "--rtf",
        str(RTF),
        "--json",
        "--out",
        str(out),
        "--headless",
        "--port",
        str(free_port()),
    )
    stdout, _ = proc.communicate(timeout=600)
    assert proc.returncode == 0, stdout[-3000:]
    summary = json.loads(stdout.strip().splitlines()[-1])
    assert summary["reached"] is True and summary["collisions"] == 0
    assert [g["result"] for g in summary["goals"]] == ["reached", "reached"]
    first, second = summary["goals"]
    assert second["goal_id"] != first["goal_id"]
    # The second goal starts where the first ended and really drives (no instant "reached" on a stale path).
    assert math.dist(second["start"], first["goal"]) < 0.2 and second["path_length_m"] > 5.0
    assert summary["v_max_mps"] == 0.5
    assert 0 < summary["optimal_length_m"] <= summary["path_length_m"] * 1.05
    assert summary["min_clearance_m"] > 0.0
    assert json.loads((out / "summary.json").read_text()) == summary
    for name in ("map.yaml", "map.pgm", "scene.html"):
        assert (out / name).is_file(), name


def test_unreachable_and_occupied_goals_fail_with_the_right_reason(tmp_path: Path) -> None:
    prior = _true_map("rooms", tmp_path / "prior.yaml")
    # A saved map: SLAM localizes on it and the costmap starts from it.
    sets = (
        "slam.mode=localization",
        f"slam.map_file={json.dumps(str(prior))}",
        f"mapper.prior_map={json.dumps(str(prior))}",
    )
    with running_stack(*sets) as (bus, client, _proc, lines):
        outside = client.run_goal(40.0, 40.0, timeout_s=30.0, wall_timeout_s=60.0)
        assert (outside.result, outside.error_code) == ("failed", STATUS.ERROR_OUTSIDE_MAP), outside
        in_wall = client.run_goal(0.0, 0.0, timeout_s=30.0, wall_timeout_s=60.0)  # the centre of the rooms' cross
        assert (in_wall.result, in_wall.error_code) == ("failed", STATUS.ERROR_GOAL_OCCUPIED), in_wall
        enclosed = client.run_goal(-7.5, 0.0, timeout_s=30.0, wall_timeout_s=60.0)  # outside the outer walls
        assert (enclosed.result, enclosed.error_code) == ("failed", STATUS.ERROR_NO_PATH), enclosed
        assert SERVICES <= set(bus.alive_services(1.0)), "a service died"
        assert "Traceback" not in "".join(lines)
        reached = client.run_goal(-1.5, -3.5, timeout_s=60.0, wall_timeout_s=120.0)
        assert reached.result == "reached", reached


def test_localization_on_a_saved_map_converges_from_a_wrong_initial_pose(tmp_path: Path) -> None:
    """SLAM in localization mode on a saved map, told a start 0.5 m and 20° off with RViz's default uncertainty
    (σ 0.5 m, 15°) by both its config and ``initialpose``: within 2 s of driving its pose is within 5 cm of the
    truth and stays there to the goal (it corrects the error at its first scan, before the robot moves)."""
    prior = _true_map("rooms", tmp_path / "prior.yaml")
    start = world_info("rooms").start
    wrong = Pose2D(start.x + 0.4, start.y - 0.3, start.theta + math.radians(20.0))
    sets = (
        "slam.mode=localization",
        f"slam.map_file={json.dumps(str(prior))}",
        f"mapper.prior_map={json.dumps(str(prior))}",
        "sim.publish_ground_truth=false",
        "sim.announce_spawn=false",  # the operator, not the sim, tells SLAM where the robot is: wrongly
        f"slam.initial_pose={json.dumps([wrong.x, wrong.y, wrong.theta])}",  # not the world's start either
        f"slam.initial_sigma={json.dumps([0.5, math.radians(15.0)])}",
    )
    estimates: list[tuple[float, Pose2D]] = []
    truths: list[tuple[float, Pose2D]] = []
    with running_stack(*sets, initial_pose=wrong, initial_sigma=(0.5, math.radians(15.0))) as (bus, client, _, _):
        bus.subscribe("pose", callback=lambda m: estimates.append((ros_seconds(m.header.stamp), ros.pose_of(m))))
        bus.subscribe("truth", callback=lambda m: truths.append((ros_seconds(m.header.stamp), ros.pose2d(m.pose))))
        outcome = client.run_goal(-1.5, -3.5, timeout_s=90.0, wall_timeout_s=300.0)
        assert outcome.result == "reached", outcome
    truth = PoseHistory(horizon_s=math.inf)
    for t, pose in truths:
        truth.add(t, pose)
    t_drive = next((t for t, pose in truths if math.hypot(pose.x - start.x, pose.y - start.y) > 0.02), None)
    assert t_drive is not None, "the robot never drove"
    errors = [(t, est.distance_to(true)) for t, est in estimates if (true := truth.at(t)) is not None]
    assert any(t < t_drive for t, _ in errors)  # compared from before the robot drives
    late = [e for t, e in errors if t >= t_drive + 2.0]
    assert late and max(late) <= 0.05, f"error 2 s after driving off: max {max(late):.3f} m"


def test_killing_the_controller_stops_the_robot_and_the_mission_still_completes() -> None:
    with running_stack() as (bus, client, _proc, lines):
        status = bus.subscribe("status", service="controller")
        speeds: list[tuple[float, float]] = []  # (sim time, forward speed) from the true pose's odometry
        bus.subscribe("odom", callback=lambda m: speeds.append((ros_seconds(m.header.stamp), m.twist.twist.linear.x)))
        commands: list[float] = []  # sim time at which each cmd_vel was seen
        bus.subscribe("cmd_vel", callback=lambda _m: commands.append(client.now()))
        outcome: list[object] = []
        runner = threading.Thread(
            target=lambda: outcome.append(client.run_goal(3.8, 2.2, timeout_s=200.0, wall_timeout_s=300.0))
        )
        runner.start()
        try:
            assert wait_until(lambda: bool(speeds) and speeds[-1][1] > 0.3, 120.0), "the robot never drove"
            first = status.wait(10.0)
            assert first is not None
            os.kill(first.pid, signal.SIGKILL)
            killed_at = client.now()
            assert client.clock.wait(30.0, lambda c: ros_seconds(c.clock) >= killed_at + 1.5) is not None
            last_cmd = max(t for t in commands if t <= killed_at + 0.2)
            stopped = [t for t, v in speeds if t > last_cmd and abs(v) < 0.02]
            assert stopped, "the robot never stopped after the controller died"
            # Watchdog at 0.5 s after the last command (applied within one 10 ms clock tick), then braking.
            assert stopped[0] - last_cmd <= 0.7, f"stopped {stopped[0] - last_cmd:.2f} s after the last command"
            restarted = status.wait(60.0, lambda s: s.pid != first.pid)
            assert restarted is not None, "the launcher did not restart the controller"
        finally:
            runner.join(400.0)
        assert outcome and outcome[0].result == "reached", outcome  # type: ignore[attr-defined]
    text = "".join(lines)
    assert f"{process_of('controller')} exited" in text and "restarting" in text


def _fuzz_payloads(msgtype: str, rng: np.random.Generator, n: int) -> list[bytes]:
    """``n`` payloads that are NOT valid ``msgtype`` messages: random bytes, truncations, NaN-laden messages."""
    template = encode(_nan_laden(msgtype, rng))
    out: list[bytes] = []
    attempt = 0
    while len(out) < n:
        kind = attempt % 3
        attempt += 1
        if kind == 0:
            data = rng.integers(0, 256, int(rng.integers(0, 300)), dtype=np.uint8).tobytes()
        elif kind == 1:
            data = encode(_nan_laden(msgtype, rng))[: int(rng.integers(0, max(1, len(template) - 1)))]
        else:
            data = encode(_nan_laden(msgtype, rng))
        try:
            validate(decode(data, msgtype))
        except MessageError:
            out.append(data)
    return out


def _nan_laden(msgtype: str, rng: np.random.Generator) -> object:
    """A structurally valid message whose float fields are NaN where it has any (else all defaults)."""
    samples = {
        "geometry_msgs/msg/Twist": {"linear": {"x": math.nan}, "angular": {"z": float(rng.normal())}},
        "geometry_msgs/msg/PoseStamped": {"pose": {"position": {"x": math.nan}, "orientation": {"w": 1.0}}},
        "sensor_msgs/msg/LaserScan": {"range_min": math.nan, "range_max": 10.0, "ranges": [1.0] * 360},
        "nav_msgs/msg/OccupancyGrid": {"info": {"resolution": math.nan, "width": 2, "height": 2}, "data": [0] * 4},
        "nav_msgs/msg/Path": {"poses": [{"pose": {"position": {"x": math.nan}, "orientation": {"w": 1.0}}}]},
        "mjnav_msgs/msg/SimStatus": {"real_time_factor": math.nan},
        "mjnav_msgs/msg/GoalStatus": {"goal": {"pose": {"position": {"y": math.nan}, "orientation": {"w": 1.0}}}},
    }
    return from_dict(msgtype, samples.get(msgtype, {}))


# Keys each service subscribes to (every service on sim time also subscribes to clock).
SUBSCRIBED = {
    "sim": ["cmd_vel"],
    "slam": ["clock", "odom", "scan", "initialpose", "robot_description"],
    "mapper": ["clock", "scan", "tf", "robot_description"],
    "planner": ["clock", "goal", "cancel", "costmap", "controller_feedback", "tf"],
    "smoother": ["clock", "plan", "costmap"],
    "controller": ["clock", "path", "tf", "scan", "goal_status", "map", "robot_description"],
    "viz": ["truth", "scan", "map", "plan", "path", "costmap", "goal", "goal_status", "sim_status"],
}
FUZZ_PER_KEY = 1000


def test_fuzzing_every_subscribed_key_is_counted_and_survived() -> None:
    import zenoh

    from mjnav.msgs import topic

    rng = np.random.default_rng(2024)
    keys = sorted({k for ks in SUBSCRIBED.values() for k in ks})
    with running_stack() as (bus, client, proc, lines):
        status = bus.subscribe("status", service="*")
        assert wait_until(lambda: set(SUBSCRIBED) <= {s.service for s in status.latest_by_key().values()}, 30.0)
        before = {s.service: s.messages_rejected for s in status.latest_by_key().values()}
        for name in keys:
            payloads = _fuzz_payloads(topic(name).msgtype, rng, FUZZ_PER_KEY)
            pub = bus.session.declare_publisher(bus.key(name), congestion_control=zenoh.CongestionControl.BLOCK)
            for data in payloads:
                pub.put(data)
            pub.undeclare()
        # The loop's services decode (and so reject) every message. viz, an observer outside the loop, reads lossy
        # subscriptions (mjnav.bus: the newest message of a snapshot topic, the last LOSSY_CAPACITY of an event
        # topic), so it rejects what it reads: at least one per key.
        # The clock is one subscription per process (mjnav.runtime.simtime.SimClock, on its first service's bus).
        first = {p.service_names()[0] for p in shipped_processes()}
        expected = {
            svc: before[svc] + FUZZ_PER_KEY * sum(k != "clock" or svc in first for k in ks)
            for svc, ks in SUBSCRIBED.items()
            if svc != "viz"
        }
        observed_at_least = before["viz"] + len(SUBSCRIBED["viz"])

        def counted() -> bool:
            now = {s.service: s.messages_rejected for s in status.latest_by_key().values()}
            return all(now.get(svc, 0) >= n for svc, n in expected.items()) and now["viz"] >= observed_at_least

        assert wait_until(counted, 60.0), {s.service: s.messages_rejected for s in status.latest_by_key().values()}
        final = {s.service: s.messages_rejected for s in status.latest_by_key().values() if s.service in expected}
        assert final == expected
        assert SERVICES <= set(bus.alive_services(1.0)) and proc.poll() is None
        assert "restarting" not in "".join(lines)
        outcome = client.run_goal(3.8, 2.2, timeout_s=200.0, wall_timeout_s=300.0)
        assert outcome.result == "reached", outcome


@pytest.mark.parametrize("seed", [0])
def test_warehouse_with_moving_obstacles_has_no_collision(seed: int) -> None:
    with running_stack("sim.world=warehouse", f"sim.seed={seed}") as (_bus, client, _proc, _lines):
        outcome = client.run_goal(5.0, 3.0, timeout_s=200.0, wall_timeout_s=300.0)
        assert outcome.result == "reached", outcome
        assert client.collisions() == 0


def _maze_there_and_back(tmp_path: Path, *sets: str) -> dict[str, Any]:
    """`mjnav demo` in the maze to the far corner and back (seed 2), navigating on SLAM with the truth switched off."""
    goals = tmp_path / "there_and_back.json"
    goals.write_text(json.dumps([[3.75, 3.75], [-3.75, -3.75]]))
    args = ["demo", "--world", "maze", "--goals", str(goals), "--seed", "2", "--rtf", "max", "--json", "--headless"]
    args += ["--port", str(free_port()), "--set", "sim.publish_ground_truth=false"]
    for item in sets:
        args += ["--set", item]
    stdout, _ = _mjnav(*args).communicate(timeout=900)
    summary: dict[str, Any] = json.loads(stdout.strip().splitlines()[-1])
    assert summary["reached"] is True and summary["collisions"] == 0, stdout[-3000:]
    return summary


def test_loop_closures_lower_the_slam_error_on_a_maze_round_trip(tmp_path: Path) -> None:
    """Back through corridors it mapped on the way out, SLAM closes loops; its trajectory error (against the truth,
    which no navigation service reads) is lower than the same mission's without loop closure."""
    closing = _maze_there_and_back(tmp_path)
    open_loop = _maze_there_and_back(tmp_path, "slam.loop_closure=false")
    assert closing["pose_source"] == "slam" and closing["loop_closures"] >= 1 and open_loop["loop_closures"] == 0
    assert closing["ate_rms_m"] < open_loop["ate_rms_m"]
    assert closing["ate_rms_m"] <= 0.03 and min(closing["map_accuracy"]) >= 0.95
