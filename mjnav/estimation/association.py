"""Data association: Mahalanobis gating, nearest neighbour, joint compatibility branch and bound (JCBB).

An observation z_k is *individually compatible* with a predicted measurement ẑ_j of covariance S_j when its
squared Mahalanobis distance d²_kj = (z_k − ẑ_j)ᵀ S_j⁻¹ (z_k − ẑ_j) lies below the χ² gate χ²_m(p) (m = measurement
dimension, p = gate probability). Nearest neighbour pairs observations and landmarks greedily in ascending d²
(each landmark used at most once). JCBB (Neira and Tardós, IEEE T-RA 17(6), 2001) searches the hypotheses jointly:
a set of pairs H is jointly compatible when the stacked innovation ν_H, with covariance
S_H = H_H P H_Hᵀ + R_H that keeps the correlations between the landmarks, has ν_Hᵀ S_H⁻¹ ν_H < χ²_{m|H|}(p); the
largest jointly compatible set wins (ties: smaller joint NIS).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.special import gammaincinv

from mjnav.estimation.errors import InvalidMeasurement, InvalidModel, NotPositiveDefinite

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


@dataclass(frozen=True, slots=True)
class Association:
    """How the K observations of one SLAM update were used.

    Attributes:
        landmark: (K,) int, index of the landmark (in the filter's ``landmarks`` after the update) each observation
            was attributed to, existing or newly created; -1 when it was discarded as ambiguous.
        is_new: (K,) bool, True where the observation created a new landmark.
        origin: (K, 2) int, the (update number, observation index) of the observation that created the landmark
            each observation was attributed to (a stable landmark identity, also across FastSLAM particles);
            (-1, -1) for discarded observations. Update numbers count from 0.
        distance2: (K,) float, squared Mahalanobis distance to the matched landmark (NaN for new or discarded).
    """

    landmark: IntArray
    is_new: NDArray[np.bool_]
    origin: IntArray
    distance2: FloatArray

    @property
    def matched(self) -> NDArray[np.bool_]:
        """(K,) bool: the observation updated an existing landmark."""
        return (self.landmark >= 0) & ~self.is_new

    @property
    def discarded(self) -> NDArray[np.bool_]:
        """(K,) bool: the observation was neither matched nor used for a new landmark."""
        return self.landmark < 0


def chi2_gate(probability: float, dof: int) -> float:
    """The χ² gate: the ``probability`` quantile of the χ² distribution with ``dof`` degrees of freedom.

    Raises:
        InvalidModel: probability outside (0, 1) or dof < 1.
    """
    if not (0.0 < probability < 1.0) or dof < 1:
        raise InvalidModel(f"need 0 < probability < 1 and dof >= 1, got ({probability}, {dof})")
    # chi2.ppf(p, k) = 2 gammaincinv(k/2, p), as scipy.stats computes it (without importing scipy.stats: ~0.5 s)
    return float(2.0 * gammaincinv(0.5 * dof, probability))


def _wrap(nu: FloatArray, angle_dims: Sequence[int]) -> FloatArray:
    for d in angle_dims:
        nu[..., d] = np.mod(nu[..., d] + np.pi, 2.0 * np.pi) - np.pi
    return nu


def pairwise_mahalanobis(z: ArrayLike, z_pred: ArrayLike, S: ArrayLike, angle_dims: Sequence[int] = ()) -> FloatArray:
    """Squared Mahalanobis distances between every observation and every predicted measurement.

    Args:
        z: (K, m) observations.
        z_pred: (M, m) predicted measurements.
        S: (M, m, m) innovation covariances of the predictions.
        angle_dims: measurement components that are angles (their differences are wrapped to [-π, π)).

    Returns:
        (K, M) squared distances d²_kj.

    Raises:
        InvalidMeasurement: shapes disagree.
        NotPositiveDefinite: an S_j is not positive definite.
    """
    Z = np.asarray(z, dtype=np.float64)
    Zp = np.asarray(z_pred, dtype=np.float64)
    Sm = np.asarray(S, dtype=np.float64)
    if Z.ndim != 2 or Zp.ndim != 2 or Z.shape[1] != Zp.shape[1] or Sm.shape != (Zp.shape[0], Z.shape[1], Z.shape[1]):
        raise InvalidMeasurement(f"need z (K, m), z_pred (M, m), S (M, m, m); got {Z.shape}, {Zp.shape}, {Sm.shape}")
    if Zp.shape[0] == 0 or Z.shape[0] == 0:
        return np.zeros((Z.shape[0], Zp.shape[0]))
    try:
        L = np.linalg.cholesky(Sm)
    except np.linalg.LinAlgError as e:
        raise NotPositiveDefinite("innovation covariance S") from e
    nu = _wrap(Z[:, None, :] - Zp[None, :, :], angle_dims)  # (K, M, m)
    w = np.linalg.solve(L[None], nu[..., None])[..., 0]
    return np.einsum("kmi,kmi->km", w, w)


def nearest_neighbor(distance2: ArrayLike, gate: float) -> IntArray:
    """Greedy one-to-one nearest neighbour within a gate.

    Pairs are taken in ascending d², skipping observations and landmarks already used, until d² ≥ gate.

    Args:
        distance2: (K, M) squared Mahalanobis distances.
        gate: χ² threshold (see :func:`chi2_gate`).

    Returns:
        (K,) landmark index per observation, -1 where none is compatible or free.
    """
    D = np.asarray(distance2, dtype=np.float64)
    K = D.shape[0]
    out = np.full(K, -1, dtype=np.int64)
    if D.ndim != 2 or D.size == 0:
        return out
    flat = np.flatnonzero(D.ravel() < gate)
    order = flat[np.argsort(D.ravel()[flat], kind="stable")]
    used = np.zeros(D.shape[1], dtype=bool)
    for idx in order:
        k, j = divmod(int(idx), D.shape[1])
        if out[k] < 0 and not used[j]:
            out[k] = j
            used[j] = True
    return out


def jcbb(
    z: ArrayLike,
    z_pred: ArrayLike,
    H: ArrayLike,
    P: ArrayLike,
    R: ArrayLike,
    *,
    gate_probability: float = 0.99,
    angle_dims: Sequence[int] = (),
    max_nodes: int = 20_000,
) -> IntArray:
    """Joint compatibility branch and bound.

    Args:
        z: (K, m) observations.
        z_pred: (M, m) predicted measurements of the M landmarks.
        H: (M, m, n) Jacobians of each prediction with respect to the full state.
        P: (n, n) state covariance.
        R: (m, m) measurement noise covariance (the same for every observation).
        gate_probability: probability of the individual gate χ²_m(p) and the joint gates χ²_{m·k}(p).
        angle_dims: measurement components that are angles.
        max_nodes: search budget (interpretation-tree nodes); when it runs out the best hypothesis found so far is
            returned. The search is exact below it.

    Returns:
        (K,) landmark index per observation, -1 for observations left unpaired.

    Raises:
        InvalidMeasurement: shapes disagree.
        NotPositiveDefinite: an individual innovation covariance is not positive definite.
    """
    Z = np.asarray(z, dtype=np.float64)
    Zp = np.asarray(z_pred, dtype=np.float64)
    Hm = np.asarray(H, dtype=np.float64)
    Pm = np.asarray(P, dtype=np.float64)
    Rm = np.asarray(R, dtype=np.float64)
    K = Z.shape[0]
    best = np.full(K, -1, dtype=np.int64)
    if K == 0 or Zp.shape[0] == 0:
        return best
    M, m = Zp.shape
    n = Pm.shape[0]
    if Hm.shape != (M, m, n) or Pm.shape != (n, n) or Rm.shape != (m, m) or Z.shape[1] != m:
        raise InvalidMeasurement(
            f"need z (K, m), z_pred (M, m), H (M, m, n), P (n, n), R (m, m); got {Z.shape}, {Zp.shape}, "
            f"{Hm.shape}, {Pm.shape}, {Rm.shape}"
        )
    Hflat = Hm.reshape(M * m, n)
    C = Hflat @ Pm @ Hflat.T  # all predicted-measurement covariances and cross-covariances
    S_ind = np.stack([C[j * m : (j + 1) * m, j * m : (j + 1) * m] + Rm for j in range(M)])
    d2 = pairwise_mahalanobis(Z, Zp, S_ind, angle_dims)
    ind_gate = chi2_gate(gate_probability, m)
    candidates = [[int(j) for j in np.argsort(d2[k]) if d2[k, j] < ind_gate] for k in range(K)]
    gates = [0.0] + [chi2_gate(gate_probability, m * p) for p in range(1, K + 1)]
    nu_all = _wrap(Z[:, None, :] - Zp[None, :, :], angle_dims)  # (K, M, m)

    def joint_nis(pairs: list[tuple[int, int]]) -> float:
        rows = np.concatenate([np.arange(j * m, (j + 1) * m) for _, j in pairs])
        S = C[np.ix_(rows, rows)] + np.kron(np.eye(len(pairs)), Rm)
        nu = np.concatenate([nu_all[k, j] for k, j in pairs])
        try:
            L = np.linalg.cholesky(S)
        except np.linalg.LinAlgError:
            return math.inf
        w = np.linalg.solve(L, nu)
        return float(w @ w)

    state = {"pairs": 0, "nis": math.inf, "nodes": 0}
    current = np.full(K, -1, dtype=np.int64)

    def search(i: int, pairs: list[tuple[int, int]], used: set[int], nis: float) -> None:
        state["nodes"] += 1
        if i == K:
            p = len(pairs)
            if p > state["pairs"] or (p == state["pairs"] and p > 0 and nis < state["nis"]):
                state["pairs"], state["nis"] = p, nis
                best[:] = current
            return
        if state["nodes"] > max_nodes:
            return
        for j in candidates[i]:
            if j in used:
                continue
            trial = [*pairs, (i, j)]
            t_nis = joint_nis(trial)
            if t_nis < gates[len(trial)]:
                current[i] = j
                search(i + 1, trial, used | {j}, t_nis)
                current[i] = -1
        if len(pairs) + (K - i - 1) > state["pairs"]:
            search(i + 1, pairs, used, nis)

    search(0, [], set(), 0.0)
    return best
