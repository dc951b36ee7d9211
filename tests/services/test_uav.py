"""The UAV stack end to end: uav_sim, ins and flight_controller as processes on loopback Zenoh, in lockstep.

Take-off, hover, the figure-8 in wind and the failsafe landing; every assertion is on sim time and sim-time figures.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import pytest

from mjnav.aerial.trajectories import figure8_plan, hover_plan
from mjnav.bus import Bus, BusConfig
from mjnav.commands.fly import fly_on_bus
from mjnav.msgs import ros
from mjnav.sim.uav import UavSimulator
from tests.conftest import REPO, free_port
from tests.services.test_navigation import _mjnav, up_process

pytestmark = pytest.mark.e2e  # processes or a live stack: see pyproject's markers

STACK = str(REPO / "services" / "uav_stack.toml")
SERVICES = ["uav_sim", "ins", "flight_controller"]
#: Figures that depend on the machine (wall time), not on the flight.
WALL_KEYS = {"wall_s", "achieved_rtf"}


def _pad() -> Any:
    return UavSimulator("field").truth().position_m


@contextmanager
def uav_stack(*sets: str) -> Iterator[Bus]:
    """`mjnav up` of the UAV stack (lockstep, as fast as possible, the flight client expected); yields a bus."""
    args = ["--stack", STACK, "--seed", "1", "--set", "uav_sim.rtf=0"]
    args += ["--set", 'uav_sim.lockstep_participants=["ins", "flight_controller", "flight"]']
    for item in sets:
        args += ["--set", item]
    with (
        up_process(*args) as (port, _, lines),
        Bus.open(BusConfig(mode="client", connect=(f"tcp/127.0.0.1:{port}",)), "uav0") as bus,
    ):
        try:
            yield bus
        except AssertionError:
            print("".join(lines)[-4000:])
            raise


def _state_times(summary_states: list[tuple[float, str]], state: str) -> list[float]:
    return [t for t, s in summary_states if s == state]


def test_takeoff_hover_land_then_failsafe_landing_when_setpoints_stop() -> None:
    with uav_stack() as bus:
        # take-off (3 s climb from the pad at t0 = 1 s) and 4 s of hover at 1.5 m, then a commanded landing
        hover = fly_on_bus(bus, SERVICES, hover_plan(_pad(), 1.0, hover_s=4.0), 0.0)
        assert hover.landed and hover.final_state == "disarmed" and hover.collisions == 0
        assert hover.samples == 4 * 50 + 1  # ground truth at 50 Hz over the scored hover
        assert hover.max_error_m < 0.01 and hover.rms_error_m < 0.005
        assert 10.0 < hover.time_s < 16.0  # 1 s on the pad + 3 s climb + 2 s settle + 4 s hover + landing
        assert hover.gps_rms_m > 0.5 and hover.ins_rms_m < hover.gps_rms_m

        # failsafe: the trajectory stops at 6 s (mid-hover); 0.5 s of sim time later the vehicle lands by itself
        from mjnav.runtime.flight import FlightClient

        cfg = json.loads(bus.call("config", service="uav_sim", timeout_s=10.0).data)
        # A participant of its own: the first flight's client ("flight") still takes part in lockstep on this bus, and
        # a second one under the same name made the sim take either's report for both (a race: 1 suite run in 4
        # saw the failsafe 0.02 s early against the arming time).
        client = FlightClient(bus, (cfg["origin_lat_deg"], cfg["origin_lon_deg"], cfg["origin_alt_m"]), name="failsafe")
        sent: list[float] = []  # sim times the trajectory left the client (its header stamp)
        bus.subscribe("trajectory", callback=lambda msg: sent.append(ros.seconds(msg.header.stamp)))
        plan = hover_plan(_pad(), 1.0, hover_s=20.0)
        failsafe = client.fly(plan, timeout_s=40.0, wall_timeout_s=300.0, stream_until_s=6.0)
        states = client.states()
        t_armed = _state_times(states, "armed")[-1]
        t_land = _state_times(states, "failsafe_land")
        assert len(t_land) == 1 and "landing" not in [s for t, s in states if t > t_armed]
        # The stream ran until 6 s after the client's first step, re-sent every 0.2 s (it began once the client saw
        # the vehicle armed, a few ticks in); the controller saw the last one a tick later and landed 0.5 s after
        # that (1e-6: stamps are float sums).
        assert 6.0 - 0.2 - 0.1 - 1e-6 <= sent[-1] - sent[0] < 6.0
        assert sent[-1] + 0.5 - 1e-6 <= t_land[0] <= sent[-1] + 0.5 + 0.04 + 1e-6
        start = t_armed - 0.02  # about the client's first step
        assert failsafe.landed and failsafe.final_state == "disarmed"
        times, track = client.truth_track()
        assert track[-1][2] < 0.1  # on the ground again
        during = track[(times > start + 5.0) & (times < t_land[0])]
        assert during[:, 2].min() > 1.45  # it was hovering until the failsafe


def _fly_twice_alike(args: list[str]) -> dict[str, Any]:
    """Fly ``mjnav fly ARGS`` twice; both summaries must agree on everything but wall-clock figures."""
    runs = []
    for _ in range(2):
        proc = _mjnav(*args, "--port", str(free_port()))
        stdout, _ = proc.communicate(timeout=600)
        assert proc.returncode == 0, stdout[-3000:]
        runs.append(json.loads(stdout.strip().splitlines()[-1]))
    first, second = runs
    assert {k: v for k, v in first.items() if k not in WALL_KEYS} == {
        k: v for k, v in second.items() if k not in WALL_KEYS
    }
    return dict(first)


def test_figure8_rpt_in_wind_meets_the_goal_and_the_same_seed_repeats() -> None:
    args = [
        "fly", "--trajectory", "figure8", "--controller", "rpt", "--state", "mocap", "--wind", "3", "--gust", "6",
        "--seed", "2", "--rtf", "max", "--json", "--headless", "--log-level", "WARNING",
    ]  # fmt: skip
    first = _fly_twice_alike(args)
    assert first["seed"] == 2 and first["trajectory"] == "figure8" and first["landed"] is True
    assert first["rms_error_m"] < 0.02 and first["max_error_m"] < 0.05  # the goal
    assert first["samples"] == 3 * 8 * 50 + 1 and first["collisions"] == 0
    assert first["achieved_rtf"] > 0 and first["time_s"] > 24.0


def test_figure8_on_the_ins_repeats_with_the_same_seed() -> None:
    # The INS's estimate of step t reaches the flight controller before or after clock t, as the router schedules
    # the two links; the controller picks the estimate by stamp, so the flight does not depend on that order.
    args = [
        "fly", "--trajectory", "figure8", "--controller", "rpt", "--state", "ins", "--seed", "3", "--rtf", "max",
        "--json", "--headless", "--log-level", "WARNING",
    ]  # fmt: skip
    first = _fly_twice_alike(args)
    assert first["state"] == "ins" and first["seed"] == 3 and first["landed"] is True
    assert first["max_error_m"] < 1.0 and first["ins_rms_m"] * 4.0 <= first["gps_rms_m"]  # the goals


@pytest.mark.parametrize("frame", ["enu", "ned"])
def test_figure8_on_the_ins_stays_within_a_metre(frame: str) -> None:
    with uav_stack('flight_controller.state_source="ins"', f'ins.frame="{frame}"') as bus:
        summary = fly_on_bus(bus, SERVICES, figure8_plan(_pad(), 10.0, periods=1), 0.0)
    assert summary.landed and summary.collisions == 0
    assert summary.max_error_m < 1.0
    assert summary.ins_rms_m * 4.0 <= summary.gps_rms_m  # the goal: INS >= 4x better than GPS alone
