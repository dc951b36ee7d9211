"""Settings that follow from the sim's world: one source (the MJCF) for the robot's geometry and the map's extent."""

from __future__ import annotations

import json
import re
from pathlib import Path

import mujoco
import pytest

from mjnav.runtime.config import parse_override
from mjnav.runtime.launcher import WORLD_MARGIN_M, Launcher
from mjnav.runtime.stack import load_stack
from mjnav.sim import Simulator, world_info
from mjnav.sim.lidar import LIDAR_NUMERICS, lidar_config_from_model

REPO = Path(__file__).resolve().parents[2]


def _settings(items: list[str]) -> dict[str, object]:
    return {k: json.loads(v) for k, v in (item.split("=", 1) for item in items)}


@pytest.mark.parametrize("world", ["rooms", "maze", "warehouse"])
def test_mjnav_up_sizes_the_costmap_to_the_world_and_takes_the_robot_from_the_model(world: str) -> None:
    launcher = Launcher(load_stack(None), overrides={"sim": [f'world="{world}"']})
    info = world_info(world)
    assert info.bounds_m is not None
    mapper = _settings(launcher.overrides["mapper"])
    x0, y0 = mapper["origin_m"]  # type: ignore[misc]
    x1, y1 = x0 + mapper["width_m"], y0 + mapper["height_m"]  # type: ignore[operator]
    b = info.bounds_m
    # Covers every wall with the margin, and not much more (the 20 x 20 m default was too small for larger maps).
    assert x0 <= b[0] - WORLD_MARGIN_M and y0 <= b[1] - WORLD_MARGIN_M
    assert x1 >= b[2] + WORLD_MARGIN_M and y1 >= b[3] + WORLD_MARGIN_M
    assert x1 - x0 <= b[2] - b[0] + 2 * WORLD_MARGIN_M + 0.1 and y1 - y0 <= b[3] - b[1] + 2 * WORLD_MARGIN_M + 0.1
    res = 0.05  # services/mapper.toml: cells stay aligned to multiples of the resolution
    assert x0 / res == pytest.approx(round(x0 / res)) and y0 / res == pytest.approx(round(y0 / res))
    radius = Simulator(world, lidar=None).robot_radius_m
    assert mapper["robot_radius_m"] == pytest.approx(radius, abs=1e-9) == 0.19  # wheels: 0.14 + 0.05
    assert _settings(launcher.overrides["controller"])["robot_radius_m"] == mapper["robot_radius_m"]
    slam = _settings(launcher.overrides["slam"])
    assert slam["laser_offset_m"] == pytest.approx(list(info.lidar_offset_m)) == [0.0, 0.0, 0.2]
    assert mapper["laser_offset_m"] == slam["laser_offset_m"][:2]  # type: ignore[index]


def test_an_explicit_set_wins_over_the_world() -> None:
    launcher = Launcher(load_stack(None), overrides={"mapper": ["robot_radius_m=0.25", "width_m=40.0"]})
    launcher.check()
    mapper = launcher.specs[[s.name for s in launcher.specs].index("mapper")]
    config = mapper.load_config(dict(parse_override(item) for item in launcher.overrides["mapper"]))
    assert config.robot_radius_m == 0.25 and config.width_m == 40.0


def test_the_configs_do_not_copy_the_robot() -> None:
    # Geometry and sensor parameters live in the robot model only.
    for toml in (REPO / "services").glob("*.toml"):
        text = toml.read_text(encoding="utf-8")
        for key in ("robot_radius_m", "laser_offset_m", "lidar_beams", "lidar_range_max_m", "lidar_noise_std_m"):
            assert not re.search(rf"^\s*{key}\s*=", text, re.M), f"{toml.name} sets {key}"


def test_the_lidar_is_read_from_the_robot_model(tmp_path: Path) -> None:
    sim = Simulator("rooms", seed=0)
    assert sim.lidar_config is not None and sim.lidar_config.num_beams == 360
    assert sim.lidar_scan().ranges_m.shape == (360,)
    # Another robot file with other numerics gives another lidar, without touching any config.
    text = (REPO / "mjcf" / "diffbot.xml").read_text(encoding="utf-8")
    text = text.replace('name="lidar_beams" data="360"', 'name="lidar_beams" data="90"')
    text = text.replace('name="lidar_range_max_m" data="12"', 'name="lidar_range_max_m" data="3.5"')
    model = mujoco.MjModel.from_xml_string(text)
    cfg = lidar_config_from_model(model)
    assert (cfg.num_beams, cfg.range_max_m, cfg.rate_hz) == (90, 3.5, 10.0)
    bad = text.replace('name="lidar_beams" data="90"', 'name="lidar_beams" data="90.5"')
    with pytest.raises(ValueError, match="whole number"):
        lidar_config_from_model(mujoco.MjModel.from_xml_string(bad))
    assert set(LIDAR_NUMERICS.values()) <= set(re.findall(r'numeric name="(lidar_\w+)"', text))


def test_standalone_defaults_agree_with_the_robot_model() -> None:
    # A service run without the launcher (mjnav run, compose) falls back to its dataclass defaults: they must be
    # the bundled robot's values, so nothing drifts from the MJCF unnoticed.
    from mjnav.services.controller import ControllerConfig
    from mjnav.services.mapper import MapperConfig
    from mjnav.services.slam import SlamServiceConfig

    info = world_info("rooms")
    assert MapperConfig().robot_radius_m == pytest.approx(info.robot_radius_m)
    assert ControllerConfig().robot_radius_m == pytest.approx(info.robot_radius_m)
    assert SlamServiceConfig().laser_offset_m == pytest.approx(info.lidar_offset_m)
    assert MapperConfig().laser_offset_m == pytest.approx(info.lidar_offset_m[:2])
