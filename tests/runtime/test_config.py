"""Config dataclasses from TOML: types, unknown keys, ranges, overrides; the stack file."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import pytest

from mjnav.runtime import ConfigError, build_config, load_stack, parse_override


@dataclass(frozen=True)
class DemoConfig:
    rate_hz: float = 10.0
    lookahead_m: float = 0.5
    retries: int = 3
    algorithm: Literal["astar", "dijkstra"] = "astar"
    gains: tuple[float, float] = (1.0, 2.0)
    prior_map: Path | None = None

    def __post_init__(self) -> None:
        if not self.lookahead_m > 0:
            raise ValueError(f"lookahead_m must be > 0, got {self.lookahead_m}")


def test_values_are_converted_and_checked() -> None:
    cfg = build_config(DemoConfig, {"rate_hz": 20, "gains": [3, 4.5], "prior_map": "maps/a.yaml"})
    assert cfg.rate_hz == 20.0 and isinstance(cfg.rate_hz, float)
    assert cfg.gains == (3.0, 4.5) and cfg.prior_map == Path("maps/a.yaml")
    assert build_config(DemoConfig, {}) == DemoConfig()


@pytest.mark.parametrize(
    ("data", "match"),
    [
        ({"rate": 1.0}, r"unknown key\(s\) \['rate'\]"),
        ({"rate_hz": "fast"}, "rate_hz: expected a number"),
        ({"rate_hz": True}, "rate_hz: expected a number"),
        ({"retries": 2.5}, "retries: expected an integer"),
        ({"algorithm": "rrt"}, "must be one of"),
        ({"gains": [1.0]}, "expected 2 values"),
        ({"lookahead_m": -1.0}, "lookahead_m must be > 0"),
        ({"rate_hz": float("nan")}, "must be finite"),
    ],
)
def test_bad_values_name_key_and_file(data: dict, match: str) -> None:
    with pytest.raises(ConfigError, match=match) as info:
        build_config(DemoConfig, data, "planner.toml")
    assert str(info.value).startswith("planner.toml")


def test_parse_override() -> None:
    assert parse_override("rate_hz=20") == ("rate_hz", 20)
    assert parse_override("world=maze") == ("world", "maze")
    assert parse_override("gains=[1, 2]") == ("gains", [1, 2])
    assert parse_override("flag = true") == ("flag", True)
    with pytest.raises(ConfigError):
        parse_override("novalue")


def test_stack_file(tmp_path: Path) -> None:
    (tmp_path / "k.toml").write_text("max_speed_mps = 0.5\n")
    (tmp_path / "stack.toml").write_text(
        'namespace = "fleet"\n[[service]]\nname = "kinematic"\n'
        'class = "tests.services.kinematic:KinematicRobot"\nconfig = "k.toml"\n'
    )
    stack = load_stack(tmp_path / "stack.toml")
    assert stack.namespace == "fleet" and stack.names() == ["kinematic"]
    spec = stack.get("kinematic")
    assert spec.load_config().max_speed_mps == 0.5
    assert spec.load_config({"rate_hz": 5}).rate_hz == 5.0
    with pytest.raises(ConfigError, match="valid keys"):
        spec.load_config({"max_speed": 1})
    with pytest.raises(ConfigError, match="services: kinematic"):
        stack.get("planner")
    (tmp_path / "dup.toml").write_text(
        '[[service]]\nname = "a"\nclass = "x:Y"\n[[service]]\nname = "a"\nclass = "x:Y"\n'
    )
    with pytest.raises(ConfigError, match="duplicate"):
        load_stack(tmp_path / "dup.toml")
    (tmp_path / "badclass.toml").write_text('[[service]]\nname = "a"\nclass = "mjnav.geometry:Pose2D"\n')
    with pytest.raises(ConfigError, match="not a Service subclass"):
        load_stack(tmp_path / "badclass.toml").get("a").load_config()


def test_the_shipped_stack_loads_and_every_config_validates() -> None:
    stack = load_stack()
    assert stack.services, "services/stack.toml defines no service"
    for spec in stack.services:
        cfg = spec.load_config()
        assert cfg.rate_hz > 0
