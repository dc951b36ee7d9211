"""Flight plans of `mjnav fly`: the issue's figure-8 over the scored periods, smooth lead-in, waypoints reached."""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np
import pytest

from mjnav.aerial.trajectories import figure8_plan, hover_plan, waypoints_plan

PAD = np.array([0.0, 0.0, 0.062])


def test_figure8_is_the_issue_formula_over_three_scored_periods() -> None:
    plan = figure8_plan(PAD, 1.0)
    assert plan.measure_to_s - plan.measure_from_s == pytest.approx(24.0)
    t = np.linspace(plan.measure_from_s, plan.measure_to_s, 2001)
    ref = plan.reference(t)
    tau = t - plan.measure_from_s + 1.0  # the 2 s lead-in covers one second of the figure's time
    np.testing.assert_allclose(ref[:, 0], np.sin(2 * math.pi * tau / 8.0), atol=1e-12)
    np.testing.assert_allclose(ref[:, 1], 0.5 * np.sin(4 * math.pi * tau / 8.0), atol=1e-12)
    np.testing.assert_allclose(ref[:, 2], 1.5)
    # from rest on the pad, through the climb and the lead-in, back to rest: no velocity jump anywhere
    dt = 1e-3
    whole = plan.reference(np.arange(0.0, plan.end_s, dt))
    np.testing.assert_allclose(whole[0], PAD)
    acc = np.diff(whole, n=2, axis=0) / dt**2
    assert np.abs(acc).max() < 2.0
    np.testing.assert_allclose(whole[-1] - whole[-2], 0.0, atol=1e-9)


def test_hover_and_waypoints() -> None:
    hover = hover_plan(PAD, 2.0, hover_s=5.0)
    np.testing.assert_allclose(hover.reference(np.array([0.0, 1.9, 9.0])), [PAD, PAD, [0.0, 0.0, 1.5]], atol=1e-12)
    wps = [[2.0, 1.0, 1.5], [-1.0, 2.0, 2.0]]
    plan = waypoints_plan(PAD, 1.0, wps, speed_mps=1.0)
    t = np.arange(0.0, plan.end_s, 0.01)
    ref = plan.reference(t)
    for wp in wps:
        assert np.min(np.linalg.norm(ref - np.array(wp), axis=1)) < 1e-9
    np.testing.assert_allclose(ref[-1], wps[-1], atol=1e-9)
    with pytest.raises(ValueError):
        waypoints_plan(PAD, 1.0, [[0.0, math.nan, 1.0]])


def test_a_waypoints_file_that_is_not_json_says_what_to_write(tmp_path: Path) -> None:
    from mjnav.commands.fly import _plan

    text = tmp_path / "wp.txt"
    text.write_text("0 0 1.0\n1 0 1.5\n", encoding="utf-8")
    args = argparse.Namespace(trajectory=["waypoints", str(text)], state="mocap")
    with pytest.raises(ValueError, match=r"wp\.txt: not JSON .*list of \[x, y, z\] in ENU metres"):
        _plan(args, PAD)
    good = tmp_path / "wp.json"
    good.write_text("[[1.0, 0.0, 1.5]]", encoding="utf-8")
    plan = _plan(argparse.Namespace(trajectory=["waypoints", str(good)], state="mocap"), PAD)
    np.testing.assert_allclose(plan.reference(np.array([plan.end_s]))[0], [1.0, 0.0, 1.5], atol=1e-9)
