"""Pose-graph optimiser on synthetic graphs with known answers (mjnav.estimation.posegraph)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mjnav.estimation import (
    EstimationError,
    PoseGraph,
    PoseGraphError,
    certify_global_optimality,
    g2o_chi2,
    odometry_guess,
    optimize_pose_graph,
    sesync_objective,
    sesync_weights,
)
from mjnav.estimation.posegraph import _g2o_errors, _Problem, _sesync_matrix, _wrap


def relative(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(dx, dy, dθ) of pose b in the frame of pose a (rows)."""
    c, s = np.cos(a[:, 2]), np.sin(a[:, 2])
    dx, dy = b[:, 0] - a[:, 0], b[:, 1] - a[:, 1]
    return np.stack([c * dx + s * dy, -s * dx + c * dy, _wrap(b[:, 2] - a[:, 2])], axis=1)


def trajectory(rng: np.random.Generator, n: int) -> np.ndarray:
    """A wandering planar trajectory: (n, 3) poses, about 1 m steps."""
    poses = np.zeros((n, 3))
    for k in range(1, n):
        th = poses[k - 1, 2]
        step = np.array([1.0 + 0.2 * rng.standard_normal(), 0.2 * rng.standard_normal()])
        poses[k, 0] = poses[k - 1, 0] + math.cos(th) * step[0] - math.sin(th) * step[1]
        poses[k, 1] = poses[k - 1, 1] + math.sin(th) * step[0] + math.cos(th) * step[1]
        poses[k, 2] = _wrap(np.array(th + 0.3 * rng.standard_normal()))
    return poses


def make_graph(
    truth: np.ndarray,
    closures: list[tuple[int, int]],
    info: np.ndarray | None = None,
    noise: float = 0.0,
    rng: np.random.Generator | None = None,
) -> PoseGraph:
    """Odometry k → k+1 plus the given loop closures, measured from ``truth`` (+ optional noise)."""
    n = truth.shape[0]
    edges = np.array([(k, k + 1) for k in range(n - 1)] + closures, dtype=np.int64)
    z = relative(truth[edges[:, 0]], truth[edges[:, 1]])
    if noise:
        assert rng is not None
        z = z + noise * rng.standard_normal(z.shape) * np.array([1.0, 1.0, 0.2])
    if info is None:
        info = np.diag([100.0, 80.0, 500.0])
    infos = np.broadcast_to(info, (edges.shape[0], 3, 3)).copy()
    return PoseGraph(truth.copy(), edges, z, infos)


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(7)


def test_exact_measurements_give_zero_error_from_a_perturbed_guess(rng: np.random.Generator) -> None:
    truth = trajectory(rng, 40)
    graph = make_graph(truth, [(0, 39), (5, 30), (10, 25)], info=np.array([[90.0, 10, 2], [10, 70, -3], [2, -3, 400]]))
    guess = truth + np.r_[[[0.0, 0.0, 0.0]], 0.05 * rng.standard_normal((39, 3))]
    start = graph.with_poses(guess)
    for objective in ("sesync", "g2o"):
        for init in ("chordal", "graph"):
            res = optimize_pose_graph(start, objective=objective, init=init)
            assert res.converged
            assert res.chi2 < 1e-12 and res.sesync_objective < 1e-12
            assert res.initial_chi2 > 1.0
            np.testing.assert_allclose(res.poses[:, :2], truth[:, :2], atol=1e-7)
            np.testing.assert_allclose(_wrap(res.poses[:, 2] - truth[:, 2]), 0.0, atol=1e-8)


def test_gauss_newton_also_reaches_the_exact_answer(rng: np.random.Generator) -> None:
    truth = trajectory(rng, 15)
    graph = make_graph(truth, [(0, 14)])
    guess = truth + np.r_[[[0.0, 0.0, 0.0]], 0.02 * rng.standard_normal((14, 3))]
    res = optimize_pose_graph(graph.with_poses(guess), method="gn", init="graph", objective="g2o")
    np.testing.assert_allclose(res.poses, truth, atol=1e-7)


def test_vertex_zero_is_the_gauge(rng: np.random.Generator) -> None:
    truth = trajectory(rng, 12)
    truth[:, :2] += [3.0, -2.0]
    graph = make_graph(truth, [(0, 11)], noise=0.05, rng=rng)
    res = optimize_pose_graph(graph)
    np.testing.assert_array_equal(res.poses[0], truth[0])


def test_noisy_graph_lowers_both_objectives_and_is_certified(rng: np.random.Generator) -> None:
    truth = trajectory(rng, 60)
    closures = [(0, 59), (10, 50), (20, 40), (5, 33)]
    graph = make_graph(truth, closures, noise=0.05, rng=rng).with_poses(odometry_guess(make_graph(truth, closures)))
    noisy = make_graph(truth, closures, noise=0.05, rng=np.random.default_rng(3))
    start = noisy.with_poses(odometry_guess(noisy))
    res = optimize_pose_graph(start, certify=True)
    assert res.sesync_objective < res.initial_sesync_objective and res.chi2 < res.initial_chi2
    assert res.certificate is not None and res.certificate.certified
    assert abs(res.certificate.lambda_min) <= res.certificate.tolerance
    assert res.certificate.stationarity < 1e-6
    # A global minimum of F: perturbing any pose raises F.
    for k in (1, 30, 59):
        bumped = res.poses.copy()
        bumped[k] += [0.01, -0.01, 0.01]
        assert sesync_objective(start, bumped) > res.sesync_objective
    # Minimising χ² instead gives a lower χ² and a higher F.
    res_g2o = optimize_pose_graph(start, objective="g2o")
    assert res_g2o.chi2 <= res.chi2 + 1e-9
    assert res_g2o.sesync_objective >= res.sesync_objective - 1e-9
    assert graph.num_vertices == 60


def test_objectives_by_hand() -> None:
    # Vertex 1 is 0.1 m too far along x and 0.2 rad too far in θ; vertex 0 is rotated by 90°.
    info = np.array([[[4.0, 1.0, 0.0], [1.0, 2.0, 0.0], [0.0, 0.0, 9.0]]])
    graph = PoseGraph(
        poses=np.array([[1.0, 2.0, math.pi / 2], [1.0, 3.1, math.pi / 2 + 0.7]]),
        edges=np.array([[0, 1]]),
        measurements=np.array([[1.0, 0.0, 0.5]]),
        information=info,
    )
    # g2o: e = R_zᵀ (R_iᵀ (t_j − t_i) − t_z) = R(−0.5) (0.1, 0), angle 0.2.
    e = np.array([math.cos(0.5) * 0.1, -math.sin(0.5) * 0.1, 0.2])
    assert g2o_chi2(graph) == pytest.approx(e @ info[0] @ e, rel=1e-12)
    kappa, tau = sesync_weights(graph)
    assert kappa[0] == 9.0
    assert tau[0] == pytest.approx(2.0 / np.trace(np.linalg.inv(info[0, :2, :2])))
    # F: κ‖R_j − R_i R_z‖²_F = 4κ(1 − cos 0.2); τ‖t_j − t_i − R_i t_z‖² = τ·0.1².
    expected = 4.0 * 9.0 * (1.0 - math.cos(0.2)) + tau[0] * 0.01
    assert sesync_objective(graph) == pytest.approx(expected, rel=1e-12)
    # The certificate's quadratic form reproduces F.
    m = _sesync_matrix(graph)
    p = graph.poses
    x = np.concatenate([p[:, 0] + 1j * p[:, 1], np.exp(1j * p[:, 2])])
    assert np.real(np.conj(x) @ (m @ x)) == pytest.approx(expected, rel=1e-12)


def test_quadratic_form_matches_f_on_a_random_graph(rng: np.random.Generator) -> None:
    truth = trajectory(rng, 20)
    graph = make_graph(truth, [(0, 19), (3, 12)], noise=0.1, rng=rng)
    poses = truth + 0.3 * rng.standard_normal(truth.shape)
    m = _sesync_matrix(graph)
    x = np.concatenate([poses[:, 0] + 1j * poses[:, 1], np.exp(1j * poses[:, 2])])
    assert np.real(np.conj(x) @ (m @ x)) == pytest.approx(sesync_objective(graph, poses), rel=1e-10)


@pytest.mark.parametrize("objective", ["sesync", "g2o"])
@pytest.mark.parametrize("robust", [None, "huber", "cauchy"])
def test_gradient_and_hessian_match_finite_differences(objective: str, robust: str | None) -> None:
    rng = np.random.default_rng(11)
    truth = trajectory(rng, 6)
    graph = make_graph(truth, [(0, 5), (1, 4)], noise=0.3, rng=rng)
    p = truth + 0.2 * rng.standard_normal(truth.shape)
    problem = _Problem(graph, objective, robust, 1.0)  # type: ignore[arg-type]
    h_gn, h, g, cost = problem.normal_equations(p)
    assert np.all(np.linalg.eigvalsh(h_gn.toarray()) > -1e-9)  # Gauss–Newton's half: positive semidefinite
    assert cost == pytest.approx(problem.cost(p)[0])
    eps = 1e-6
    num = np.zeros(g.size)
    for k in range(g.size):
        dp = np.zeros_like(p)
        dp[1:].flat[k] = eps
        num[k] = (problem.cost(p + dp)[0] - problem.cost(p - dp)[0]) / (2 * eps)
    np.testing.assert_allclose(2 * g, num, rtol=1e-5, atol=1e-6)  # cost = Σ ρ(‖r‖²): g is half
    if objective == "sesync" and robust is None:  # exact Newton: H is the true Hessian of F
        hd = h.toarray()
        for k in range(g.size):
            dp = np.zeros_like(p)
            dp[1:].flat[k] = eps
            gp = problem.normal_equations(p + dp)[2]
            gm = problem.normal_equations(p - dp)[2]
            np.testing.assert_allclose(hd[:, k], (gp - gm) / (2 * eps), rtol=1e-4, atol=1e-4)  # both halves


def test_g2o_gauss_newton_hessian_is_jt_omega_j_of_finite_difference_jacobians() -> None:
    # The g2o blocks (a numba kernel) against Jᵀ Ω J with J the finite-difference Jacobian of the edge errors.
    rng = np.random.default_rng(12)
    truth = trajectory(rng, 6)
    graph = make_graph(truth, [(0, 5), (1, 4), (2, 5)], noise=0.3, rng=rng)
    p = truth + 0.2 * rng.standard_normal(truth.shape)
    h_gn = _Problem(graph, "g2o", None, 1.0).normal_equations(p)[0].toarray()
    eps = 1e-6
    jac = np.zeros((graph.num_edges, 3, h_gn.shape[0]))
    for k in range(h_gn.shape[0]):
        dp = np.zeros_like(p)
        dp[1:].flat[k] = eps
        jac[:, :, k] = (_g2o_errors(graph, p + dp) - _g2o_errors(graph, p - dp)) / (2 * eps)
    expected = np.einsum("eak,eab,ebl->kl", jac, graph.information, jac)
    np.testing.assert_allclose(h_gn, expected, rtol=1e-5, atol=1e-5 * np.abs(expected).max())


def test_robust_kernels_down_weight_an_outlier_loop_closure(rng: np.random.Generator) -> None:
    truth = trajectory(rng, 50)
    closures = [(0, 49), (10, 40), (15, 35), (20, 30), (5, 45)]
    graph = make_graph(truth, closures, noise=0.01, rng=rng)
    # An outlier: a closure claiming vertex 44 sits 3 m sideways and 1 rad turned from vertex 12.
    z = np.vstack([graph.measurements, [0.0, 3.0, 1.0]])
    edges = np.vstack([graph.edges, [12, 44]])
    info = np.concatenate([graph.information, graph.information[:1]])
    bad = PoseGraph(graph.poses, edges, z, info)
    start = bad.with_poses(odometry_guess(bad))

    def err(poses: np.ndarray) -> float:
        return float(np.max(np.hypot(*(poses[:, :2] - truth[:, :2]).T)))

    plain = optimize_pose_graph(start)
    errors = {None: err(plain.poses)}
    for kernel in ("huber", "cauchy"):
        res = optimize_pose_graph(start, robust=kernel)
        errors[kernel] = err(res.poses)
        assert res.cost < res.chi2  # the kernel caps the outlier's share
    assert errors[None] > 0.3
    assert errors["cauchy"] < 0.1
    assert errors["huber"] < errors[None] / 2


def test_certificate_rejects_a_local_minimum() -> None:
    # Ten poses at one spot, each measured 36° from the previous around the ring, with zero translations: F's
    # rotation part is Σ 4κ(1 − cos e_k). Poses turned by 2·36° each wind once more around the circle: every
    # error is 36°, equal errors balance at each vertex (a critical point, a local minimum), but F > 0 = the
    # global minimum, so the certificate must fail.
    n = 10
    step = 2 * math.pi / n
    edges = np.array([(k, (k + 1) % n) for k in range(n)])
    z = np.tile([0.0, 0.0, step], (n, 1))
    info = np.tile(np.diag([10.0, 10.0, 5.0]), (n, 1, 1))
    wound = np.zeros((n, 3))
    wound[:, 2] = _wrap(2 * step * np.arange(n))
    graph = PoseGraph(wound, edges, z, info)
    assert sesync_objective(graph) > 1.0
    cert = certify_global_optimality(graph)
    assert cert.stationarity < 1e-12  # a critical point …
    assert not cert.certified and cert.lambda_min < -1.0  # … that is not the global minimum
    best = optimize_pose_graph(graph, certify=True)  # the chordal start finds the global one
    assert best.sesync_objective < 1e-12
    assert best.certificate is not None and best.certificate.certified


def test_odometry_guess_composes_and_bridges_a_broken_chain(rng: np.random.Generator) -> None:
    truth = trajectory(rng, 10)
    graph = make_graph(truth, [(2, 8)])
    np.testing.assert_allclose(odometry_guess(graph), truth, atol=1e-12)
    # Remove odometry 4 → 5 and reverse 6 → 7: the tree uses the closure 2 → 8 and the inverted edge.
    keep = [k for k in range(graph.num_edges) if tuple(graph.edges[k]) != (4, 5)]
    edges = graph.edges[keep].copy()
    z = graph.measurements[keep].copy()
    k67 = int(np.flatnonzero((edges[:, 0] == 6) & (edges[:, 1] == 7))[0])
    edges[k67] = [7, 6]
    z[k67] = relative(truth[7:8], truth[6:7])[0]
    broken = PoseGraph(np.zeros_like(truth), edges, z, graph.information[keep])
    guess = odometry_guess(broken.with_poses(np.tile(truth[:1], (10, 1))))
    np.testing.assert_allclose(guess, truth, atol=1e-12)


def test_invalid_graphs_and_options_raise() -> None:
    poses = np.zeros((3, 3))
    edges = np.array([[0, 1], [1, 2]])
    z = np.zeros((2, 3))
    info = np.tile(np.eye(3), (2, 1, 1))
    PoseGraph(poses, edges, z, info)
    with pytest.raises(PoseGraphError, match="edge indices"):
        PoseGraph(poses, np.array([[0, 1], [1, 3]]), z, info)
    with pytest.raises(PoseGraphError, match="itself"):
        PoseGraph(poses, np.array([[0, 1], [2, 2]]), z, info)
    with pytest.raises(PoseGraphError, match="positive definite"):
        PoseGraph(poses, edges, z, np.tile(np.diag([1.0, 1.0, 0.0]), (2, 1, 1)))
    with pytest.raises(PoseGraphError, match="symmetric"):
        PoseGraph(poses, edges, z, np.tile(np.array([[1.0, 0.5, 0], [0, 1, 0], [0, 0, 1]]), (2, 1, 1)))
    with pytest.raises(PoseGraphError, match="finite"):
        PoseGraph(np.full((3, 3), np.nan), edges, z, info)
    disconnected = PoseGraph(np.zeros((4, 3)), edges, z, info)
    with pytest.raises(PoseGraphError, match="disconnected"):
        optimize_pose_graph(disconnected)
    graph = PoseGraph(poses, edges, z, info)
    with pytest.raises(PoseGraphError, match="robust"):
        optimize_pose_graph(graph, robust="tukey")  # type: ignore[arg-type]
    with pytest.raises(PoseGraphError, match="method"):
        optimize_pose_graph(graph, method="dogleg")  # type: ignore[arg-type]
    with pytest.raises(PoseGraphError, match="poses must be"):
        g2o_chi2(graph, np.zeros((2, 3)))
    assert issubclass(PoseGraphError, ValueError) and issubclass(PoseGraphError, EstimationError)


def test_graph_copies_its_inputs() -> None:
    poses = np.zeros((2, 3))
    graph = PoseGraph(poses, np.array([[0, 1]]), np.array([[1.0, 0.0, 0.0]]), np.eye(3)[None])
    poses[1, 0] = 5.0  # the caller's array stays writable …
    assert graph.poses[1, 0] == 0.0  # … and the graph does not change
    with pytest.raises(ValueError):
        graph.poses[0, 0] = 1.0
