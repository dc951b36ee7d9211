"""SimRunner: hooks run on their sim-time schedule; the run covers exactly the requested sim time."""

from __future__ import annotations

import math
import time

import pytest

from mjnav.sim import InvalidCommandError, SimRunner, Simulator


def test_hooks_run_on_schedule_and_the_end_time_is_exclusive() -> None:
    sim = Simulator("empty", seed=0, lidar=None)
    runner = SimRunner(sim, rtf=None)
    frames: list[float] = []
    fast: list[int] = []
    runner.add_hook(lambda s: frames.append(s.time_s), 1.0 / 30.0)
    runner.add_hook(lambda s: fast.append(s.step_count), None)
    stats = runner.run(3.0)
    assert stats.sim_time_s == pytest.approx(3.0)
    assert stats.steps == 1500
    assert sim.time_s == pytest.approx(3.0)
    assert len(frames) == 90
    assert frames[0] == 0.0
    assert all(-1e-12 <= t - k / 30.0 < 0.002 for k, t in enumerate(frames))  # the first 2 ms step at or after
    assert fast == list(range(1500))


def test_advance_in_slices_calls_each_hook_once_per_due_time_including_the_time_reached() -> None:
    sim = Simulator("empty", seed=0, lidar=None)
    runner = SimRunner(sim, rtf=None)
    ticks: list[int] = []
    runner.add_hook(lambda s: ticks.append(s.step_count), 0.01)  # every 5 steps
    for target in (0.0, 0.013, 0.013, 0.05, 0.1):  # uneven slices, one repeated
        runner.advance(target)
        assert sim.step_count == round(target / 0.002)
    assert ticks == list(range(0, 51, 5))  # 0 … 0.1 s, the last at the time reached, none twice
    start = sim.step_count
    runner.advance(math.inf, wall_deadline=time.perf_counter())  # a spent budget: due hooks only, no stepping
    assert sim.step_count == start and ticks[-1] == 50


def test_a_controller_hook_keeps_the_watchdog_fed_and_should_stop_ends_the_run() -> None:
    sim = Simulator("empty", seed=0, lidar=None)
    runner = SimRunner(sim, rtf=None)
    runner.add_hook(lambda s: s.set_command(0.4, 0.0), 0.1)
    stats = runner.run(2.0, should_stop=lambda: sim.ground_truth_pose().x > 0.5)
    assert stats.stopped_early
    assert 0.5 < sim.ground_truth_pose().x < 0.6
    assert not sim.watchdog_tripped
    stats = runner.run(1.0)  # a second run continues from where the first stopped
    assert not stats.stopped_early and stats.sim_time_s == pytest.approx(1.0)


def test_paced_run_reaches_the_same_state_as_an_unpaced_one() -> None:
    states = []
    for rtf in (None, 20.0):
        sim = Simulator("rooms", seed=5)
        runner = SimRunner(sim, rtf=rtf)
        runner.add_hook(lambda s: s.set_command(0.3, 0.5), 0.1)
        runner.run(0.5)
        states.append((sim.ground_truth_pose(), sim.odometry().pose))
    assert states[0] == states[1]


def test_bad_runner_arguments_are_typed_errors() -> None:
    sim = Simulator("empty", seed=0, lidar=None)
    with pytest.raises(InvalidCommandError):
        SimRunner(sim, rtf=0.0)
    runner = SimRunner(sim, rtf=None)
    with pytest.raises(InvalidCommandError):
        runner.add_hook(lambda s: None, -1.0)
    with pytest.raises(InvalidCommandError):
        runner.run(-1.0)
