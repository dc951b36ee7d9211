"""The sim service as a real process on loopback Zenoh: topics, stamps, cmd_vel drives the wheels, watchdog."""

from __future__ import annotations

import math
import re
import signal
import subprocess
import sys
import threading
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np
import pytest

from mjnav.bus import Bus
from mjnav.geometry import Pose2D
from mjnav.msgs import ros
from mjnav.robot import parse_robot_description
from tests.conftest import REPO, stop_process


@pytest.fixture
def sim_process(router_endpoint: str) -> Iterator[subprocess.Popen[str]]:
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "mjnav",
            "run",
            "sim",
            "--connect",
            router_endpoint,
            "--set",
            "world=empty",
            "--set",
            "rtf=1.0",
            "--set",
            "lockstep_participants=[]",  # alone: sim time starts at once (sim.toml waits for the stack)
        ],
        cwd=REPO,
        text=True,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
    )
    yield proc
    stop_process(proc, 10.0)


@pytest.mark.e2e
def test_sim_publishes_sensors_and_obeys_cmd_vel_with_a_watchdog(
    sim_process: subprocess.Popen[str], peer: Callable[..., Bus]
) -> None:
    me = peer()
    clock = me.subscribe("clock")
    scan = me.subscribe("scan")
    truth = me.subscribe("ground_truth")
    subs = {name: me.subscribe(name) for name in ("odom", "imu", "joint_states", "tf")}
    first = clock.wait(60.0)
    assert first is not None, "no clock from the sim"

    s = scan.wait(10.0)
    assert s is not None and len(s.ranges) == 360 and s.header.frame_id == "laser"
    assert s.range_max == pytest.approx(12.0) and math.isclose(s.angle_increment, 2 * math.pi / 360, rel_tol=1e-6)
    for name, sub in subs.items():
        assert sub.wait(10.0) is not None, f"no {name}"
    assert subs["tf"].latest().transforms[0].child_frame_id == "base_link"
    # The robot's facts, latched: a subscriber that joins now, long after they went out, gets them at once.
    late = peer()
    description = late.subscribe("robot_description").wait(10.0)
    assert description is not None and parse_robot_description(description.data).radius_m == pytest.approx(0.19)
    statics = late.subscribe("tf_static").wait(10.0)
    assert statics is not None
    frames = {t.child_frame_id: (t.header.frame_id, t.transform.translation.z) for t in statics.transforms}
    assert frames == {"laser": ("base_link", 0.2), "imu": ("base_link", 0.1)}  # the model's sites

    start = truth.wait(10.0)
    x0 = start.pose.position.x
    cmd = me.publisher("cmd_vel")
    assert cmd.wait_for_subscribers(10.0)
    stop = threading.Event()

    def drive() -> None:
        while not stop.wait(0.05):  # a 20 Hz teleop source
            cmd.put(ros.twist(0.3, 0.0))

    driver = threading.Thread(target=drive)
    driver.start()
    t_start = ros.seconds(clock.latest().clock)
    try:
        assert clock.wait(30.0, lambda c: ros.seconds(c.clock) >= t_start + 2.0) is not None
    finally:
        stop.set()
        driver.join()
    moving = truth.latest()
    assert moving.pose.position.x - x0 > 0.3, "the robot did not drive forward"
    assert subs["odom"].latest().twist.twist.linear.x == pytest.approx(0.3, rel=0.15)

    # No more commands: after the 0.5 s watchdog the robot must stand still.
    t_last = ros.seconds(clock.latest().clock)
    assert clock.wait(30.0, lambda c: ros.seconds(c.clock) >= t_last + 1.0) is not None
    p1 = truth.latest().pose.position
    t1 = ros.seconds(clock.latest().clock)
    assert clock.wait(30.0, lambda c: ros.seconds(c.clock) >= t1 + 0.5) is not None
    p2 = truth.latest().pose.position
    assert np.hypot(p2.x - p1.x, p2.y - p1.y) < 0.01, "the watchdog did not stop the wheels"

    stamps = [ros.seconds(c) for c in (first.clock, clock.latest().clock)]
    assert stamps[1] > stamps[0]


@pytest.mark.e2e
@pytest.mark.parametrize("world", ["warehouse", "empty"])
def test_obstacles_carry_the_true_poses_of_the_moving_bodies(world: str, peer: Callable[..., Bus]) -> None:
    from mjnav.services.sim import SimBridge, SimConfig
    from mjnav.sim import LidarConfig, SimRunner, Simulator

    sim = Simulator(world, seed=0, lidar=LidarConfig(num_beams=36))
    sim_bus = peer()
    runner = SimRunner(sim, rtf=None)
    SimBridge(sim, sim_bus, SimConfig(world=world)).attach(runner)
    me = peer()
    obstacles, clock = me.subscribe("obstacles"), me.subscribe("clock")
    for name in ("obstacles", "clock"):  # our subscriptions have reached the bridge's session
        assert sim_bus.publisher(name).wait_for_subscribers(10.0)
    runner.advance(0.0)
    if world == "empty":
        runner.advance(0.5)
        assert clock.wait(10.0, lambda c: ros.seconds(c.clock) >= 0.5) is not None
        assert obstacles.latest() is None, "a world without moving bodies published obstacles"
        return

    first = obstacles.wait(10.0, lambda m: True)  # the t = 0 message may already be here
    assert first is not None
    assert sorted(t.child_frame_id for t in first.transforms) == ["cart", "picker"]
    assert {t.header.frame_id for t in first.transforms} == {"map"}
    truth = {b.name: b for b in sim.moving_body_poses()}
    for t in first.transforms:
        tr = t.transform.translation
        assert [tr.x, tr.y, tr.z] == pytest.approx(truth[t.child_frame_id].position_m.tolist())
    runner.advance(2.0)  # the carts oscillate on springs: two seconds later they are elsewhere
    later = obstacles.wait(10.0, lambda m: ros.seconds(m.transforms[0].header.stamp) >= 2.0)
    assert later is not None
    moved = {t.child_frame_id: t.transform.translation.y for t in later.transforms}
    start = {t.child_frame_id: t.transform.translation.y for t in first.transforms}
    assert all(abs(moved[n] - start[n]) > 0.05 for n in moved), (start, moved)
    assert moved == pytest.approx({b.name: float(b.position_m[1]) for b in sim.moving_body_poses()}, abs=0.05)


@pytest.mark.e2e
def test_the_sim_service_records_while_it_runs(router_endpoint: str, peer: Callable[..., Bus], tmp_path: Path) -> None:
    import imageio.v3 as iio

    from mjnav.sim import RenderBackendUnavailableError, select_gl_backend

    try:
        select_gl_backend()
    except RenderBackendUnavailableError as exc:
        pytest.skip(f"no offscreen OpenGL here: {exc}")
    out = tmp_path / "sim.mp4"
    sets = ["world=warehouse", "rtf=0", f"record_path={str(out)!r}", "record_fps=10.0", "lockstep_participants=[]"]
    cmd = [sys.executable, "-m", "mjnav", "run", "sim", "--connect", router_endpoint]
    proc = subprocess.Popen(
        cmd + [a for s in sets for a in ("--set", s)],
        cwd=REPO,
        text=True,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
    )
    try:
        clock = peer().subscribe("clock")
        assert clock.wait(90.0, lambda c: ros.seconds(c.clock) >= 2.0) is not None, "the sim never reached 2 s"
    finally:
        proc.send_signal(signal.SIGINT)
        log, _ = proc.communicate(timeout=30)
    assert proc.returncode == 0, log
    wrote = re.search(r"wrote (\d+) frames", log)
    stopped = re.search(r"stopped at sim time ([0-9.]+) s", log)
    assert wrote and stopped, log
    frames = iio.imread(out, plugin="FFMPEG")
    assert frames.shape[0] == int(wrote.group(1))
    # One frame every 0.1 s of sim time, the first at 0 (±1 for the step the signal arrived in).
    assert abs(frames.shape[0] - (math.floor(float(stopped.group(1)) * 10.0) + 1)) <= 1
    assert np.abs(frames[0].astype(int) - frames[-1].astype(int)).mean() > 0.05  # the carts move


@pytest.mark.e2e
@pytest.mark.parametrize("rates", [{}, {"odom_rate_hz": 50.0}, {"odom_rate_hz": 20.0, "imu_rate_hz": 60.0}])
def test_each_clock_goes_out_at_its_own_tick_whatever_the_valid_rates(
    rates: dict[str, float], peer: Callable[..., Bus]
) -> None:
    from mjnav.services.sim import SimBridge, SimConfig
    from mjnav.sim import SimRunner, Simulator

    sim = Simulator("empty", seed=0)
    bus = peer()
    bridge = SimBridge(sim, bus, SimConfig(world="empty", **rates))
    bridge.attach(SimRunner(sim, rtf=None))
    tick = bridge.clock_period_s
    for k in range(1, 21):
        bridge.advance(k * tick)  # one lockstep round
        assert bus.sim_time == pytest.approx(k * tick), f"round {k}: the clock went out at {bus.sim_time}"


@pytest.mark.parametrize(
    "rates", [{"imu_rate_hz": 50.0}, {"odom_rate_hz": 30.0, "imu_rate_hz": 30.0}, {"clock_rate_hz": 30.0}]
)
def test_rates_that_put_clock_ticks_off_the_publishing_grid_are_refused(rates: dict[str, float]) -> None:
    from mjnav.services.sim import SimConfig

    # imu_rate_hz = 50 with the 20 Hz clock published the clock of 0.05 s at 0.06 s and stalled every lockstep round
    with pytest.raises(ValueError, match="whole multiple of clock_rate_hz"):
        SimConfig(world="empty", **rates)


@pytest.mark.e2e
@pytest.mark.parametrize(
    "rates",
    [
        {"clock_rate_hz": 40.0, "imu_rate_hz": 200.0},
        {"clock_rate_hz": 80.0, "odom_rate_hz": 80.0, "imu_rate_hz": 160.0},
    ],
)
def test_a_clock_off_the_physics_steps_is_refused_when_the_sim_is_wired(
    rates: dict[str, float], peer: Callable[..., Bus]
) -> None:
    from mjnav.services.sim import SimBridge, SimConfig
    from mjnav.sim import SimRunner, Simulator

    # 40 Hz passes the rate check (200 = 5 x 40) but is 12.5 steps of 2 ms: clocks would go out late or never.
    sim = Simulator("empty", seed=0)
    bridge = SimBridge(sim, peer(), SimConfig(world="empty", **rates))
    with pytest.raises(ValueError, match="whole number of 2 ms physics steps"):
        bridge.attach(SimRunner(sim, rtf=None))


@pytest.mark.e2e
@pytest.mark.parametrize("announce", [True, False])
def test_sim_time_starts_with_the_spawn_pose_on_initialpose(announce: bool, peer: Callable[..., Bus]) -> None:
    """Placing the robot at the world's start is part of the simulated world: the sim's first publications (t = 0)
    tell SLAM where it is, once; `announce_spawn = false` leaves that to an operator."""
    from mjnav.services.sim import SimBridge, SimConfig
    from mjnav.sim import SimRunner, Simulator

    sim = Simulator("rooms", seed=0)
    me = peer()
    got = me.subscribe("initialpose")
    clock = me.subscribe("clock")
    bus = peer()
    config = SimConfig(world="rooms", announce_spawn=announce, spawn_sigma=(0.1, 0.2))
    bridge = SimBridge(sim, bus, config)
    bridge.attach(SimRunner(sim, rtf=None))
    assert bus.publisher("initialpose").wait_for_subscribers(10.0)  # the sim's session knows `me` subscribes
    for k in range(3):
        bridge.advance(k * bridge.clock_period_s)
    assert clock.wait(10.0, lambda c: ros.seconds(c.clock) >= 0.1) is not None
    poses = got.drain()
    if not announce:
        assert poses == []
        return
    assert len(poses) == 1, poses
    (pose,) = poses
    assert ros.seconds(pose.header.stamp) == 0.0 and pose.header.frame_id == "map"
    assert ros.pose_of(pose) == pytest.approx(sim.world.start)
    assert np.diag(ros.planar_covariance(pose)) == pytest.approx([0.01, 0.01, 0.04])


@pytest.mark.e2e
@pytest.mark.parametrize(
    ("delay_s", "rates"),
    [(0.01, {}), (0.03, {}), (0.05, {}), (0.01, {"imu_rate_hz": 20.0}), (0.02, {"odom_rate_hz": 100.0})],
)
def test_the_wheels_take_a_command_exactly_the_actuation_delay_after_the_clock(
    delay_s: float, rates: dict[str, float], peer: Callable[..., Bus]
) -> None:
    """The command a controller computes on clock t drives the wheels from t + actuation_delay_s, whatever the
    sensors' rates (it used to be the IMU's period: imu_rate_hz = 20 silently made it 50 ms)."""
    from mjnav.services.sim import SimBridge, SimConfig
    from mjnav.sim import SimRunner, Simulator

    sim = Simulator("empty", seed=0)
    bus, controller = peer(), peer()
    bridge = SimBridge(sim, bus, SimConfig(world="empty", actuation_delay_s=delay_s, **rates))
    runner = SimRunner(sim, rtf=None)
    bridge.attach(runner)
    seen: list[tuple[float, float]] = []  # (sim time, commanded v) at every physics step, after the bridge's hooks
    runner.add_hook(lambda s: seen.append((s.time_s, s.command[0])))
    marker = bus.subscribe("goal", immediate=True)
    cmd, mark = controller.publisher("cmd_vel"), controller.publisher("goal")
    assert cmd.wait_for_subscribers(5.0) and mark.wait_for_subscribers(5.0)
    tick = bridge.clock_period_s
    for k in range(1, 5):
        bridge.advance(k * tick)  # lockstep rounds without a command
    t0 = 4 * tick  # the controller answers clock t0 ...
    cmd.put(ros.twist(0.3, 0.0))
    mark.put(ros.pose_stamped(0.0, "map", Pose2D(0.0, 0.0, 0.0)))  # ... and the sim has it before the next round
    assert marker.wait(30.0) is not None
    bridge.advance(t0 + tick)
    driven = [t for t, v in seen if v == pytest.approx(0.3)]
    assert driven, "the command never reached the wheels"
    assert driven[0] == pytest.approx(t0 + delay_s, abs=1e-9)
    assert all(v == 0.0 for t, v in seen if t < t0 + delay_s - 1e-9)


@pytest.mark.parametrize(("delay_s", "error"), [(0.0, "> 0"), (0.06, "at most one clock period")])
def test_an_actuation_delay_outside_one_clock_period_is_refused(delay_s: float, error: str) -> None:
    from mjnav.services.sim import SimConfig

    with pytest.raises(ValueError, match=error):
        SimConfig(world="empty", actuation_delay_s=delay_s)


def test_an_actuation_delay_off_the_physics_steps_is_refused_when_the_sim_is_wired(peer: Callable[..., Bus]) -> None:
    from mjnav.services.sim import SimBridge, SimConfig
    from mjnav.sim import SimRunner, Simulator

    sim = Simulator("empty", seed=0)
    bridge = SimBridge(sim, peer(), SimConfig(world="empty", actuation_delay_s=0.003))
    with pytest.raises(ValueError, match=r"actuation_delay_s .* whole number of 2 ms physics steps"):
        bridge.attach(SimRunner(sim, rtf=None))
