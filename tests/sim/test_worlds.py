"""Every MJCF file compiles and steps cleanly; world names resolve; start and goal are sane."""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pytest

import mjnav
from mjnav.geometry import Pose2D
from mjnav.sim import (
    ModelLoadError,
    RobotNotFoundError,
    Simulator,
    UnknownWorldError,
    available_worlds,
    resolve_world,
    world_info,
)

from .helpers import write

MJCF = mjnav.REPO_ROOT / "mjcf"
ALL_MJCF = sorted(MJCF.rglob("*.xml"))


def _warnings(data: mujoco.MjData) -> dict[str, int]:
    return {mujoco.mjtWarning(i).name: int(w.number) for i, w in enumerate(data.warning) if w.number}


def test_bundled_worlds_are_the_four_scenes() -> None:
    assert set(available_worlds()) >= {"empty", "rooms", "maze", "warehouse"}
    assert "diffbot" not in available_worlds()


@pytest.mark.parametrize("path", ALL_MJCF, ids=[str(p.relative_to(MJCF)) for p in ALL_MJCF])
def test_every_mjcf_compiles_and_steps_one_second_without_warnings(path: Path) -> None:
    model = mujoco.MjModel.from_xml_path(str(path))  # the raw file, exactly as MuJoCo's viewer would load it
    data = mujoco.MjData(model)
    model.opt.timestep = 0.002
    if model.nu:
        data.ctrl[:] = 5.0
    mujoco.mj_step(model, data, nstep=500)
    assert data.time == pytest.approx(1.0)
    assert _warnings(data) == {}
    assert np.all(np.isfinite(data.qpos))
    if path.parent == MJCF and path.stem in available_worlds():
        sim = Simulator(path, seed=0)
        sim.set_command(0.2, 0.3)
        sim.step_until(1.0)
        assert sim.mujoco_warnings() == {}
        assert sim.collisions == 0, "the robot must start clear of every obstacle"


@pytest.mark.parametrize("name", ["empty", "rooms", "maze", "warehouse"])
def test_world_info_has_start_goal_and_names_resolve(name: str) -> None:
    info = world_info(name)
    assert info.path == (MJCF / f"{name}.xml").resolve()
    assert resolve_world(name) == info.path
    assert resolve_world(str(info.path)) == info.path
    assert info.goal is not None
    assert info.start.distance_to(info.goal) > 3.0
    if name != "empty":
        assert info.bounds_m is not None
        x0, y0, x1, y1 = info.bounds_m
        for p in (info.start, info.goal):
            assert x0 < p.x < x1 and y0 < p.y < y1


def test_unknown_world_lists_the_available_ones() -> None:
    with pytest.raises(UnknownWorldError) as err:
        resolve_world("atlantis")
    for name in ("empty", "rooms", "maze", "warehouse"):
        assert name in str(err.value)
    assert isinstance(err.value, LookupError)


def test_mjcf_without_robot_is_a_typed_error(tmp_path: Path) -> None:
    path = write(tmp_path, "norobot.xml", '<mujoco><worldbody><geom type="plane" size="1 1 .1"/></worldbody></mujoco>')
    with pytest.raises(RobotNotFoundError, match="no robot"):
        Simulator(path, seed=0)


def test_broken_mjcf_is_a_typed_error(tmp_path: Path) -> None:
    path = write(tmp_path, "broken.xml", "<mujoco><worldbody><geom type='sphere' size='-1'/></mujoco>")
    with pytest.raises(ModelLoadError):
        Simulator(path, seed=0)


def test_start_override_and_robot_dimensions() -> None:
    sim = Simulator("empty", seed=0, start=Pose2D(1.0, -2.0, 0.5))
    pose = sim.ground_truth_pose()
    assert (pose.x, pose.y, pose.theta) == pytest.approx((1.0, -2.0, 0.5))
    assert sim.start_pose == Pose2D(1.0, -2.0, 0.5)
    assert sim.wheel_diameter_m == pytest.approx(0.10)
    assert sim.wheel_separation_m == pytest.approx(0.28)
    assert sim.robot_radius_m == pytest.approx(0.19, abs=1e-6)  # wheel spheres: 0.14 + 0.05
    assert sim.max_speed_mps == pytest.approx(1.0)
    assert sim.robot.wheel_joint_names == ("left_wheel_joint", "right_wheel_joint")
