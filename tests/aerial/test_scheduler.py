"""Onboard scheduler: exact invocation counts on sim time, the seed's fixed order, overrun counting."""

from __future__ import annotations

import pytest

from mjnav.aerial import InvalidParameterError, Scheduler, Task, default_task_table
from mjnav.aerial.scheduler import SEED_TASK_ORDER


def test_exact_counts_over_ten_seconds() -> None:
    sched = Scheduler(default_task_table(), base_rate_hz=1000.0)
    sched.run_for(10.0)
    assert sched.tick_count == 10_000
    assert sched.invocations() == {
        "IMU": 10_000,
        "DAQ": 5_000,
        "CAM": 300,
        "CTL": 2_500,
        "SVO": 2_500,
        "NET": 500,
        "CMM": 100,
        "DLG": 100,
    }
    assert sched.skipped_releases == 0


def test_run_until_and_tuple_rows() -> None:
    sched = Scheduler([("IMU", 1000.0, 100.0, 2), ("CTL", 250.0, 150.0, 1)], base_rate_hz=1000.0, t0_s=2.0)
    sched.run_until(3.0)
    assert sched.invocations() == {"IMU": 1000, "CTL": 250}
    assert sched.now_s == pytest.approx(3.0)
    sched.run(0.5)
    assert sched.invocations()["IMU"] == 1500


def test_counts_for_rates_that_do_not_divide_the_base() -> None:
    tasks = [Task("A", 333.0, 10.0), Task("B", 7.0, 10.0), Task("C", 1000.0 / 3.0, 10.0)]
    sched = Scheduler(tasks, base_rate_hz=1000.0)
    for k in range(2500):
        sched.tick(k / 1000.0)  # the caller's sim time
    n = sched.invocations()
    # runs at ticks 0 .. 2499: floor(2499 · f / 1000) + 1
    assert n == {"A": 2499 * 333 // 1000 + 1, "B": 2499 * 7 // 1000 + 1, "C": 2499 // 3 + 1}


def test_fixed_seed_order_within_a_tick() -> None:
    order: list[str] = []
    handlers = {name: (lambda now, name=name: order.append(name)) for name in SEED_TASK_ORDER}
    sched = Scheduler(default_task_table(), handlers=handlers)
    assert [t.name for t in sched.tasks] == list(SEED_TASK_ORDER)
    ran = sched.tick(0.0)
    assert ran == list(SEED_TASK_ORDER) == order
    assert sched.tick(0.001) == ["IMU"]
    assert sched.tick(0.002) == ["IMU", "DAQ"]
    assert sched.tick(0.004) == ["IMU", "DAQ", "CTL", "SVO"]  # 0.003 skipped by the caller: IMU missed one
    assert sched.skipped_releases == 1


def test_overruns_and_frame_overruns() -> None:
    costs = iter([150.0, 90.0] * 10)
    sched = Scheduler(
        [Task("IMU", 1000.0, 100.0), Task("CTL", 500.0, 1000.0)],
        handlers={"IMU": lambda now: next(costs), "CTL": lambda now: 950.0},
    )
    sched.run_for(0.01)
    stats = sched.stats()
    assert stats["IMU"].invocations == 10 and stats["IMU"].overruns == 5
    assert stats["IMU"].max_us == 150.0 and stats["IMU"].total_us == pytest.approx(1200.0)
    assert stats["CTL"].overruns == 0 and stats["CTL"].invocations == 5
    # the frames with CTL take 150 + 950 or 90 + 950 µs > 1000 µs
    assert sched.frame_overruns == 5
    assert sched.overruns() == {"IMU": 5, "CTL": 0}


def test_handlers_receive_sim_time() -> None:
    seen: list[float] = []
    sched = Scheduler([Task("NET", 50.0, 300.0)], base_rate_hz=1000.0, handlers={"NET": seen.append}, t0_s=5.0)
    sched.run_for(0.1)
    assert seen == pytest.approx([5.0 + 0.02 * i for i in range(5)])


def test_bad_tables_are_refused() -> None:
    with pytest.raises(InvalidParameterError):
        Task("X", 0.0, 10.0)
    with pytest.raises(InvalidParameterError):
        Task("X", 10.0, -1.0)
    with pytest.raises(InvalidParameterError):
        Scheduler([Task("A", 10.0, 1.0), Task("A", 5.0, 1.0)])
    with pytest.raises(InvalidParameterError):
        Scheduler([Task("A", 2000.0, 1.0)], base_rate_hz=1000.0)
    with pytest.raises(InvalidParameterError):
        Scheduler([Task("A", 10.0, 1.0)], handlers={"B": lambda now: None})
    sched = Scheduler([Task("A", 10.0, 1.0)])
    sched.tick(1.0)
    with pytest.raises(ValueError):
        sched.tick(0.5)
