"""Robot and world facts have one source each: the robot's MJCF (the sim publishes it) and the world. No service
config, launcher or library default carries a robot number."""

from __future__ import annotations

import ast
import io
import tokenize
import tomllib
from dataclasses import fields
from pathlib import Path

import pytest

from mjnav.robot import parse_robot_description
from mjnav.runtime.config import read_toml
from mjnav.runtime.launcher import Launcher
from mjnav.runtime.stack import OPTIONAL_SERVICES, load_stack, services_dir
from mjnav.sim import Simulator
from tests.conftest import REPO

#: Config keys that would copy a robot or world fact into a service (they came from the launcher once).
FACT_KEYS = {
    "robot_radius_m",
    "laser_offset_m",
    "imu_offset_m",
    "footprint",
    "footprint_m",
    "width_m",
    "height_m",
    "origin_m",
    "wheel_separation_m",
    "wheel_radius_m",
}


def _robot_numbers() -> dict[str, float]:
    """The bundled robot's distinctive dimensions, read from its model (generic ones such as 0.1 m are left out:
    they are everywhere for other reasons)."""
    sim = Simulator("rooms", lidar=None)
    d = sim.description
    return {
        "footprint radius": round(d.radius_m, 6),
        "chassis radius": round(d.inscribed_radius_m, 6),
        "wheel separation": round(sim.wheel_separation_m, 6),
        "half the wheel separation": round(sim.wheel_separation_m / 2, 6),
    }


def _numbers_in(value: object) -> list[float]:
    if isinstance(value, bool):
        return []
    if isinstance(value, int | float):
        return [float(value)]
    if isinstance(value, list | tuple):
        return [v for item in value for v in _numbers_in(item)]
    if isinstance(value, dict):
        return [v for item in value.values() for v in _numbers_in(item)]
    return []


@pytest.mark.e2e
def test_no_robot_number_is_written_outside_mjcf() -> None:
    numbers = _robot_numbers()
    assert numbers == {  # the bundled robot, as its MJCF says
        "footprint radius": 0.19,
        "chassis radius": 0.18,
        "wheel separation": 0.28,
        "half the wheel separation": 0.14,
    }
    found = []
    for path in sorted((REPO / "mjnav").rglob("*.py")):
        for tok in tokenize.generate_tokens(io.StringIO(path.read_text(encoding="utf-8")).readline):
            if tok.type == tokenize.NUMBER:
                value = ast.literal_eval(tok.string)
                found += [f"{path.relative_to(REPO)}:{tok.start[0]}: {what} {tok.string}"
                          for what, n in numbers.items() if value == n]  # fmt: skip
    for path in sorted((REPO / "services").glob("*.toml")):
        data = tomllib.loads(path.read_text(encoding="utf-8"))
        found += [f"{path.relative_to(REPO)}: {what} {v}" for v in _numbers_in(data)
                  for what, n in numbers.items() if v == n]  # fmt: skip
    assert not found, "robot numbers outside mjcf/ (take them from the robot description):\n" + "\n".join(found)


def test_the_number_check_catches_a_copy(tmp_path: Path) -> None:
    """The same scan as above finds a radius written into a config or a default."""
    numbers = set(_robot_numbers().values())
    source = "class C:\n    robot_radius_m: float = 0.19\n"
    toks = tokenize.generate_tokens(io.StringIO(source).readline)
    assert any(t.type == tokenize.NUMBER and float(t.string) in numbers for t in toks)
    assert set(_numbers_in(tomllib.loads("r = [0.0, 0.28]"))) & numbers


def test_no_service_config_has_a_robot_or_world_fact() -> None:
    specs = []
    for stack_file in ("stack.toml", "uav_stack.toml"):
        stack = load_stack(services_dir() / stack_file)
        specs += [stack.get(name) for name in stack.names()]
    specs += [load_stack().get(name) for name in OPTIONAL_SERVICES]
    for spec in specs:
        declared = {f.name for f in fields(spec.load_class().config_class)}
        assert not declared & FACT_KEYS, f"{spec.name} declares {sorted(declared & FACT_KEYS)}"
        if spec.config_file is not None:
            assert not set(read_toml(spec.config_file)) & FACT_KEYS, spec.config_file


@pytest.mark.parametrize("world", ["empty", "rooms", "maze", "warehouse"])
def test_the_launcher_injects_no_robot_or_world_fact(world: str) -> None:
    launcher = Launcher(load_stack(None), overrides={"sim": [f'world="{world}"']}, seed=3)
    run_settings = {"seed", "lockstep", "lockstep_participants"}
    for name, items in launcher.overrides.items():
        keys = {item.split("=", 1)[0] for item in items}
        if name == "sim":
            keys.discard("world")  # the caller's own --set
        assert keys <= run_settings, f"the launcher sets {sorted(keys - run_settings)} for {name}"


@pytest.mark.parametrize(("stack_file", "sim"), [("stack.toml", "sim"), ("uav_stack.toml", "uav_sim")])
def test_the_sim_starts_time_with_every_sim_time_service_of_its_stack(stack_file: str, sim: str) -> None:
    """`mjnav run` and compose start sim time when the stack is there, as `mjnav up` does."""
    stack = load_stack(services_dir() / stack_file)
    expected = [n for n in stack.names() if stack.get(n).load_class().uses_sim_time]
    assert list(stack.get(sim).load_config().lockstep_participants) == expected


def test_another_lidar_is_another_robot_file() -> None:
    text = (REPO / "mjcf" / "diffbot.xml").read_text(encoding="utf-8")
    text = text.replace('name="lidar_beams" data="360"', 'name="lidar_beams" data="90"')
    text = text.replace('name="lidar_range_max_m" data="12"', 'name="lidar_range_max_m" data="3.5"')
    lidar = parse_robot_description(text).lidar
    assert lidar is not None and (lidar.num_beams, lidar.range_max_m, lidar.rate_hz) == (90, 3.5, 10.0)
