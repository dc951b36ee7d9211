"""The seeded landmark world and the scoring helpers the SLAM tests rely on."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mjnav.estimation import InvalidModel
from mjnav.estimation.simulation import (
    nees_bounds,
    pose_nees,
    random_landmarks,
    simulate_landmark_run,
    simulate_loop_world,
    truncate_run,
)
from mjnav.motion import velocity_motion


def test_random_landmarks_are_separated_and_inside_the_bounds() -> None:
    lms = random_landmarks(30, (-5.0, 5.0, 0.0, 8.0), 1.0, np.random.default_rng(2))
    assert lms.shape == (30, 2)
    assert (lms[:, 0] >= -5).all() and (lms[:, 0] <= 5).all() and (lms[:, 1] >= 0).all() and (lms[:, 1] <= 8).all()
    d = np.hypot(*(lms[:, None, :] - lms[None, :, :]).transpose(2, 0, 1))
    assert d[~np.eye(30, dtype=bool)].min() >= 1.0
    with pytest.raises(InvalidModel):
        random_landmarks(50, (0.0, 1.0, 0.0, 1.0), 1.0, np.random.default_rng(0))


def test_noise_free_run_observes_exact_range_and_bearing_within_range() -> None:
    lms = np.array([[2.0, 0.0], [0.0, 3.0], [10.0, 10.0], [-1.0, -1.0]])
    controls = np.array([[1.0, 0.5], [1.0, -0.2], [0.5, 0.0]])
    run = simulate_landmark_run(
        lms,
        controls,
        0.5,
        motion_alphas=np.zeros(6),
        range_std_m=0.0,
        bearing_std_rad=0.0,
        max_range_m=4.0,
        rng=np.random.default_rng(0),
    )
    pose = np.zeros(3)
    for t, (v, w) in enumerate(controls):
        pose = velocity_motion(pose, v, w, 0.5)
        assert np.allclose(run.poses[t + 1], pose)
        ids = run.observation_ids[t]
        assert sorted(ids.tolist()) == [0, 1, 3]  # landmark 2 is out of range
        for (r, b), i in zip(run.observations[t], ids, strict=True):
            dx, dy = lms[i] - pose[:2]
            assert r == pytest.approx(math.hypot(dx, dy))
            assert b == pytest.approx((math.atan2(dy, dx) - pose[2] + math.pi) % (2 * math.pi) - math.pi)


def test_loop_world_is_seeded_and_truncates() -> None:
    a = simulate_loop_world(np.random.default_rng(5))
    b = simulate_loop_world(np.random.default_rng(5))
    assert np.array_equal(a.poses, b.poses) and all(
        np.array_equal(x, y) for x, y in zip(a.observations, b.observations, strict=True)
    )
    assert a.controls.shape == (80, 2) and a.poses.shape == (81, 3) and a.landmarks.shape == (40, 2)
    assert np.hypot(*a.poses[-1, :2]) < 3.0  # one loop: back near the start
    short = truncate_run(a, 10)
    assert short.controls.shape == (10, 2) and len(short.observations) == 10 and short.poses.shape == (11, 3)


def test_nees_helpers() -> None:
    lo, hi = nees_bounds(3, 50)
    assert lo == pytest.approx(2.3597, abs=1e-3) and hi == pytest.approx(3.7160, abs=1e-3)
    cov = np.diag([0.04, 0.01, 0.0025])
    assert pose_nees([0.2, 0.1, 0.0], [0.0, 0.0, 2 * math.pi - 0.05], cov) == pytest.approx(1.0 + 1.0 + 1.0)
    assert pose_nees([0.1, 0.0, 0.0], np.zeros(3), np.zeros((3, 3))) == math.inf
