"""A seeded landmark world for testing and benchmarking the SLAM filters.

The robot follows commanded (v, ω) controls through :func:`mjnav.motion.sample_velocity_motion` (the same model
the filters assume) and, after every step, measures range and bearing to every landmark within ``max_range_m``
and the field of view, with Gaussian noise. Observations come in a random order and carry no ids; the true ids
are returned beside them for scoring only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.special import gammaincinv

from mjnav.estimation.association import Association
from mjnav.estimation.errors import InvalidModel
from mjnav.geometry import wrap_angles
from mjnav.motion import sample_velocity_motion

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

#: The documented noise of the loop world (the ≥ 99% association and NEES claims of the SLAM filters hold here):
#: velocity-model α1..α6 (variances per squared command), range σ (m), bearing σ (rad).
LOOP_WORLD_ALPHAS = (0.01, 0.0, 0.0001, 0.01, 0.0001, 0.0)
LOOP_WORLD_RANGE_STD_M = 0.1
LOOP_WORLD_BEARING_STD_RAD = 0.02

#: A low-odometry-noise setting (α ten times smaller, noisier sensor) in which FastSLAM 1.0 with 500 particles stays
#: consistent over the first half of the loop (40 steps); over the full loop and at the default noise it becomes
#: overconfident, as FastSLAM 1.0 is known to (Bailey, Nieto, Nebot, ICRA 2006).
FASTSLAM_WORLD_ALPHAS = tuple(0.1 * a for a in LOOP_WORLD_ALPHAS)
FASTSLAM_WORLD_RANGE_STD_M = 0.2
FASTSLAM_WORLD_BEARING_STD_RAD = 0.05


@dataclass(frozen=True)
class LandmarkRun:
    """One simulated run.

    Attributes:
        landmarks: (L, 2) true landmark positions, metres.
        poses: (T + 1, 3) true poses (x m, y m, θ rad); poses[0] is the initial pose.
        controls: (T, 2) commanded (v m/s, ω rad/s) for each step.
        dt_s: step duration, s.
        observations: T arrays (K_t, 2) of range (m), bearing (rad, robot frame) taken at poses[t + 1].
        observation_ids: T arrays (K_t,) of the true landmark index of each observation (for scoring only).
    """

    landmarks: FloatArray
    poses: FloatArray
    controls: FloatArray
    dt_s: float
    observations: tuple[FloatArray, ...]
    observation_ids: tuple[IntArray, ...]


def random_landmarks(
    count: int, bounds: tuple[float, float, float, float], min_separation_m: float, rng: np.random.Generator
) -> FloatArray:
    """``count`` landmarks uniform in ``bounds`` = (xmin, xmax, ymin, ymax), pairwise ≥ ``min_separation_m`` apart.

    Raises:
        InvalidModel: the landmarks do not fit (rejection sampling gives up after 1000 tries per landmark).
    """
    xmin, xmax, ymin, ymax = bounds
    out = np.empty((count, 2))
    placed = 0
    tries = 0
    while placed < count:
        p = np.array([rng.uniform(xmin, xmax), rng.uniform(ymin, ymax)])
        d2 = np.sum((out[:placed] - p) ** 2, axis=1)
        if placed == 0 or float(d2.min()) >= min_separation_m**2:
            out[placed] = p
            placed += 1
            tries = 0
        else:
            tries += 1
            if tries > 1000:
                raise InvalidModel(f"cannot place {count} landmarks {min_separation_m} m apart in {bounds}")
    return out


def simulate_landmark_run(
    landmarks: ArrayLike,
    controls: ArrayLike,
    dt_s: float,
    *,
    motion_alphas: ArrayLike,
    range_std_m: float,
    bearing_std_rad: float,
    max_range_m: float,
    rng: np.random.Generator,
    initial_pose: ArrayLike = (0.0, 0.0, 0.0),
    fov_rad: float = 2.0 * math.pi,
    min_range_m: float = 0.3,
) -> LandmarkRun:
    """Simulate a run through a landmark world.

    Args:
        landmarks: (L, 2) landmark positions, metres.
        controls: (T, 2) commanded (v m/s, ω rad/s) per step.
        dt_s: step duration, s.
        motion_alphas: (α1..α6) velocity-model noise (see :mod:`mjnav.motion.velocity`).
        range_std_m: range noise σ_r, metres.
        bearing_std_rad: bearing noise σ_φ, radians.
        max_range_m: landmarks farther than this are not observed.
        rng: random generator (motion, measurement noise and observation order).
        initial_pose: (3,) start pose.
        fov_rad: field of view centred on the heading (2π: all around).
        min_range_m: landmarks nearer than this are not observed.

    Returns:
        The :class:`LandmarkRun`.
    """
    L = np.asarray(landmarks, dtype=np.float64).reshape(-1, 2)
    U = np.asarray(controls, dtype=np.float64).reshape(-1, 2)
    poses = np.empty((U.shape[0] + 1, 3))
    poses[0] = np.asarray(initial_pose, dtype=np.float64)
    obs: list[FloatArray] = []
    ids: list[IntArray] = []
    for t, (v, w) in enumerate(U):
        poses[t + 1] = sample_velocity_motion(poses[t], float(v), float(w), dt_s, motion_alphas, rng)
        x, y, th = poses[t + 1]
        dx, dy = L[:, 0] - x, L[:, 1] - y
        r = np.hypot(dx, dy)
        b = wrap_angles(np.arctan2(dy, dx) - th)
        seen = np.flatnonzero((r <= max_range_m) & (r >= min_range_m) & (np.abs(b) <= 0.5 * fov_rad))
        seen = seen[rng.permutation(seen.shape[0])]
        z = np.stack(
            (
                r[seen] + rng.normal(0.0, range_std_m, seen.shape[0]),
                wrap_angles(b[seen] + rng.normal(0.0, bearing_std_rad, seen.shape[0])),
            ),
            axis=-1,
        )
        keep = z[:, 0] > 0.0  # a noisy range at or below zero is not a measurement
        obs.append(z[keep])
        ids.append(seen[keep].astype(np.int64))
    return LandmarkRun(L, poses, U, float(dt_s), tuple(obs), tuple(ids))


def simulate_loop_world(
    rng: np.random.Generator,
    *,
    num_landmarks: int = 40,
    steps: int = 80,
    dt_s: float = 0.5,
    speed_mps: float = 1.5,
    max_range_m: float = 6.0,
    min_separation_m: float = 2.0,
    motion_alphas: ArrayLike = LOOP_WORLD_ALPHAS,
    range_std_m: float = LOOP_WORLD_RANGE_STD_M,
    bearing_std_rad: float = LOOP_WORLD_BEARING_STD_RAD,
) -> LandmarkRun:
    """The documented test world: one counter-clockwise circle (radius v·T·Δt / 2π ≈ 9.5 m) from the origin.

    Landmarks are uniform in the circle's bounding box grown by 4 m, ``min_separation_m`` apart; every step drives
    (v, ω = 2π / (T Δt)) and observes the landmarks within ``max_range_m``, all around.
    """
    w = 2.0 * math.pi / (steps * dt_s)
    radius = speed_mps / w
    lms = random_landmarks(
        num_landmarks, (-radius - 4.0, radius + 4.0, -4.0, 2.0 * radius + 4.0), min_separation_m, rng
    )
    controls = np.tile([speed_mps, w], (steps, 1))
    return simulate_landmark_run(
        lms,
        controls,
        dt_s,
        motion_alphas=motion_alphas,
        range_std_m=range_std_m,
        bearing_std_rad=bearing_std_rad,
        max_range_m=max_range_m,
        rng=rng,
    )


class SlamFilter(Protocol):
    """What :func:`evaluate_slam` needs of a filter (EKFSLAM and FastSLAM both qualify)."""

    def predict(self, v_mps: float, omega_radps: float, dt_s: float) -> None: ...

    def update(self, observations: ArrayLike) -> Association: ...

    @property
    def pose(self) -> FloatArray: ...

    @property
    def pose_covariance(self) -> FloatArray: ...

    @property
    def landmarks(self) -> FloatArray: ...

    @property
    def landmark_origins(self) -> IntArray: ...


@dataclass(frozen=True)
class SlamScore:
    """Scores of one filter run against the simulator's truth.

    Attributes:
        nees: (T,) pose NEES eᵀ P⁻¹ e after each update (e = truth − estimate, heading wrapped).
        correct: observations attributed to the right landmark (matched to it, or a first sighting made new).
        wrong: observations matched to another landmark, or made new although their landmark was mapped.
        discarded: observations the filter discarded as ambiguous.
        landmark_rmse_m: RMS position error of the mapped landmarks (each scored against its creator's truth).
    """

    nees: FloatArray
    correct: int
    wrong: int
    discarded: int
    landmark_rmse_m: float

    @property
    def total(self) -> int:
        """Number of observations."""
        return self.correct + self.wrong + self.discarded


def pose_nees(true_pose: ArrayLike, pose: ArrayLike, covariance: ArrayLike) -> float:
    """Normalised estimation error squared of a pose (heading difference wrapped); inf for a singular covariance
    (e.g. a particle cloud collapsed onto one pose)."""
    e = np.asarray(true_pose, dtype=np.float64) - np.asarray(pose, dtype=np.float64)
    e[2] = (e[2] + math.pi) % (2.0 * math.pi) - math.pi
    try:
        L = np.linalg.cholesky(np.asarray(covariance, dtype=np.float64))
    except np.linalg.LinAlgError:
        return math.inf
    w = np.linalg.solve(L, e)
    return float(w @ w)


def nees_bounds(dof: int, runs: int, probability: float = 0.95) -> tuple[float, float]:
    """Two-sided ``probability`` interval of the average NEES over ``runs`` Monte Carlo runs (χ²_{dof·runs} / runs)."""
    # chi2.ppf(p, k) = 2 gammaincinv(k/2, p), as scipy.stats computes it (without importing scipy.stats: ~0.5 s)
    lo, hi = 2.0 * gammaincinv(0.5 * dof * runs, [(1.0 - probability) / 2.0, (1.0 + probability) / 2.0])
    return float(lo) / runs, float(hi) / runs


def evaluate_slam(slam: SlamFilter, run: LandmarkRun) -> SlamScore:
    """Run a SLAM filter through a simulated run and score it (pose NEES, associations, landmark RMSE)."""
    T = run.controls.shape[0]
    nees = np.empty(T)
    first_seen: set[int] = set()
    correct = wrong = discarded = 0
    for t in range(T):
        slam.predict(float(run.controls[t, 0]), float(run.controls[t, 1]), run.dt_s)
        a = slam.update(run.observations[t])
        ids = run.observation_ids[t]
        for k in range(ids.shape[0]):
            true_id = int(ids[k])
            if a.landmark[k] < 0:
                discarded += 1
                continue
            creator = int(run.observation_ids[int(a.origin[k, 0])][int(a.origin[k, 1])])
            ok = creator == true_id and (not a.is_new[k] or true_id not in first_seen)
            correct += ok
            wrong += not ok
            first_seen.add(true_id)
        nees[t] = pose_nees(run.poses[t + 1], slam.pose, slam.pose_covariance)
    origins = slam.landmark_origins
    if origins.shape[0]:
        truth = np.array([run.observation_ids[int(u)][int(k)] for u, k in origins])
        err = slam.landmarks - run.landmarks[truth]
        rmse = float(np.sqrt(np.mean(np.sum(err * err, axis=1))))
    else:
        rmse = math.nan
    return SlamScore(nees, correct, wrong, discarded, rmse)


def truncate_run(run: LandmarkRun, steps: int) -> LandmarkRun:
    """The first ``steps`` steps of a run (same world)."""
    return LandmarkRun(
        run.landmarks,
        run.poses[: steps + 1],
        run.controls[:steps],
        run.dt_s,
        run.observations[:steps],
        run.observation_ids[:steps],
    )
