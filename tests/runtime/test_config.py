"""Config dataclasses from TOML: types, unknown keys, ranges, overrides; the stack file."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import pytest

from mjnav.runtime import ConfigError, build_config, load_stack, parse_override
from mjnav.runtime.stack import port_overrides
from tests.conftest import REPO


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


def _processes(only: list[str] | None = None, packed: bool = True) -> dict[str, list[str]]:
    stack = load_stack()
    return {p.name: p.service_names() for p in stack.processes(stack.select(only), packed=packed)}


def test_the_stack_files_containers_pack_the_services_into_processes() -> None:
    # In start order (a container where its first member starts), each container stepping in its own order.
    assert _processes() == {
        "sim": ["sim"],
        "nav": ["controller", "slam", "mapper", "planner", "smoother"],
        "viz": ["viz"],
    }
    assert list(_processes(packed=False).values()) == [[n] for n in load_stack().names()]
    assert _processes(only=["planner", "slam", "sim"]) == {"sim": ["sim"], "nav": ["slam", "planner"]}
    assert _processes(only=["mapper"]) == {"mapper": ["mapper"]}  # a container's only selected member runs alone
    nav = load_stack().container("nav")
    assert nav is not None and nav.container and nav.restarts == 3 and load_stack().container("sim") is None
    uav = load_stack(REPO / "services" / "uav_stack.toml")
    assert [p.service_names() for p in uav.processes(uav.select(None))] == [
        ["uav_sim"],
        ["flight_controller", "ins"],
        ["uav_viz"],
    ]


SERVICES_TOML = (
    '[[service]]\nname = "sim"\nclass = "mjnav.services.sim:SimService"\n'
    '[[service]]\nname = "slam"\nclass = "mjnav.services.slam:SlamService"\n'
    '[[service]]\nname = "viz"\nclass = "mjnav.services.viz:VizService"\n'
    '[[service]]\nname = "ros_bridge"\nclass = "mjnav.services.ros_bridge:RosBridgeService"\n'
)


@pytest.mark.parametrize(
    ("container", "match"),
    [
        ('name = "c"\nservices = ["slam"]\nshelf = 1', r"unknown key\(s\) \['shelf'\]"),
        ('name = "slam"\nservices = ["sim"]', "taken by a service"),
        ('name = "c"\nservices = []', "non-empty list"),
        ('name = "c"\nservices = ["mapper"]', "no service 'mapper' in the stack"),
        ('name = "c"\nservices = ["slam"]\n[[container]]\nname = "d"\nservices = ["slam"]', "already in container c"),
        ('name = "c"\nservices = ["slam"]\nrestarts = -1', "non-negative"),
    ],
)
def test_a_bad_container_is_refused_with_its_place(tmp_path: Path, container: str, match: str) -> None:
    (tmp_path / "stack.toml").write_text(f"{SERVICES_TOML}[[container]]\n{container}\n")
    with pytest.raises(ConfigError, match=match):
        load_stack(tmp_path / "stack.toml")


@pytest.mark.parametrize(
    ("members", "match"),
    [
        ('["sim", "slam"]', r"one clock, sim or wall time: sim \(wall time\), slam \(sim time\)"),
        ('["viz", "ros_bridge"]', "ros_bridge must run in a process of its own"),
    ],
)
def test_a_container_steps_on_one_clock_and_never_hosts_a_lone_service(
    tmp_path: Path, members: str, match: str
) -> None:
    (tmp_path / "stack.toml").write_text(f'{SERVICES_TOML}[[container]]\nname = "c"\nservices = {members}\n')
    stack = load_stack(tmp_path / "stack.toml")
    with pytest.raises(ConfigError, match=match):
        stack.processes(stack.select(None))
    assert len(stack.processes(stack.select(None), packed=False)) == 4  # one per process stays possible


def test_one_port_base_numbers_every_listener_after_the_routers() -> None:
    ground = load_stack().with_services(["foxglove"])
    assert port_overrides(ground.select(None), 9000) == {
        "viz": ["web_port=9001", "zmq_port=9002", "port_search=0"],  # no silent move to another port
        "foxglove": ["port=9003"],
    }
    assert port_overrides(ground.select(["sim", "slam"]), 9000) == {}
    uav = load_stack(REPO / "services" / "uav_stack.toml")
    assert port_overrides(uav.select(None), 7600) == {"uav_viz": ["web_port=7601", "zmq_port=7602", "port_search=0"]}
    with pytest.raises(ConfigError, match="beyond 65535"):
        port_overrides(ground.select(None), 65533)
