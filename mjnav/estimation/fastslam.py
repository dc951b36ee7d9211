"""FastSLAM 1.0 with unknown data association (Montemerlo et al., AAAI 2002; Probabilistic Robotics §13.3, §13.8).

Each of N particles carries a pose hypothesis and its own map: one 2-D EKF (mean, 2×2 covariance) per landmark.

- :meth:`FastSLAM.predict` samples every particle's pose from the velocity motion model
  (:func:`mjnav.motion.sample_velocity_motion`, the project's model, α1..α6 as there).
- :meth:`FastSLAM.update` associates per particle, like :class:`~mjnav.estimation.ekf_slam.EKFSLAM`: squared
  Mahalanobis distance d² to each of the particle's landmarks (S = H Σ Hᵀ + R), greedy one-to-one nearest
  neighbour inside χ²_2(gate_probability); an unmatched observation starts a landmark when min d² exceeds the larger
  χ²_2(new_landmark_probability) and is discarded otherwise. Matched landmarks get an EKF update and the particle's
  weight is multiplied by N(ν; 0, S); a new landmark multiplies it by the constant
  p0 = exp(−½ χ²_2(new_landmark_probability)) / (2π √det R); a discarded observation by N(ν; 0, S) of its nearest
  landmark. When the effective sample size N_eff = 1 / Σ wᵢ² falls below ``resample_threshold`` · N the particles
  are resampled with the low-variance sampler (Probabilistic Robotics, Table 4.4) drawn from the seeded ``rng``.

The per-particle association and landmark updates run in a numba kernel. ``pose`` and ``pose_covariance`` are the
weighted mean (circular mean for θ) and covariance of the particle cloud; ``landmarks`` and the returned
:class:`~mjnav.estimation.association.Association` are those of the highest-weight particle.

Documented behaviour (tests): ≥ 99% correct associations at the noise documented in :mod:`mjnav.estimation.ekf_slam`
(``LOOP_WORLD_*`` of :mod:`mjnav.estimation.simulation`, 100 particles, full loop). Pose NEES: with 500 particles
the 50-run average stays inside the 95% χ² band over the first 40 steps of the loop at the low-odometry-noise
setting ``FASTSLAM_WORLD_*`` (α ten times smaller, σ_r = 0.2 m, σ_φ = 0.05 rad). Over the full loop, and at the
default noise, FastSLAM 1.0 becomes overconfident — its particles lose path diversity on resampling (Bailey, Nieto,
Nebot, ICRA 2006) — see ``benchmarks/estimation_filters.py`` for the measured figures.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

from mjnav.estimation.association import Association, chi2_gate
from mjnav.estimation.ekf_slam import check_motion_alphas, empty_association, observations_array
from mjnav.estimation.errors import InvalidModel
from mjnav.estimation.simulation import LOOP_WORLD_ALPHAS, LOOP_WORLD_BEARING_STD_RAD, LOOP_WORLD_RANGE_STD_M
from mjnav.motion import sample_velocity_motion

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
_LOG_2PI = math.log(2.0 * math.pi)


@njit(cache=True)
def _wrap(a: float) -> float:
    return (a + math.pi) % (2.0 * math.pi) - math.pi


@njit(cache=True)
def _update_particles(
    poses: FloatArray,
    mu: FloatArray,
    cov: FloatArray,
    count: IntArray,
    origin: IntArray,
    Z: FloatArray,
    R: FloatArray,
    gate: float,
    new_gate: float,
    log_p0: float,
    update_index: int,
    assoc: IntArray,
    is_new: NDArray[np.bool_],
    dist: FloatArray,
) -> FloatArray:
    """Associate and update every particle's landmarks in place; returns each particle's log-likelihood."""
    N = poses.shape[0]
    K = Z.shape[0]
    loglik = np.zeros(N)
    r00, r01, r11 = R[0, 0], R[0, 1], R[1, 1]
    cap = mu.shape[1]
    zp = np.empty((cap, 2))  # work arrays shared by all particles (first M rows used)
    H = np.empty((cap, 2, 2))
    Si = np.empty((cap, 3))  # inverse S as (a, b, c) of [[a, b], [b, c]]
    ldet = np.empty(cap)
    d2 = np.empty((K, cap))
    a = np.empty(K, dtype=np.int64)
    used = np.empty(cap, dtype=np.bool_)
    for p in range(N):
        px, py, pth = poses[p, 0], poses[p, 1], poses[p, 2]
        M = count[p]
        for j in range(M):
            dx = mu[p, j, 0] - px
            dy = mu[p, j, 1] - py
            q = max(dx * dx + dy * dy, 1e-12)
            r = math.sqrt(q)
            zp[j, 0] = r
            zp[j, 1] = _wrap(math.atan2(dy, dx) - pth)
            H[j, 0, 0] = dx / r
            H[j, 0, 1] = dy / r
            H[j, 1, 0] = -dy / q
            H[j, 1, 1] = dx / q
            # S = H Σ Hᵀ + R
            c00, c01, c11 = cov[p, j, 0, 0], cov[p, j, 0, 1], cov[p, j, 1, 1]
            h00, h01, h10, h11 = H[j, 0, 0], H[j, 0, 1], H[j, 1, 0], H[j, 1, 1]
            t00 = h00 * c00 + h01 * c01
            t01 = h00 * c01 + h01 * c11
            t10 = h10 * c00 + h11 * c01
            t11 = h10 * c01 + h11 * c11
            s00 = t00 * h00 + t01 * h01 + r00
            s01 = t00 * h10 + t01 * h11 + r01
            s11 = t10 * h10 + t11 * h11 + r11
            det = s00 * s11 - s01 * s01
            Si[j, 0] = s11 / det
            Si[j, 1] = -s01 / det
            Si[j, 2] = s00 / det
            ldet[j] = math.log(det)
        for k in range(K):
            for j in range(M):
                n0 = Z[k, 0] - zp[j, 0]
                n1 = _wrap(Z[k, 1] - zp[j, 1])
                d2[k, j] = Si[j, 0] * n0 * n0 + 2.0 * Si[j, 1] * n0 * n1 + Si[j, 2] * n1 * n1
        # greedy one-to-one nearest neighbour inside the gate
        a[:] = -1
        used[:M] = False
        for _ in range(min(K, M)):
            best = gate
            bk = -1
            bj = -1
            for k in range(K):
                if a[k] >= 0:
                    continue
                for j in range(M):
                    if not used[j] and d2[k, j] < best:
                        best = d2[k, j]
                        bk = k
                        bj = j
            if bk < 0:
                break
            a[bk] = bj
            used[bj] = True
        ll = 0.0
        for k in range(K):
            j = a[k]
            if j >= 0:
                n0 = Z[k, 0] - zp[j, 0]
                n1 = _wrap(Z[k, 1] - zp[j, 1])
                # K = Σ Hᵀ S⁻¹; μ += K ν; Σ = (I − K H) Σ
                c00, c01, c11 = cov[p, j, 0, 0], cov[p, j, 0, 1], cov[p, j, 1, 1]
                h00, h01, h10, h11 = H[j, 0, 0], H[j, 0, 1], H[j, 1, 0], H[j, 1, 1]
                ph00 = c00 * h00 + c01 * h01  # Σ Hᵀ
                ph01 = c00 * h10 + c01 * h11
                ph10 = c01 * h00 + c11 * h01
                ph11 = c01 * h10 + c11 * h11
                k00 = ph00 * Si[j, 0] + ph01 * Si[j, 1]
                k01 = ph00 * Si[j, 1] + ph01 * Si[j, 2]
                k10 = ph10 * Si[j, 0] + ph11 * Si[j, 1]
                k11 = ph10 * Si[j, 1] + ph11 * Si[j, 2]
                mu[p, j, 0] += k00 * n0 + k01 * n1
                mu[p, j, 1] += k10 * n0 + k11 * n1
                # Σ − K (H Σ) with H Σ = (Σ Hᵀ)ᵀ
                n00 = c00 - (k00 * ph00 + k01 * ph01)
                n01 = c01 - (k00 * ph10 + k01 * ph11)
                n11 = c11 - (k10 * ph10 + k11 * ph11)
                cov[p, j, 0, 0] = n00
                cov[p, j, 0, 1] = n01
                cov[p, j, 1, 0] = n01
                cov[p, j, 1, 1] = n11
                ll += -0.5 * (d2[k, j] + ldet[j] + 2.0 * _LOG_2PI)
                assoc[p, k] = j
                is_new[p, k] = False
                dist[p, k] = d2[k, j]
                continue
            jmin = -1
            dmin = math.inf
            for jj in range(M):
                if d2[k, jj] < dmin:
                    dmin = d2[k, jj]
                    jmin = jj
            dist[p, k] = math.nan
            if dmin > new_gate:
                m = count[p]
                ang = pth + Z[k, 1]
                c, s = math.cos(ang), math.sin(ang)
                rr = Z[k, 0]
                mu[p, m, 0] = px + rr * c
                mu[p, m, 1] = py + rr * s
                # Σ = G_z R G_zᵀ, G_z = [[c, −r s], [s, r c]]
                g00, g01, g10, g11 = c, -rr * s, s, rr * c
                t00 = g00 * r00 + g01 * r01
                t01 = g00 * r01 + g01 * r11
                t10 = g10 * r00 + g11 * r01
                t11 = g10 * r01 + g11 * r11
                cov[p, m, 0, 0] = t00 * g00 + t01 * g01
                cov[p, m, 0, 1] = t00 * g10 + t01 * g11
                cov[p, m, 1, 0] = cov[p, m, 0, 1]
                cov[p, m, 1, 1] = t10 * g10 + t11 * g11
                origin[p, m, 0] = update_index
                origin[p, m, 1] = k
                count[p] = m + 1
                ll += log_p0
                assoc[p, k] = m
                is_new[p, k] = True
            else:
                ll += -0.5 * (dmin + ldet[jmin] + 2.0 * _LOG_2PI)
                assoc[p, k] = -1
                is_new[p, k] = False
        loglik[p] = ll
    return loglik


def low_variance_indices(weights: ArrayLike, rng: np.random.Generator) -> IntArray:
    """Low-variance (systematic) resampling: N indices drawn with one uniform offset r ~ U(0, 1/N).

    Args:
        weights: (N,) non-negative weights (normalised here).
        rng: random generator.

    Returns:
        (N,) int indices, non-decreasing; particle i appears ⌊N wᵢ⌋ or ⌈N wᵢ⌉ times.
    """
    w = np.asarray(weights, dtype=np.float64)
    N = w.shape[0]
    c = np.cumsum(w / w.sum())
    c[-1] = 1.0
    u = rng.uniform(0.0, 1.0 / N) + np.arange(N) / N
    return np.searchsorted(c, u, side="right").astype(np.int64)


class FastSLAM:
    """FastSLAM 1.0 with range-bearing observations and unknown correspondences.

    Args:
        motion_alphas: (α1..α6) velocity motion-model noise (4 values: α5 = α6 = 0); default: the documented
            loop-world noise.
        range_std_m: range noise σ_r, metres (default 0.1).
        bearing_std_rad: bearing noise σ_φ, radians (default 0.02).
        rng: random generator for motion sampling and resampling, or an int seed; None means seed 0, so runs are
            always repeatable.
        num_particles: N.
        initial_pose: (3,) start pose.
        initial_covariance: (3, 3) start pose covariance the particles are drawn from (default zeros).
        gate_probability: χ² gate probability for matching.
        new_landmark_probability: larger threshold for starting a landmark (≥ gate_probability).
        resample_threshold: resample when N_eff < threshold · N (0 never, 1 always).

    Attributes:
        last_association: :class:`Association` of the last update for the highest-weight particle.

    Raises:
        InvalidModel: bad noise values, particle count, probabilities or threshold.
    """

    def __init__(
        self,
        motion_alphas: ArrayLike = LOOP_WORLD_ALPHAS,
        range_std_m: float = LOOP_WORLD_RANGE_STD_M,
        bearing_std_rad: float = LOOP_WORLD_BEARING_STD_RAD,
        *,
        rng: np.random.Generator | int | None = None,
        num_particles: int = 100,
        initial_pose: ArrayLike = (0.0, 0.0, 0.0),
        initial_covariance: ArrayLike | None = None,
        gate_probability: float = 0.999,
        new_landmark_probability: float = 0.99999,
        resample_threshold: float = 0.5,
    ) -> None:
        self.alphas = check_motion_alphas(motion_alphas)
        if not (range_std_m > 0 and bearing_std_rad > 0 and math.isfinite(range_std_m + bearing_std_rad)):
            raise InvalidModel(f"need range_std_m > 0 and bearing_std_rad > 0, got {range_std_m}, {bearing_std_rad}")
        if num_particles < 1:
            raise InvalidModel(f"num_particles must be >= 1, got {num_particles}")
        if new_landmark_probability < gate_probability:
            raise InvalidModel("new_landmark_probability must be >= gate_probability")
        if not 0.0 <= resample_threshold <= 1.0:
            raise InvalidModel(f"resample_threshold must be in [0, 1], got {resample_threshold}")
        if rng is None or isinstance(rng, int):
            rng = np.random.default_rng(0 if rng is None else rng)
        if not isinstance(rng, np.random.Generator):
            raise InvalidModel(f"rng must be a numpy Generator or an int seed, got {type(rng).__name__}")
        self.rng = rng
        self.R = np.diag([range_std_m**2, bearing_std_rad**2])
        self.gate = chi2_gate(gate_probability, 2)
        self.new_gate = chi2_gate(new_landmark_probability, 2)
        self.log_p0 = -0.5 * (self.new_gate + math.log(np.linalg.det(self.R)) + 2.0 * _LOG_2PI)
        self.resample_threshold = float(resample_threshold)
        pose = np.asarray(initial_pose, dtype=np.float64).reshape(-1)
        if pose.shape != (3,) or not np.isfinite(pose).all():
            raise InvalidModel(f"initial_pose must be 3 finite values, got {pose.tolist()}")
        N = int(num_particles)
        if initial_covariance is None:
            self._poses = np.tile(pose, (N, 1))
        else:
            P0 = np.asarray(initial_covariance, dtype=np.float64)
            if P0.shape != (3, 3) or not np.isfinite(P0).all():
                raise InvalidModel("initial_covariance must be a finite (3, 3) matrix")
            self._poses = rng.multivariate_normal(pose, P0, N)
        self._poses[:, 2] = np.mod(self._poses[:, 2] + np.pi, 2.0 * np.pi) - np.pi
        cap = 16
        self._mu = np.zeros((N, cap, 2))
        self._cov = np.zeros((N, cap, 2, 2))
        self._origin = np.full((N, cap, 2), -1, dtype=np.int64)
        self._count = np.zeros(N, dtype=np.int64)
        self._w = np.full(N, 1.0 / N)
        self._best = 0
        self._updates = 0
        self.resampled = False
        """Whether the last update resampled."""
        self.last_association = empty_association()

    # ----------------------------------------------------------------------------------------------- properties
    @property
    def num_particles(self) -> int:
        """N."""
        return int(self._poses.shape[0])

    @property
    def particles(self) -> FloatArray:
        """(N, 3) particle poses."""
        return self._poses.copy()

    @property
    def weights(self) -> FloatArray:
        """(N,) normalised particle weights."""
        return self._w.copy()

    @property
    def effective_sample_size(self) -> float:
        """N_eff = 1 / Σ wᵢ²."""
        return float(1.0 / np.sum(self._w * self._w))

    @property
    def best_particle(self) -> int:
        """Index of the highest-weight particle (after a resampling: a copy of the one that was highest)."""
        return self._best

    @property
    def pose(self) -> FloatArray:
        """(3,) weighted mean pose (circular mean for θ)."""
        w = self._w
        th = math.atan2(float(w @ np.sin(self._poses[:, 2])), float(w @ np.cos(self._poses[:, 2])))
        return np.array([float(w @ self._poses[:, 0]), float(w @ self._poses[:, 1]), th])

    @property
    def pose_covariance(self) -> FloatArray:
        """(3, 3) weighted covariance of the particle poses about :attr:`pose` (θ deviations wrapped)."""
        d = self._poses - self.pose
        d[:, 2] = np.mod(d[:, 2] + np.pi, 2.0 * np.pi) - np.pi
        return (d * self._w[:, None]).T @ d

    @property
    def covariance(self) -> FloatArray:
        """(3, 3) pose covariance of the particle cloud (FastSLAM keeps no joint pose-map covariance)."""
        return self.pose_covariance

    @property
    def landmarks(self) -> FloatArray:
        """(M, 2) landmark means of the highest-weight particle, metres."""
        b = self._best
        return self._mu[b, : self._count[b]].copy()

    @property
    def landmark_covariances(self) -> FloatArray:
        """(M, 2, 2) landmark covariances of the highest-weight particle."""
        b = self._best
        return self._cov[b, : self._count[b]].copy()

    @property
    def landmark_origins(self) -> IntArray:
        """(M, 2) (update number, observation index) that created each landmark of the highest-weight particle."""
        b = self._best
        return self._origin[b, : self._count[b]].copy()

    # ------------------------------------------------------------------------------------------------ filtering
    def predict(self, v_mps: float, omega_radps: float, dt_s: float) -> None:
        """Sample every particle's motion from the velocity motion model.

        Raises:
            ValueError: non-finite command or negative dt (from :func:`mjnav.motion.sample_velocity_motion`).
        """
        self._poses = sample_velocity_motion(self._poses, v_mps, omega_radps, dt_s, self.alphas, self.rng)

    def update(self, observations: ArrayLike) -> Association:
        """Associate per particle, update landmark EKFs and weights, resample when N_eff is low.

        Args:
            observations: (K, 2) range (m, > 0) and bearing (rad, robot frame), no ids, any order.

        Returns:
            The :class:`Association` of the highest-weight particle (landmark indices into :attr:`landmarks`).

        Raises:
            InvalidMeasurement: observations not (K, 2), non-finite or with range <= 0.
        """
        Z = np.ascontiguousarray(observations_array(observations))
        u = self._updates
        self._updates += 1
        self.resampled = False
        K = Z.shape[0]
        if K == 0:
            self.last_association = empty_association()
            return self.last_association
        self._reserve(int(self._count.max()) + K)
        N = self.num_particles
        assoc = np.full((N, K), -1, dtype=np.int64)
        is_new = np.zeros((N, K), dtype=np.bool_)
        dist = np.full((N, K), np.nan)
        loglik = _update_particles(
            self._poses,
            self._mu,
            self._cov,
            self._count,
            self._origin,
            Z,
            self.R,
            self.gate,
            self.new_gate,
            self.log_p0,
            u,
            assoc,
            is_new,
            dist,
        )
        logw = np.log(np.maximum(self._w, 1e-300)) + loglik
        w = np.exp(logw - logw.max())
        self._w = w / w.sum()
        b = int(np.argmax(self._w))
        lm = assoc[b]
        origin = np.full((K, 2), -1, dtype=np.int64)
        ok = lm >= 0
        origin[ok] = self._origin[b, lm[ok]]
        self.last_association = Association(lm.copy(), is_new[b].copy(), origin, dist[b].copy())
        self._best = b
        if self.effective_sample_size < self.resample_threshold * N:
            idx = low_variance_indices(self._w, self.rng)
            self._poses = self._poses[idx]
            self._mu = self._mu[idx]
            self._cov = self._cov[idx]
            self._origin = self._origin[idx]
            self._count = self._count[idx]
            self._w = np.full(N, 1.0 / N)
            self._best = int(np.flatnonzero(idx == b)[0])
            self.resampled = True
        return self.last_association

    def _reserve(self, needed: int) -> None:
        cap = self._mu.shape[1]
        if needed <= cap:
            return
        new_cap = max(needed, 2 * cap)
        N = self.num_particles
        mu = np.zeros((N, new_cap, 2))
        cov = np.zeros((N, new_cap, 2, 2))
        origin = np.full((N, new_cap, 2), -1, dtype=np.int64)
        mu[:, :cap], cov[:, :cap], origin[:, :cap] = self._mu, self._cov, self._origin
        self._mu, self._cov, self._origin = mu, cov, origin
