"""Evaluating SLAM trajectories: Kümmerle et al.'s relative pose error, and seeded odometry corruption.

**Relative pose error** (R. Kümmerle, B. Steder, C. Dornhege, M. Ruhnke, G. Grisetti, C. Stachniss, A. Kleiner,
"On measuring the accuracy of SLAM algorithms", Autonomous Robots 27(4), 2009): for a set of relations (i, j) the
estimated relative motion δ_ij = x_i⁻¹ ∘ x_j is compared with the reference δ*_ij; the error of a relation is
e_ij = δ*_ij⁻¹ ∘ δ_ij, its translational part ‖(e_x, e_y)‖ (metres) and its rotational part |e_θ| (degrees). The
paper reports the mean and standard deviation of both parts over its relations; so do :func:`relative_pose_error`
(relations from a reference trajectory) and :func:`relation_error` (relations given as measured relative poses, as
the paper's relation files give them).
The metric does not depend on the global frame, so no alignment is needed.

The paper's relations were chosen and verified by hand (pairs of nearby poses whose scans overlap). Here the
relations are computed from the reference trajectory: :func:`consecutive_relations` (every pair of consecutive
scans, the closest analogue for logs whose scans are about a metre apart) and :func:`distance_relations` (from
every scan to the first later scan at least ``distance_m`` farther along the reference path). The reference for the
Radish/Freiburg "corrected" logs is itself a SLAM solution, not ground truth.

**Odometry corruption** (:func:`corrupt_odometry`): the corrected logs' odometry equals the corrected pose, so a
SLAM run would be handed the answer. Each increment u = x_{k−1}⁻¹ ∘ x_k of the reference (in the previous pose's
frame, travelled distance d = ‖(u_x, u_y)‖, turned angle |u_θ|) gets independent Gaussian noise

    u_x, u_y += N(0, σ_t²·d),   u_θ += N(0, σ_r²·|u_θ| + σ_b²·d),

and the noisy increments are composed from the first pose. The variances grow linearly with the motion (a random
walk per metre and per radian), so the drift does not depend on how often the log samples the motion. σ_t is in
m/√m, σ_r in rad/√rad and σ_b in rad/√m; :data:`DEFAULT_ODOMETRY_NOISE` = (0.05, 0.05, 0.02): after 100 m of
travel the position has drifted by about 0.5 m (1 σ, from σ_t alone) and the heading by 0.2 rad ≈ 11° (from σ_b).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mjnav.estimation.slam import SlamError, compose, relative

__all__ = [
    "DEFAULT_ODOMETRY_NOISE",
    "RelativePoseError",
    "consecutive_relations",
    "corrupt_odometry",
    "distance_relations",
    "relation_error",
    "relative_pose_error",
]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

DEFAULT_ODOMETRY_NOISE: tuple[float, float, float] = (0.05, 0.05, 0.02)


def _poses(value: ArrayLike, name: str) -> FloatArray:
    p = np.asarray(value, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 3 or not np.all(np.isfinite(p)):
        raise SlamError(f"{name} must be a finite (N, 3) array of poses, got shape {p.shape}")
    return p


@dataclass(frozen=True)
class RelativePoseError:
    """Kümmerle et al.'s error statistics over a set of relations.

    Attributes:
        relations: number of relations.
        trans_mean_m: mean translational error, metres.
        trans_std_m: its standard deviation, metres.
        rot_mean_deg: mean rotational error, degrees.
        rot_std_deg: its standard deviation, degrees.
        trans_errors_m: (R,) per-relation translational errors, metres.
        rot_errors_deg: (R,) per-relation rotational errors, degrees.
    """

    relations: int
    trans_mean_m: float
    trans_std_m: float
    rot_mean_deg: float
    rot_std_deg: float
    trans_errors_m: FloatArray
    rot_errors_deg: FloatArray


def relative_pose_error(estimate: ArrayLike, reference: ArrayLike, relations: ArrayLike) -> RelativePoseError:
    """Kümmerle et al.'s relative error of ``estimate`` against ``reference`` over ``relations``.

    Args:
        estimate: (N, 3) estimated poses (x, y, θ).
        reference: (N, 3) reference poses, same order.
        relations: (R, 2) index pairs (i, j), R >= 1.

    Returns:
        :class:`RelativePoseError` (standard deviations with ddof 0).

    Raises:
        SlamError: mismatched shapes, indices out of range, or no relation.
    """
    est = _poses(estimate, "estimate")
    ref = _poses(reference, "reference")
    if est.shape != ref.shape:
        raise SlamError(f"estimate and reference must have the same shape, got {est.shape} and {ref.shape}")
    rel = np.asarray(relations)
    if rel.ndim != 2 or rel.shape[1] != 2 or rel.shape[0] == 0 or rel.dtype.kind not in "iu":
        raise SlamError(f"relations must be a non-empty (R, 2) integer array, got {rel.shape}")
    if rel.min() < 0 or rel.max() >= est.shape[0]:
        raise SlamError(f"relation indices must lie in [0, {est.shape[0]})")
    return relation_error(est, rel, relative(ref[rel[:, 0]], ref[rel[:, 1]]))


def relation_error(estimate: ArrayLike, relations: ArrayLike, measured: ArrayLike) -> RelativePoseError:
    """Kümmerle et al.'s relative error of ``estimate`` against given relative poses (the paper's form: its
    relations are measured relative poses, e.g. by scan matching, not poses of a reference trajectory).

    Args:
        estimate: (N, 3) estimated poses (x, y, θ).
        relations: (R, 2) index pairs (i, j), R >= 1.
        measured: (R, 3) the reference relative pose δ*_ij = x_i⁻¹ ∘ x_j of each relation.

    Returns:
        :class:`RelativePoseError` (standard deviations with ddof 0).

    Raises:
        SlamError: mismatched shapes, indices out of range, or no relation.
    """
    est = _poses(estimate, "estimate")
    rel = np.asarray(relations)
    if rel.ndim != 2 or rel.shape[1] != 2 or rel.shape[0] == 0 or rel.dtype.kind not in "iu":
        raise SlamError(f"relations must be a non-empty (R, 2) integer array, got {rel.shape}")
    if rel.min() < 0 or rel.max() >= est.shape[0]:
        raise SlamError(f"relation indices must lie in [0, {est.shape[0]})")
    meas = _poses(measured, "measured")
    if meas.shape[0] != rel.shape[0]:
        raise SlamError(f"need one measured relative pose per relation, got {meas.shape[0]} for {rel.shape[0]}")
    i, j = rel[:, 0], rel[:, 1]
    err = relative(meas, relative(est[i], est[j]))
    t = np.hypot(err[:, 0], err[:, 1])
    r = np.degrees(np.abs(err[:, 2]))
    return RelativePoseError(int(t.size), float(t.mean()), float(t.std()), float(r.mean()), float(r.std()), t, r)


def consecutive_relations(n: int) -> IntArray:
    """(n − 1, 2) relations (k, k + 1) of n poses."""
    if n < 2:
        raise SlamError(f"need at least 2 poses for a relation, got {n}")
    k = np.arange(n - 1, dtype=np.int64)
    return np.column_stack((k, k + 1))


def distance_relations(reference: ArrayLike, distance_m: float) -> IntArray:
    """Relations from every pose i to the first later pose j at least ``distance_m`` farther along the path.

    Args:
        reference: (N, 3) reference poses; the path length is the sum of their consecutive distances.
        distance_m: path distance, metres (> 0).

    Returns:
        (R, 2) int relations (poses with no such successor have none).

    Raises:
        SlamError: a bad distance or pose array.
    """
    ref = _poses(reference, "reference")
    if not (math.isfinite(distance_m) and distance_m > 0):
        raise SlamError(f"distance_m must be finite and > 0, got {distance_m}")
    s = np.concatenate(([0.0], np.cumsum(np.hypot(*np.diff(ref[:, :2], axis=0).T))))
    j = np.searchsorted(s, s + distance_m, side="left")
    i = np.flatnonzero(j < ref.shape[0])
    return np.column_stack((i, j[i])).astype(np.int64)


def corrupt_odometry(
    reference: ArrayLike,
    rng: np.random.Generator,
    sigmas: tuple[float, float, float] = DEFAULT_ODOMETRY_NOISE,
) -> FloatArray:
    """Noisy odometry from a reference trajectory (the module doc gives the model).

    Args:
        reference: (N, 3) poses (x, y, θ); N >= 1.
        rng: the random generator (seed it for a reproducible run).
        sigmas: (σ_t m/√m, σ_r rad/√rad, σ_b rad/√m), each >= 0.

    Returns:
        (N, 3) odometry poses starting at the first reference pose.

    Raises:
        SlamError: a bad pose array or a negative/non-finite sigma.
    """
    ref = _poses(reference, "reference")
    if len(sigmas) != 3 or not all(math.isfinite(v) and v >= 0 for v in sigmas):
        raise SlamError(f"odometry sigmas must be three finite numbers >= 0, got {sigmas!r}")
    st, sr, sb = (float(v) for v in sigmas)
    u = relative(ref[:-1], ref[1:])
    d = np.hypot(u[:, 0], u[:, 1])
    noise = rng.standard_normal((u.shape[0], 3))
    u_noisy = u.copy()
    u_noisy[:, 0] += st * np.sqrt(d) * noise[:, 0]
    u_noisy[:, 1] += st * np.sqrt(d) * noise[:, 1]
    u_noisy[:, 2] += np.sqrt(sr * sr * np.abs(u[:, 2]) + sb * sb * d) * noise[:, 2]
    out = np.empty_like(ref)
    out[0] = ref[0]
    for k in range(u.shape[0]):
        out[k + 1] = compose(out[k], u_noisy[k])
    return out
