"""Graph SLAM and localization on a seeded synthetic ring world; Kümmerle's relative error; odometry noise."""

from __future__ import annotations

import math
import pickle

import numpy as np
import pytest

from mjnav.estimation.slam import GraphSlam, Localizer, SlamConfig, SlamError, compose, invert, relative
from mjnav.estimation.slam_metrics import (
    consecutive_relations,
    corrupt_odometry,
    distance_relations,
    relation_error,
    relative_pose_error,
)
from tests.estimation._slam_world import TWO_CORRIDORS, ring_drive, scans, true_map, two_corridor_drive


def _run(loop_candidates: int, seed: int) -> tuple[GraphSlam, np.ndarray, np.ndarray]:
    truth = ring_drive()
    rng = np.random.default_rng(seed)
    angles, ranges = scans(truth, rng, noise_m=0.02)
    odom = corrupt_odometry(truth, rng, (0.05, 0.05, 0.05))
    # A 4 m lidar: the front end drifts by centimetres over the lap, so loop closure has something to correct.
    slam = GraphSlam(SlamConfig(max_range_m=4.0, loop_candidates=loop_candidates), initial_pose=truth[0])
    for k in range(truth.shape[0]):
        est = slam.update(0.1 * k, odom[k], ranges[k], angles, range_min_m=0.1, range_max_m=12.0)
        assert np.allclose(compose(est.map_to_odom, odom[k]), est.pose)
    return slam, truth, odom


@pytest.mark.e2e
@pytest.mark.parametrize("seed", [0, 1])
def test_loop_closure_is_found_and_lowers_the_error(seed: int) -> None:
    with_loops, truth, odom = _run(2, seed)
    without, _, _ = _run(0, seed)
    assert without.loop_closures == 0 and without.optimizations == 0
    assert with_loops.loop_closures >= 1 and with_loops.optimizations >= 1
    # A real loop: some closure joins a keyframe of the first 10 m to one driven after a full lap (≥ 50 m later).
    kf_xy = with_loops.keyframe_poses()[:, :2]
    travel = np.concatenate(([0.0], np.cumsum(np.hypot(*np.diff(kf_xy, axis=0).T))))
    pairs = with_loops.loop_edges()
    assert np.any((travel[pairs[:, 0]] < 10.0) & (travel[pairs[:, 1]] > 50.0))

    def ate(slam: GraphSlam) -> float:
        _, traj = slam.trajectory()
        return float(np.sqrt(np.mean(np.sum((traj[:, :2] - truth[:, :2]) ** 2, axis=1))))

    odom_err = float(np.sqrt(np.mean(np.sum((odom[:, :2] - truth[:, :2]) ** 2, axis=1))))
    assert ate(without) < 0.1 * odom_err  # the front end alone already removes most odometry drift
    assert ate(with_loops) < 0.8 * ate(without)
    assert ate(with_loops) < 0.08
    # The returned estimate's covariance is a proper covariance.
    cov = with_loops.covariance
    assert np.allclose(cov, cov.T) and np.all(np.linalg.eigvalsh(cov) > 0)


@pytest.mark.e2e
def test_a_pickled_slam_continues_exactly_and_leaves_its_caches_behind() -> None:
    """A checkpoint (pickle) holds the state, not the caches derived from it: restored half-way round the ring,
    after loop closures filled the submap cache, the SLAM goes on to the same poses to the last bit."""
    truth = ring_drive()
    rng = np.random.default_rng(0)
    angles, ranges = scans(truth, rng, noise_m=0.02)
    odom = corrupt_odometry(truth, rng, (0.05, 0.05, 0.05))
    slam = GraphSlam(SlamConfig(max_range_m=4.0, loop_candidates=2), initial_pose=truth[0])

    def update(s: GraphSlam, k: int) -> np.ndarray:
        return s.update(0.1 * k, odom[k], ranges[k], angles, range_min_m=0.1, range_max_m=12.0).pose

    k = 0
    while slam.loop_closures == 0:  # drive on until the first closure (the submap cache then holds matchers)
        update(slam, k)
        k += 1
    assert slam._submap_cache and slam._local is not None
    blob = pickle.dumps(slam)
    restored = pickle.loads(blob)
    assert not restored._submap_cache  # rebuilt when the loop search needs it
    assert len(blob) < 0.5 * len(pickle.dumps(slam.__dict__))
    for j in range(k, truth.shape[0]):
        assert np.array_equal(update(restored, j), update(slam, j)), j
    assert restored.loop_closures == slam.loop_closures > 1
    assert np.array_equal(restored.trajectory()[1], slam.trajectory()[1])


@pytest.mark.e2e
def test_loop_edges_carry_the_scaled_match_covariance() -> None:
    with_loops, _, _ = _run(2, 0)
    graph = with_loops.pose_graph()
    cfg = with_loops.config
    loops = set(map(tuple, with_loops.loop_edges().tolist()))
    rows = [r for r, e in enumerate(graph.edges.tolist()) if tuple(e) in loops]
    assert rows
    for r in rows:
        cov = np.linalg.inv(graph.information[r])
        assert math.sqrt(np.linalg.eigvalsh(cov[:2, :2])[0]) == pytest.approx(cfg.loop_sigma_m, rel=1e-6)
        assert cov[2, 2] >= cfg.loop_sigma_rad**2 * (1 - 1e-9)


def test_loop_information_is_soft_along_a_corridor_in_the_keyframes_frame() -> None:
    cfg = SlamConfig()
    slam = GraphSlam(cfg)
    # A PL-ICP covariance of a corridor along the submap's x axis: x ten times less certain than y.
    cov = np.diag([1e-4, 1e-6, 1e-6])
    info = slam._loop_information(cov, math.pi / 2)  # the keyframe faces +y: the corridor is its y axis
    c = np.linalg.inv(info)
    assert math.sqrt(c[0, 0]) == pytest.approx(cfg.loop_sigma_m)  # across the corridor: the loop σ
    assert math.sqrt(c[1, 1]) == pytest.approx(10.0 * cfg.loop_sigma_m)  # along it: ten times softer
    # The heading is scaled by the same factor (σ 1e-3 rad × loop_sigma_m / 1e-3 m), above the loop_sigma_rad floor.
    assert math.sqrt(c[2, 2]) == pytest.approx(max(cfg.loop_sigma_rad, cfg.loop_sigma_m))


def _two_corridors(seed: int, loop_min_overlap: float) -> tuple[GraphSlam, np.ndarray]:
    """East along corridor A, a U-turn, west along the parallel corridor B, with every loop search window 2.3 m
    wide: from B, the search reaches A, whose walls line up with B's 2.2 m aside (the maze's false closure)."""
    truth = two_corridor_drive()
    rng = np.random.default_rng(seed)
    angles, ranges = scans(truth, rng, max_range_m=8.0, world=TWO_CORRIDORS)
    odom = corrupt_odometry(truth, rng, (0.05, 0.05, 0.05))
    cfg = SlamConfig(
        max_range_m=8.0,
        loop_min_travel_m=0.0,  # B's keyframes are candidates against A's submaps
        loop_window_m=2.3,
        loop_min_window_m=2.3,
        loop_min_overlap=loop_min_overlap,
    )
    slam = GraphSlam(cfg, initial_pose=truth[0])
    for k in range(truth.shape[0]):
        slam.update(0.1 * k, odom[k], ranges[k], angles, range_min_m=0.1, range_max_m=8.0)
    return slam, truth


def _loop_errors(slam: GraphSlam, truth: np.ndarray) -> np.ndarray:
    """(L,) translational error of each loop edge's measurement against the true relative pose, metres."""
    kf_truth = truth[np.rint(slam.keyframe_stamps() / 0.1).astype(int)]
    graph = slam.pose_graph()
    loops = set(map(tuple, slam.loop_edges().tolist()))
    errs = [
        relative(relative(kf_truth[a], kf_truth[b]), z)[:2]
        for (a, b), z in zip(graph.edges.tolist(), graph.measurements, strict=True)
        if (a, b) in loops
    ]
    return np.hypot(*np.array(errs).reshape(-1, 2).T)


@pytest.mark.e2e
@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_a_scan_from_the_neighbouring_corridor_does_not_close_a_loop(seed: int) -> None:
    """Loop matches are scored on the part of the scan inside the space the submap observed: a scan from corridor
    B cannot borrow A's walls. Scored over the whole scan (loop_min_overlap = 0), B's keyframes close against A."""
    slam, truth = _two_corridors(seed, SlamConfig().loop_min_overlap)
    errors = _loop_errors(slam, truth)
    assert errors.size >= 5  # the U-turn re-observes A's east end from B: true closures
    assert np.mean(errors > 1.0) < 0.1  # (at most one a run on these seeds; 2.2 m = the next corridor)
    _, est = slam.trajectory()
    assert float(np.sqrt(np.mean(np.sum((est[:, :2] - truth[:, :2]) ** 2, axis=1)))) < 0.1
    whole, _ = _two_corridors(seed, 0.0)
    assert np.mean(_loop_errors(whole, truth) > 1.0) > 0.5  # the failure this guards against


def test_outputs_of_a_short_run() -> None:
    truth = ring_drive(0.2)
    rng = np.random.default_rng(5)
    angles, ranges = scans(truth, rng)
    odom = corrupt_odometry(truth, rng)
    slam = GraphSlam()
    for k in range(truth.shape[0]):
        slam.update(0.1 * k, odom[k], ranges[k], angles, range_min_m=0.1, range_max_m=12.0)
    stamps, traj = slam.trajectory()
    assert traj.shape == (truth.shape[0], 3) and np.allclose(stamps, 0.1 * np.arange(truth.shape[0]))
    # Map frame = odom frame at the start (no initial pose given): the first pose is the first odometry pose.
    assert np.allclose(traj[0], odom[0])
    graph = slam.pose_graph()
    assert graph.num_vertices == slam.num_keyframes >= 10
    assert graph.num_edges == slam.num_keyframes - 1  # no loop in a fifth of a lap
    grid = slam.occupancy_grid()
    occupied = grid.states() == 100
    assert occupied.sum() > 100
    # The map is in the odom frame of the first scan: true walls moved by the start's odometry offset.
    assert grid.contains(*compose(odom[0], relative(truth[0], (10.0, 0.0, 0.0)))[:2])


def test_bad_input_is_a_typed_error() -> None:
    slam = GraphSlam()
    with pytest.raises(SlamError):
        slam.update(0.0, (0.0, 0.0), [1.0, 2.0], [0.0, 0.1], range_min_m=0.1, range_max_m=10.0)
    with pytest.raises(SlamError):
        slam.update(0.0, (0.0, 0.0, 0.0), [1.0, 2.0], [0.0], range_min_m=0.1, range_max_m=10.0)
    with pytest.raises(SlamError):
        slam.update(0.0, (0.0, 0.0, 0.0), [1.0], [0.0], range_min_m=5.0, range_max_m=1.0)
    with pytest.raises(SlamError):
        slam.occupancy_grid()
    with pytest.raises(SlamError, match="match_window_m must be > 0"):
        SlamConfig(match_window_m=-1.0)
    with pytest.raises(SlamError, match="loop_min_overlap must be >= 0"):  # 0 is allowed: say so
        SlamConfig(loop_min_overlap=-0.1)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_localization_converges_from_half_a_metre_and_twenty_degrees(seed: int) -> None:
    grid = true_map()
    loc = Localizer(grid)
    truth = ring_drive(0.3, 0.5, 0.1)[:20]  # 2 s of driving at 10 Hz
    rng = np.random.default_rng(seed)
    angles, ranges = scans(truth, rng)
    odom = corrupt_odometry(truth, rng)
    phi = rng.uniform(-math.pi, math.pi)
    sign = 1.0 if rng.uniform() < 0.5 else -1.0
    start = truth[0] + np.array([0.5 * math.cos(phi), 0.5 * math.sin(phi), sign * math.radians(20.0)])
    with pytest.raises(SlamError):
        loc.update(odom[0], ranges[0], angles, range_min_m=0.1, range_max_m=12.0)
    loc.set_pose(start, np.diag([0.25, 0.25, 0.0685]))  # RViz's 2D Pose Estimate covariance
    for k in range(truth.shape[0]):
        est = loc.update(odom[k], ranges[k], angles, range_min_m=0.1, range_max_m=12.0)
    err = relative(truth[-1], est.pose)
    assert math.hypot(err[0], err[1]) <= 0.05
    assert abs(math.degrees(err[2])) <= 1.0
    assert est.matched
    assert np.allclose(compose(loc.map_to_odom(), odom[-1]), est.pose)


def test_localizer_needs_walls() -> None:
    from mjnav.mapping import OccupancyGrid

    with pytest.raises(SlamError):
        Localizer(OccupancyGrid(10, 10, 0.1))


# ---------------------------------------------------------------------------------------------------------------
# Kümmerle et al.'s metric and the odometry noise


def test_relative_pose_error_by_hand() -> None:
    # Reference: three poses 1 m apart along x. Estimate: the second pose 0.1 m too far in y and turned 2°.
    ref = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]])
    est = ref.copy()
    est[1] = (1.0, 0.1, math.radians(2.0))
    e = relative_pose_error(est, ref, consecutive_relations(3))
    # Relation (0,1): δ = (1, 0.1, 2°) vs δ* = (1, 0, 0) → error (0, 0.1, 2°): 0.1 m, 2°.
    # Relation (1,2): δ = est1⁻¹·(2, 0, 0); δ*⁻¹·δ has translation length |R(−2°)·(1, −0.1) − (1, 0)| and −2°.
    c, s = math.cos(math.radians(2.0)), math.sin(math.radians(2.0))
    t2 = math.hypot(c * 1.0 + s * -0.1 - 1.0, -s * 1.0 + c * -0.1)
    assert e.relations == 2
    assert e.trans_errors_m == pytest.approx([0.1, t2], abs=1e-12)
    assert e.rot_errors_deg == pytest.approx([2.0, 2.0], abs=1e-12)
    assert e.trans_mean_m == pytest.approx((0.1 + t2) / 2)
    assert e.trans_std_m == pytest.approx(abs(0.1 - t2) / 2)
    assert e.rot_std_deg == pytest.approx(0.0, abs=1e-12)
    # The metric ignores the global frame: moving the whole estimate changes nothing.
    moved = compose(np.array([3.0, -1.0, 0.7]), est)
    assert relative_pose_error(moved, ref, consecutive_relations(3)).trans_mean_m == pytest.approx(e.trans_mean_m)


def test_relation_error_takes_measured_relative_poses() -> None:
    ref = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]])
    est = ref.copy()
    est[1] = (1.0, 0.1, math.radians(2.0))
    rel = consecutive_relations(3)
    # Measured relations equal to the reference's relative poses: the same as relative_pose_error.
    same = relation_error(est, rel, relative(ref[:-1], ref[1:]))
    assert same.trans_errors_m == pytest.approx(relative_pose_error(est, ref, rel).trans_errors_m, abs=1e-12)
    # A relation measured 5 cm longer than the estimate's 1 m step: 5 cm of error, none in rotation.
    e = relation_error(ref, rel[:1], np.array([[1.05, 0.0, 0.0]]))
    assert e.trans_errors_m == pytest.approx([0.05], abs=1e-12)
    assert e.rot_errors_deg == pytest.approx([0.0], abs=1e-12)
    with pytest.raises(SlamError):
        relation_error(est, rel, np.zeros((1, 3)))


def test_relations() -> None:
    ref = np.column_stack((np.arange(6) * 0.4, np.zeros(6), np.zeros(6)))
    assert distance_relations(ref, 1.0).tolist() == [[0, 3], [1, 4], [2, 5]]
    assert consecutive_relations(3).tolist() == [[0, 1], [1, 2]]
    with pytest.raises(SlamError):
        relative_pose_error(ref, ref[:3], consecutive_relations(3))
    with pytest.raises(SlamError):
        relative_pose_error(ref, ref, np.array([[0, 9]]))


@pytest.mark.e2e
def test_odometry_noise_is_seeded_and_grows_like_a_random_walk() -> None:
    ref = np.column_stack((np.linspace(0.0, 100.0, 1001), np.zeros(1001), np.zeros(1001)))
    a = corrupt_odometry(ref, np.random.default_rng(3))
    assert np.array_equal(a, corrupt_odometry(ref, np.random.default_rng(3)))
    assert np.array_equal(corrupt_odometry(ref, np.random.default_rng(3), (0.0, 0.0, 0.0)), ref)
    # σ_b = 0.02 rad/√m: the heading after 100 m has σ = 0.2 rad; over 400 seeded runs the spread matches.
    ends = np.array([corrupt_odometry(ref, np.random.default_rng(s))[-1, 2] for s in range(400)])
    assert np.std(ends) == pytest.approx(0.2, rel=0.15)
    assert np.allclose(invert(invert(a[5])), a[5])


def test_walls_seen_at_grazing_angles_stay_occupied_in_the_map() -> None:
    """Driving down a 1.2 m aisle, each wall cell is seen mostly at grazing angles, and the beams that end further
    along pass through the free sliver of its face cell. With OctoMap's miss weight 6–11 % of the face ended below
    occupied; :class:`SlamConfig`'s map model keeps the whole face (within one cell)."""
    from tests.estimation._scans import raycast

    walls = np.array([(-1, -0.6, 13, -0.6), (-1, 0.6, 13, 0.6), (-1, -0.6, -1, 0.6), (13, -0.6, 13, 0.6)], float)
    rng = np.random.default_rng(0)
    slam = GraphSlam(SlamConfig(max_range_m=8.0), initial_pose=(0.0, 0.0, 0.0))
    for k, x in enumerate(np.arange(0.0, 12.0, 0.1)):
        angles, ranges = raycast(walls, (float(x), 0.0, 0.0), 360, 2 * math.pi, 12.0)
        slam.update(
            0.1 * k,
            (x, 0.0, 0.0),
            ranges + rng.normal(0.0, 0.01, ranges.shape),
            angles,
            range_min_m=0.1,
            range_max_m=12.0,
        )
    grid = slam.occupancy_grid()
    states = grid.states()
    xs = np.arange(0.5, 11.5, grid.resolution_m) + 0.5 * grid.resolution_m
    for y in (0.6, -0.6):
        occupied = np.zeros(len(xs), dtype=bool)
        for dy in (-grid.resolution_m, 0.0, grid.resolution_m):
            cells = np.array([grid.world_to_cell(x, y + dy) for x in xs])
            occupied |= states[cells[:, 0], cells[:, 1]] == 100
        assert occupied.mean() >= 0.98, (y, occupied.mean())
