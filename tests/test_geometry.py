"""SE(2) poses, angle wrapping and the pose history."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mjnav.geometry import Pose2D, PoseHistory, angle_diff, interpolate_pose, wrap_angle, wrap_angles


def test_wrapping() -> None:
    assert wrap_angle(math.pi) == pytest.approx(-math.pi)
    assert wrap_angle(3 * math.pi / 2) == pytest.approx(-math.pi / 2)
    assert angle_diff(math.radians(170), math.radians(-170)) == pytest.approx(math.radians(-20))
    np.testing.assert_allclose(wrap_angles([0.0, 2 * math.pi + 0.1, -math.pi - 0.1]), [0.0, 0.1, math.pi - 0.1])


def test_compose_inverse_and_transforms_hand_worked() -> None:
    a = Pose2D(1.0, 2.0, math.pi / 2)
    b = Pose2D(1.0, 0.0, 0.0)
    ab = a * b  # one metre "forward" of a, which faces +y
    assert (ab.x, ab.y) == pytest.approx((1.0, 3.0)) and ab.theta == pytest.approx(math.pi / 2)
    ident = a * a.inverse()
    assert (ident.x, ident.y, ident.theta) == pytest.approx((0.0, 0.0, 0.0), abs=1e-12)
    pts = np.array([[1.0, 0.0], [0.0, 1.0]])
    world = a.transform_points(pts)
    np.testing.assert_allclose(world, [[1.0, 3.0], [0.0, 2.0]], atol=1e-12)
    np.testing.assert_allclose(a.to_local(world), pts, atol=1e-12)
    np.testing.assert_allclose(a.matrix() @ [1.0, 0.0, 1.0], [1.0, 3.0, 1.0], atol=1e-12)
    with pytest.raises(ValueError):
        Pose2D(math.nan, 0.0, 0.0)


def test_interpolation_takes_the_short_way_round() -> None:
    p = interpolate_pose(Pose2D(0.0, 0.0, math.radians(170)), Pose2D(2.0, 0.0, math.radians(-170)), 0.5)
    assert (p.x, p.y) == (1.0, 0.0)
    assert abs(p.theta) == pytest.approx(math.pi)


def test_pose_history_interpolates_extrapolates_briefly_and_forgets() -> None:
    h = PoseHistory(horizon_s=1.0)
    assert h.at(0.0) is None
    h.add(0.0, Pose2D(0.0, 0.0, 0.0))
    h.add(0.1, Pose2D(1.0, 0.0, 0.0))
    h.add(0.05, Pose2D(9.0, 9.0, 0.0))  # out of order: ignored
    assert h.at(0.025).x == pytest.approx(0.25)
    assert h.at(0.14).x == 1.0 and h.at(0.2) is None  # 40 ms past the end is kept, 100 ms is not
    for k in range(2, 30):
        h.add(0.1 * k, Pose2D(float(k), 0.0, 0.0))
    assert len(h) <= 12 and h.at(0.5) is None  # older than the horizon
    assert h.latest() == (pytest.approx(2.9), Pose2D(29.0, 0.0, 0.0))
