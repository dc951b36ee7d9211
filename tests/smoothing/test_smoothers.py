"""Gradient descent, moving averages and the OSQP quadratic programme."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mjnav.smoothing import (
    InfeasibleProblem,
    PathError,
    gradient_descent,
    moving_average,
    qp_smooth,
    qp_smooth_detailed,
    roughness,
    smoothing_cost,
    triangular_weights,
    weighted_moving_average,
)

THREE = np.array([[0.0, 0.0], [1.0, 1.0], [2.0, 0.0]])
# with one free point s1 the cost ws|x0 - 2 s1 + x2|² + wd|s1 - x1|² is minimised by
# s1 = (4 ws (x0 + x2) + 2 wd x1) / (8 ws + 2 wd) = (1, 0.2 / 8.2) for ws = 1, wd = 0.1
THREE_OPT = np.array([[0.0, 0.0], [1.0, 0.2 / 8.2], [2.0, 0.0]])


def test_gradient_descent_three_points_hand_worked() -> None:
    np.testing.assert_allclose(gradient_descent(THREE, 1.0, 0.1, 1e-12, 100_000), THREE_OPT, atol=1e-9)


def test_qp_three_points_hand_worked_and_boxed() -> None:
    np.testing.assert_allclose(qp_smooth(THREE, max_deviation_m=math.inf), THREE_OPT, atol=1e-12)
    # with a 0.5 m box the single free coordinate is clipped: s1 = (1, 0.5)
    boxed = np.array([[0.0, 0.0], [1.0, 0.5], [2.0, 0.0]])
    np.testing.assert_allclose(qp_smooth(THREE, max_deviation_m=0.5), boxed, atol=1e-9)
    np.testing.assert_allclose(gradient_descent(THREE, max_deviation_m=0.5), boxed, atol=1e-9)


@pytest.mark.parametrize("box", [0.2, 0.1, 0.06])
def test_smoothers_reduce_roughness_inside_box(noisy_path: np.ndarray, box: float) -> None:
    r0 = roughness(noisy_path)
    for out in (
        gradient_descent(noisy_path, max_deviation_m=box),
        qp_smooth(noisy_path, max_deviation_m=box),
    ):
        assert roughness(out) <= 0.2 * r0
        assert np.abs(out - noisy_path).max() <= box + 1e-4
        np.testing.assert_array_equal(out[[0, -1]], noisy_path[[0, -1]])


def test_moving_averages_reduce_roughness(noisy_path: np.ndarray) -> None:
    r0 = roughness(noisy_path)
    for out in (moving_average(noisy_path, 7), weighted_moving_average(noisy_path, triangular_weights(9))):
        assert roughness(out) <= 0.2 * r0
        assert np.abs(out - noisy_path).max() <= 0.2  # ~4σ of the 5 cm noise
        np.testing.assert_array_equal(out[[0, -1]], noisy_path[[0, -1]])


def test_qp_matches_projected_gradient_descent(noisy_path: np.ndarray) -> None:
    box = np.random.default_rng(5).uniform(0.005, 0.08, noisy_path.shape[0])
    qp = qp_smooth(noisy_path, max_deviation_m=box, w_smooth=2.0, w_data=0.3)
    gd = gradient_descent(noisy_path, 2.0, 0.3, 1e-12, 200_000, max_deviation_m=box)
    np.testing.assert_allclose(qp, gd, atol=2e-5)
    assert smoothing_cost(qp, noisy_path, 2.0, 0.3) <= smoothing_cost(gd, noisy_path, 2.0, 0.3) + 1e-9


def test_qp_report(noisy_path: np.ndarray) -> None:
    res = qp_smooth_detailed(noisy_path, max_deviation_m=0.02)
    assert res.status == "solved"
    assert res.osqp_solves == 2 and res.iterations > 0
    assert 0 < res.active_bounds <= 2 * (noisy_path.shape[0] - 2)
    assert res.objective == pytest.approx(smoothing_cost(res.path, noisy_path, 1.0, 0.1))
    free = qp_smooth_detailed(noisy_path, max_deviation_m=math.inf)
    assert free.osqp_solves == 0 and free.active_bounds == 0
    assert free.objective < res.objective


def test_qp_per_point_box_and_pins(noisy_path: np.ndarray) -> None:
    box = np.full(noisy_path.shape[0], 0.05)
    box[50:60] = 0.0  # pinned points
    out = qp_smooth(noisy_path, max_deviation_m=box)
    np.testing.assert_array_equal(out[50:60], noisy_path[50:60])
    assert np.all(np.abs(out - noisy_path) <= box[:, None] + 1e-12)


def test_qp_clearance_keeps_path_out_of_obstacle() -> None:
    # a path grazing a round obstacle of radius 0.5 centred at (5, 0.8); noise pushes points towards it
    rng = np.random.default_rng(9)
    t = np.linspace(0.0, 10.0, 101)
    path = np.c_[t, np.zeros_like(t)] + rng.normal(0.0, 0.04, (101, 2))
    centre, radius = np.array([5.0, 0.8]), 0.5
    clearance = np.linalg.norm(path - centre, axis=1) - radius
    assert clearance.min() > 0.0
    out = qp_smooth(path, max_deviation_m=0.5, clearance=clearance)
    assert np.all(np.linalg.norm(out - centre, axis=1) > radius)
    assert np.all(np.abs(out - path) <= np.minimum(0.5, clearance / math.sqrt(2))[:, None] + 1e-12)


def test_moving_average_hand_worked() -> None:
    p = np.array([[0.0, 0.0], [1.0, 3.0], [2.0, 0.0], [3.0, 3.0], [4.0, 0.0]])
    np.testing.assert_allclose(moving_average(p, 3), [[0, 0], [1, 1], [2, 2], [3, 1], [4, 0]])
    # window 5: the middle point averages all five; its neighbours shrink to 3 points, the ends to 1
    np.testing.assert_allclose(moving_average(p, 5), [[0, 0], [1, 1], [2, 1.2], [3, 1], [4, 0]])
    np.testing.assert_allclose(moving_average(p, 1), p)


def test_weighted_moving_average_hand_worked() -> None:
    p = np.array([[0.0, 0.0], [1.0, 3.0], [2.0, 0.0], [3.0, 3.0], [4.0, 0.0]])
    np.testing.assert_allclose(
        weighted_moving_average(p, [1.0, 2.0, 1.0]), [[0, 0], [1, 1.5], [2, 1.5], [3, 1.5], [4, 0]]
    )
    np.testing.assert_allclose(weighted_moving_average(p, [1.0, 1.0, 1.0]), moving_average(p, 3))
    np.testing.assert_allclose(triangular_weights(5), np.array([1, 2, 3, 2, 1]) / 9)


def test_two_point_paths_pass_through() -> None:
    p = np.array([[0.0, 0.0], [1.0, 1.0]])
    for out in (gradient_descent(p), moving_average(p, 5), qp_smooth(p, max_deviation_m=0.1)):
        np.testing.assert_array_equal(out, p)


def test_bad_input_raises_typed_errors(noisy_path: np.ndarray) -> None:
    bad = noisy_path.copy()
    bad[3, 1] = math.nan
    for fn in (
        lambda p: gradient_descent(p),
        lambda p: moving_average(p, 3),
        lambda p: weighted_moving_average(p, [1.0, 1.0, 1.0]),
        lambda p: qp_smooth(p, max_deviation_m=0.1),
    ):
        with pytest.raises(PathError):
            fn(bad)
        with pytest.raises(PathError):
            fn(noisy_path[:1])
        with pytest.raises(PathError):
            fn(np.zeros((5, 3)))
    with pytest.raises(InfeasibleProblem):
        qp_smooth(noisy_path, max_deviation_m=-0.1)
    with pytest.raises(InfeasibleProblem, match="inside an obstacle"):
        qp_smooth(noisy_path, max_deviation_m=0.1, clearance=np.full(noisy_path.shape[0], -0.01))
    with pytest.raises(ValueError, match="shape"):
        qp_smooth(noisy_path, max_deviation_m=np.ones(7))
    with pytest.raises(ValueError, match="w_data"):
        gradient_descent(noisy_path, 1.0, 0.0)
    with pytest.raises(ValueError, match="odd"):
        moving_average(noisy_path, 4)
    with pytest.raises(ValueError, match="centre weight"):
        weighted_moving_average(noisy_path, [1.0, 0.0, 1.0])


def _bounded_least_squares_reference(path: np.ndarray, box: float, w_smooth: float, w_data: float) -> np.ndarray:
    """The box-constrained optimum from scipy's exact bounded least squares (BVLS), coordinate by coordinate.

    J = w_s‖D s‖² + w_d‖s − x‖² with the end points fixed is ‖A d − b‖² in the interior offsets d = s − x.
    """
    from scipy.optimize import lsq_linear

    n = len(path)
    second = np.zeros((n - 2, n))
    for i in range(n - 2):
        second[i, i : i + 3] = (1.0, -2.0, 1.0)
    out = path.copy()
    for axis in range(2):
        x = path[:, axis]
        a = np.vstack((math.sqrt(w_smooth) * second[:, 1:-1], math.sqrt(w_data) * np.eye(n - 2)))
        b = np.concatenate((-math.sqrt(w_smooth) * (second @ x), np.zeros(n - 2)))
        res = lsq_linear(a, b, bounds=(-box, box), method="bvls", tol=1e-14)
        out[1:-1, axis] += res.x
    return out


@pytest.mark.parametrize("active", ["x", "y", "both", "none"])
def test_qp_is_the_exact_box_constrained_optimum(active: str) -> None:
    # Noise in one coordinate (some boxes bind there, others not) beside a straight line in the other (its
    # unconstrained minimiser fits the box): the presolve may settle only the coordinate whose minimiser is inside;
    # clipping the unconstrained minimiser of the other would not be the optimum.
    t = np.linspace(0.0, 6.0, 61)
    noise = np.random.default_rng(3).normal(0.0, 0.05, (2, 61))
    line = 0.5 * t
    xs = {
        "x": (t + noise[0], line),
        "y": (t, line + noise[1]),
        "both": (t + noise[0], line + noise[1]),
        "none": (t, line),
    }
    path = np.column_stack(xs[active])
    box, w_smooth, w_data = 0.03, 1.0, 0.1
    reference = _bounded_least_squares_reference(path, box, w_smooth, w_data)
    res = qp_smooth_detailed(path, max_deviation_m=box, w_smooth=w_smooth, w_data=w_data)
    np.testing.assert_allclose(res.path, reference, atol=1e-7)
    assert res.osqp_solves == {"x": 1, "y": 1, "both": 2, "none": 0}[active]
    assert res.objective <= smoothing_cost(reference, path, w_smooth, w_data) + 1e-10
