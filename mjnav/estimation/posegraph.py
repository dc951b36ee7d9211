"""SE(2) pose-graph optimisation: sparse Levenberg–Marquardt, chordal initialisation and SE-Sync's certificate.

A pose graph holds N planar poses ``(x, y, θ)`` (metres, metres, radians, world frame) and M relative-pose
measurements ``z_ij = (dx, dy, dθ)`` of vertex ``j`` in the frame of vertex ``i``, each with a 3×3 information
matrix ``Ω`` (inverse covariance, in the order x, y, θ). Two objectives are reported for any set of poses:

* g2o's χ²: ``Σ e_ijᵀ Ω e_ij`` with ``e_ij = t2v(Z_ij⁻¹ · X_i⁻¹ · X_j)`` (the error g2o's ``EDGE_SE2`` computes),
* SE-Sync's objective (Rosen et al., IJRR 2019, eq. 8 with the isotropic weights of its data sets):
  ``F = Σ κ ‖R_j − R_i·Rot(dθ)‖²_F + τ ‖t_j − t_i − R_i·t_ij‖²`` with ``κ = Ω_θθ`` and
  ``τ = 2 / trace(inv(Ω_tt))``, ``R`` the 2×2 rotation matrices.

:func:`optimize_pose_graph` minimises one of them (``objective="sesync"`` by default, the objective whose global
optimum SE-Sync certifies) from a chordal initialisation (Carlone et al., ICRA 2015: relax the rotations to
unconstrained complex numbers, solve the linear least squares, project onto the unit circle, then solve the
translations) by Levenberg–Marquardt on the poses:

* the Hessian is assembled in one vectorised scatter into a CSC pattern fixed at set-up and factored by CHOLMOD's
  sparse Cholesky under a fill-reducing (AMD) ordering analysed once;
* on F the steps are exact Newton (F's chordal residuals make Gauss–Newton converge only linearly), falling back to
  Gauss–Newton where the exact Hessian is not positive definite;
* on F, after each step the translations move to their exact optimum for the new rotations (F is quadratic in them:
  one solve with a Laplacian factored once; Kaufman's variable projection);
* near the optimum the previous factor preconditions a few conjugate-gradient iterations instead of a new
  factorisation.

:func:`certify_global_optimality` runs SE-Sync's verification: with ``x`` the poses as complex numbers,
``F = xᴴ M x``; at a critical point ``M x = Λ x`` on the rotation block, and ``S = M − diag(0, Λ) ⪰ 0`` proves ``x``
is a global minimiser of ``F``.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace
from typing import Literal

import numpy as np
import scipy.sparse as sp
from numba import njit
from numpy.typing import NDArray
from scipy.sparse.csgraph import breadth_first_order, connected_components, minimum_spanning_tree
from scipy.sparse.linalg import ArpackNoConvergence, LinearOperator, eigsh
from sksparse.cholmod import CholmodNotPositiveDefiniteError, Factor, analyze

from mjnav.estimation._graph_kernels import g2o_blocks
from mjnav.estimation.errors import EstimationError

__all__ = [
    "OptimalityCertificate",
    "PoseGraph",
    "PoseGraphError",
    "PoseGraphResult",
    "certify_global_optimality",
    "g2o_chi2",
    "odometry_guess",
    "optimize_pose_graph",
    "sesync_objective",
    "sesync_weights",
]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

Robust = Literal["huber", "cauchy"]
Objective = Literal["sesync", "g2o"]
Method = Literal["lm", "gn"]
Init = Literal["auto", "chordal", "graph"]

# sqrt of the 95 % quantile of χ² with 3 degrees of freedom: an edge whose squared error exceeds 7.81 is unlikely
# (p < 5 %) under its own information matrix, so the kernels start down-weighting there.
DEFAULT_ROBUST_WIDTH = math.sqrt(7.814727903251178)


class PoseGraphError(EstimationError, ValueError):
    """Invalid pose graph, poses or options (bad shapes, non-finite values, disconnected graph, …)."""


# --------------------------------------------------------------------------------------------------------------------
# The graph


@dataclass(frozen=True)
class PoseGraph:
    """An SE(2) pose graph.

    Attributes:
        poses: (N, 3) float array: x, y (metres) and θ (radians) of each vertex, world frame; the initial guess.
        edges: (M, 2) int array: indices ``(i, j)`` into ``poses`` of each measurement (``j`` seen from ``i``).
        measurements: (M, 3) float array: ``(dx, dy, dθ)`` of vertex ``j`` in the frame of vertex ``i``.
        information: (M, 3, 3) float array: symmetric positive-definite information matrices (order x, y, θ).
        ids: (N,) int array: vertex ids as a file names them (empty, the default, means ``0..N-1``).
    """

    poses: FloatArray
    edges: IntArray
    measurements: FloatArray
    information: FloatArray
    ids: IntArray = field(default_factory=lambda: np.empty(0, dtype=np.int64))

    def __post_init__(self) -> None:
        # Own copies, made read-only (the caller's arrays stay writable and cannot change the graph).
        poses = np.array(self.poses, dtype=np.float64, order="C")
        edges = np.array(self.edges, dtype=np.int64, order="C")
        meas = np.array(self.measurements, dtype=np.float64, order="C")
        info = np.array(self.information, dtype=np.float64, order="C")
        if poses.ndim != 2 or poses.shape[1] != 3 or poses.shape[0] < 1:
            raise PoseGraphError(f"poses must be (N, 3) with N >= 1, got {poses.shape}")
        n = poses.shape[0]
        if edges.ndim != 2 or edges.shape[1] != 2:
            raise PoseGraphError(f"edges must be (M, 2), got {edges.shape}")
        m = edges.shape[0]
        if meas.shape != (m, 3):
            raise PoseGraphError(f"measurements must be ({m}, 3), got {meas.shape}")
        if info.shape != (m, 3, 3):
            raise PoseGraphError(f"information must be ({m}, 3, 3), got {info.shape}")
        if not (np.isfinite(poses).all() and np.isfinite(meas).all() and np.isfinite(info).all()):
            raise PoseGraphError("poses, measurements and information must be finite")
        if m and (edges.min() < 0 or edges.max() >= n):
            raise PoseGraphError(f"edge indices must lie in [0, {n})")
        if m and np.any(edges[:, 0] == edges[:, 1]):
            bad = int(np.flatnonzero(edges[:, 0] == edges[:, 1])[0])
            raise PoseGraphError(f"edge {bad} joins vertex {edges[bad, 0]} to itself")
        if m:
            if not np.allclose(info, np.swapaxes(info, 1, 2), rtol=1e-9, atol=0.0):
                raise PoseGraphError("information matrices must be symmetric")
            eig = np.linalg.eigvalsh(info)
            if np.any(eig[:, 0] <= 0.0):
                bad = int(np.flatnonzero(eig[:, 0] <= 0.0)[0])
                raise PoseGraphError(f"information matrix of edge {bad} is not positive definite")
        if np.size(self.ids) == 0:
            ids = np.arange(n, dtype=np.int64)
        else:
            ids = np.array(self.ids, dtype=np.int64, order="C")
            if ids.shape != (n,):
                raise PoseGraphError(f"ids must be ({n},), got {ids.shape}")
            if np.unique(ids).size != n:
                raise PoseGraphError("vertex ids must be unique")
        for name, arr in (("poses", poses), ("edges", edges), ("measurements", meas), ("information", info)):
            arr.flags.writeable = False
            object.__setattr__(self, name, arr)
        ids.flags.writeable = False
        object.__setattr__(self, "ids", ids)

    @property
    def num_vertices(self) -> int:
        """N, the number of poses."""
        return int(self.poses.shape[0])

    @property
    def num_edges(self) -> int:
        """M, the number of measurements."""
        return int(self.edges.shape[0])

    def with_poses(self, poses: FloatArray) -> PoseGraph:
        """The same graph with other poses ((N, 3) x, y, θ)."""
        return PoseGraph(poses, self.edges, self.measurements, self.information, self.ids)


@dataclass(frozen=True)
class OptimalityCertificate:
    """SE-Sync's verification of global optimality for the objective F.

    Attributes:
        certified: True when ``lambda_min >= -tolerance``: the poses are a global minimiser of F (up to the
            numerical tolerance).
        lambda_min: smallest eigenvalue of the certificate matrix ``S = M − diag(0, Λ)`` (F's units); 0 at an
            exact certified optimum (S x = 0), clearly negative at a local minimum that is not global.
        tolerance: the threshold used (absolute, F's units).
        stationarity: ``‖S x‖ / ‖M x‖`` (dimensionless): how close the poses are to a critical point of F.
    """

    certified: bool
    lambda_min: float
    tolerance: float
    stationarity: float


@dataclass(frozen=True)
class PoseGraphResult:
    """What :func:`optimize_pose_graph` returns.

    Attributes:
        poses: (N, 3) float array, optimised x, y (metres), θ (radians, wrapped to (−π, π]); vertex 0 is held fixed.
        iterations: Levenberg–Marquardt (or Gauss–Newton) iterations taken, rejected LM steps included.
        time_s: wall-clock seconds of the optimisation (initialisation included, certificate excluded).
        chi2: g2o's χ² at ``poses`` (no robust kernel).
        sesync_objective: SE-Sync's objective F at ``poses``.
        initial_chi2: g2o's χ² at the graph's initial poses.
        initial_sesync_objective: F at the graph's initial poses.
        cost: the minimised cost at ``poses`` (the chosen objective, through the robust kernel if any).
        converged: True when the relative cost decrease fell below the tolerance before ``max_iterations``.
        certificate: SE-Sync's global-optimality certificate when requested (``certify=True``), else None.
        certificate_time_s: wall-clock seconds of the certificate (0 when not requested).
    """

    poses: FloatArray
    iterations: int
    time_s: float
    chi2: float
    sesync_objective: float
    initial_chi2: float
    initial_sesync_objective: float
    cost: float
    converged: bool
    certificate: OptimalityCertificate | None = None
    certificate_time_s: float = 0.0

    @property
    def time(self) -> float:
        """Alias of ``time_s`` (seconds)."""
        return self.time_s


# --------------------------------------------------------------------------------------------------------------------
# Small helpers


def _wrap(a: FloatArray) -> FloatArray:
    """Angles wrapped to (−π, π]."""
    return np.asarray(-(np.remainder(-np.asarray(a) + np.pi, 2.0 * np.pi) - np.pi), dtype=np.float64)


def _check_poses(graph: PoseGraph, poses: FloatArray | None) -> FloatArray:
    if poses is None:
        return graph.poses
    p = np.asarray(poses, dtype=np.float64)
    if p.shape != graph.poses.shape:
        raise PoseGraphError(f"poses must be {graph.poses.shape}, got {p.shape}")
    if not np.isfinite(p).all():
        raise PoseGraphError("poses must be finite")
    return p


def sesync_weights(graph: PoseGraph) -> tuple[FloatArray, FloatArray]:
    """SE-Sync's isotropic weights of each edge.

    Returns:
        (kappa, tau): two (M,) float arrays; ``κ = Ω_θθ`` (1/rad²) and ``τ = 2 / trace(inv(Ω_tt))`` (1/m²), with
        ``Ω_tt`` the 2×2 translational block of the information matrix.
    """
    info = graph.information
    kappa = info[:, 2, 2].copy()
    a, b, d = info[:, 0, 0], info[:, 0, 1], info[:, 1, 1]
    det = a * d - b * b
    tau = 2.0 * det / (a + d)  # trace(inv(Ω_tt)) = (a + d) / det
    return kappa, tau


def g2o_chi2(graph: PoseGraph, poses: FloatArray | None = None) -> float:
    """g2o's χ² ``Σ eᵀ Ω e`` with ``e = t2v(Z⁻¹ X_i⁻¹ X_j)`` (angle wrapped); dimensionless.

    Args:
        graph: the pose graph.
        poses: (N, 3) poses to evaluate; the graph's own poses when None.
    """
    p = _check_poses(graph, poses)
    e = _g2o_errors(graph, p)
    return float(np.sum(e * (graph.information @ e[:, :, None])[:, :, 0]))


def sesync_objective(graph: PoseGraph, poses: FloatArray | None = None) -> float:
    """SE-Sync's objective ``F = Σ κ‖R_j − R_i Rot(dθ)‖²_F + τ‖t_j − t_i − R_i t_ij‖²`` (see the module doc).

    Args:
        graph: the pose graph.
        poses: (N, 3) poses to evaluate; the graph's own poses when None.
    """
    p = _check_poses(graph, poses)
    kappa, tau = sesync_weights(graph)
    r = _sesync_residuals(graph, p, kappa, tau)
    return float(np.sum(r * r))


def _g2o_errors(graph: PoseGraph, p: FloatArray) -> FloatArray:
    i, j = graph.edges[:, 0], graph.edges[:, 1]
    z = graph.measurements
    ci, si = np.cos(p[i, 2]), np.sin(p[i, 2])
    cz, sz = np.cos(z[:, 2]), np.sin(z[:, 2])
    dx, dy = p[j, 0] - p[i, 0], p[j, 1] - p[i, 1]
    ux = ci * dx + si * dy - z[:, 0]  # R_iᵀ (t_j − t_i) − t_z
    uy = -si * dx + ci * dy - z[:, 1]
    e = np.empty((graph.num_edges, 3))
    e[:, 0] = cz * ux + sz * uy  # R_zᵀ (…)
    e[:, 1] = -sz * ux + cz * uy
    e[:, 2] = _wrap(p[j, 2] - p[i, 2] - z[:, 2])
    return e


def _sesync_residuals(graph: PoseGraph, p: FloatArray, kappa: FloatArray, tau: FloatArray) -> FloatArray:
    """(M, 4) whitened residuals whose squared sum is F: √(2κ)·(rotation columns), √τ·(translation)."""
    i, j = graph.edges[:, 0], graph.edges[:, 1]
    z = graph.measurements
    a = p[i, 2] + z[:, 2]
    ci, si = np.cos(p[i, 2]), np.sin(p[i, 2])
    sk, st = np.sqrt(2.0 * kappa), np.sqrt(tau)
    r = np.empty((graph.num_edges, 4))
    r[:, 0] = sk * (np.cos(p[j, 2]) - np.cos(a))
    r[:, 1] = sk * (np.sin(p[j, 2]) - np.sin(a))
    r[:, 2] = st * (p[j, 0] - p[i, 0] - (ci * z[:, 0] - si * z[:, 1]))
    r[:, 3] = st * (p[j, 1] - p[i, 1] - (si * z[:, 0] + ci * z[:, 1]))
    return r


# --------------------------------------------------------------------------------------------------------------------
# Initial guesses


def odometry_guess(graph: PoseGraph) -> FloatArray:
    """Poses composed from the odometry edges ``k−1 → k`` (by vertex index), starting at the graph's pose 0.

    The composition runs along a spanning tree that prefers the odometry edges (``k−1 → k`` or ``k → k−1``,
    inverted): a graph whose odometry chain is complete gets exactly the dead-reckoned poses; where the chain is
    broken (ais2klinik between vertices 7289 and 7290) the tree bridges the gap with a loop-closure edge.

    Returns:
        (N, 3) float array, x, y (metres), θ (radians, wrapped).

    Raises:
        PoseGraphError: the graph is disconnected.
    """
    _check_connected(graph)
    n = graph.num_vertices
    if n == 1:
        return graph.poses.copy()
    i, j = graph.edges[:, 0], graph.edges[:, 1]
    lo, hi = np.minimum(i, j), np.maximum(i, j)
    key = lo * n + hi
    order = np.argsort(key, kind="stable")  # the first edge of each vertex pair in file order comes first
    ukey, first = np.unique(key[order], return_index=True)
    chosen = order[first]  # one edge per vertex pair
    weight = np.where(hi[chosen] - lo[chosen] == 1, 1.0, 1000.0)
    adj = sp.csr_matrix((weight, (lo[chosen], hi[chosen])), shape=(n, n))
    tree = minimum_spanning_tree(adj)
    bfs, pred = breadth_first_order(tree, 0, directed=False, return_predecessors=True)
    kids = bfs[1:]
    parents = pred[kids]
    pair = np.minimum(kids, parents) * n + np.maximum(kids, parents)
    edge = chosen[np.searchsorted(ukey, pair)]
    forward = i[edge] == parents  # edge parent → kid: the measurement as is; else its inverse
    z = graph.measurements[edge]
    c, s = np.cos(z[:, 2]), np.sin(z[:, 2])
    step = np.where(
        forward[:, None], z, np.stack([-(c * z[:, 0] + s * z[:, 1]), -(-s * z[:, 0] + c * z[:, 1]), -z[:, 2]], 1)
    )
    out = np.empty((n, 3))
    out[0] = graph.poses[0]
    _compose_tree(out, kids.astype(np.int64), parents.astype(np.int64), step)
    out[:, 2] = _wrap(out[:, 2])
    return out


@njit(cache=True)
def _compose_tree(poses: FloatArray, kids: IntArray, parents: IntArray, step: FloatArray) -> None:  # pragma: no cover
    """poses[kid] = poses[parent] ⊕ step, in breadth-first order (parents before their children)."""
    for k in range(kids.shape[0]):
        a, b = parents[k], kids[k]
        c, s = math.cos(poses[a, 2]), math.sin(poses[a, 2])
        poses[b, 0] = poses[a, 0] + c * step[k, 0] - s * step[k, 1]
        poses[b, 1] = poses[a, 1] + s * step[k, 0] + c * step[k, 1]
        poses[b, 2] = poses[a, 2] + step[k, 2]


def _spd_solve(a: sp.spmatrix, b: FloatArray) -> FloatArray:
    """Solve ``a x = b`` for a sparse symmetric positive-definite ``a`` with CHOLMOD (AMD ordering)."""
    a = sp.csc_matrix(a)
    factor = analyze(a, mode="simplicial", ordering_method="amd")
    if not _factor_ok(factor, a, 0.0):
        raise PoseGraphError("the linear system is singular: is the graph connected?")
    return np.asarray(factor(b), dtype=np.float64)


def _chordal_guess(graph: PoseGraph, translations: _Translations | None = None) -> FloatArray:
    """Carlone et al.'s chordal initialisation in complex form, vertex 0 held at the graph's pose 0.

    Rotations ``z_k = e^{iθ_k}``: minimise ``Σ κ |z_j − z_i e^{i dθ}|²`` over unconstrained complex ``z`` (a linear
    least-squares problem), project to the unit circle; then minimise ``Σ τ |p_j − p_i − z_i t_ij|²`` over the
    translations ``p`` (a weighted graph Laplacian solve).
    """
    n = graph.num_vertices
    kappa, tau = sesync_weights(graph)
    i, j = graph.edges[:, 0], graph.edges[:, 1]
    z = graph.measurements
    w = np.exp(1j * z[:, 2])
    # Hermitian normal matrix of Σ κ |z_j − w z_i|², then realified: c = a + ib → [[Re, −Im], [Im, Re]].
    rows = np.concatenate([i, j, j, i])
    cols = np.concatenate([i, j, i, j])
    vals = np.concatenate([kappa, kappa, -kappa * w, -kappa * np.conj(w)])
    a = sp.csr_matrix((vals, (rows, cols)), shape=(n, n))
    z0 = np.exp(1j * graph.poses[0, 2])
    rhs = -np.asarray(a[1:, 0].toarray()).ravel() * z0
    ar = a[1:, 1:]
    big = sp.bmat([[ar.real, -ar.imag], [ar.imag, ar.real]], format="csc")
    sol = _spd_solve(big, np.concatenate([rhs.real, rhs.imag]))
    zc = np.empty(n, dtype=np.complex128)
    zc[0] = z0
    zc[1:] = sol[: n - 1] + 1j * sol[n - 1 :]
    if np.any(np.abs(zc) < 1e-12):
        raise PoseGraphError("chordal relaxation gave a zero rotation; use init='graph'")
    theta = np.angle(zc)
    out = np.empty((n, 3))
    out[0] = graph.poses[0]
    out[:, 2] = theta
    out[1:, :2] = (translations or _Translations(graph, tau)).solve(theta)
    return out


class _Translations:
    """The translations minimising F for given rotations: ``Σ τ |p_j − p_i − R_i t_ij|²`` is a weighted graph
    Laplacian ``L p = b(θ)`` whose matrix does not depend on the rotations, so one factorisation serves every θ."""

    def __init__(self, graph: PoseGraph, tau: FloatArray) -> None:
        n = graph.num_vertices
        i, j = graph.edges[:, 0], graph.edges[:, 1]
        lap = sp.csr_matrix(
            (np.concatenate([tau, tau, -tau, -tau]), (np.concatenate([i, j, i, j]), np.concatenate([i, j, j, i]))),
            shape=(n, n),
        )
        self.graph, self.tau, self.n = graph, tau, n
        self.anchor = np.asarray(lap[1:, 0].toarray()) * graph.poses[0, :2][None, :]  # vertex 0 held
        reduced = sp.csc_matrix(lap[1:, 1:])
        self.factor = analyze(reduced, mode="simplicial", ordering_method="amd")
        if not _factor_ok(self.factor, reduced, 0.0):
            raise PoseGraphError("the translation Laplacian is singular: is the graph connected?")

    def solve(self, theta: FloatArray) -> FloatArray:
        """(N − 1, 2) translations of vertices 1…N−1 (metres) for rotations θ ((N,) radians)."""
        g = self.graph
        i, j = g.edges[:, 0], g.edges[:, 1]
        z = g.measurements
        ci, si = np.cos(theta[i]), np.sin(theta[i])
        wx = self.tau * (ci * z[:, 0] - si * z[:, 1])
        wy = self.tau * (si * z[:, 0] + ci * z[:, 1])
        b = np.empty((self.n, 2))
        b[:, 0] = np.bincount(j, weights=wx, minlength=self.n) - np.bincount(i, weights=wx, minlength=self.n)
        b[:, 1] = np.bincount(j, weights=wy, minlength=self.n) - np.bincount(i, weights=wy, minlength=self.n)
        return np.asarray(self.factor(b[1:] - self.anchor), dtype=np.float64).reshape(self.n - 1, 2)


# --------------------------------------------------------------------------------------------------------------------
# Levenberg–Marquardt


class _Assembler:
    """Scatters per-edge 3×3 Hessian blocks into a fixed CSC pattern (vertex 0 removed as the gauge)."""

    def __init__(self, edges: IntArray, n: int) -> None:
        i, j = edges[:, 0], edges[:, 1]
        nb = n - 1
        nv = 3 * nb
        # Vertex-pair blocks of each edge, in the order ii, ij, ji, jj; blocks touching vertex 0 are dropped.
        br = np.stack([i, i, j, j], axis=1).ravel() - 1
        bc = np.stack([i, j, i, j], axis=1).ravel() - 1
        kept = np.flatnonzero((br >= 0) & (bc >= 0))
        ukey, q = np.unique(br[kept] * nb + bc[kept], return_inverse=True)
        ur, uc = ukey // nb, ukey % nb  # unique blocks sorted by (row, col)
        bptr = np.searchsorted(ur, np.arange(nb + 1))
        if np.any(np.diff(bptr) == 0):
            raise PoseGraphError("the graph is disconnected: some vertex has no edge")
        cnt = np.diff(bptr)
        # Scalar CSR (= CSC, the matrix is symmetric): row 3r + k holds, for each block of block-row r in column
        # order, its three entries; entry (k, l) of unique block u sits at 9·bptr[r] + 3k·cnt[r] + 3(u − bptr[r]) + l.
        kk, ll = np.repeat(np.arange(3), 3), np.tile(np.arange(3), 3)
        nu = ukey.size
        # Per unique block: where its entry (0, 0) goes and the stride between its rows; then (nu, 9) positions.
        base = 9 * bptr[ur] + 3 * (np.arange(nu) - bptr[ur])
        stride = 3 * cnt[ur]
        pos = base[:, None] + stride[:, None] * kk[None, :] + ll[None, :]  # (nu, 9)
        indices = np.empty(9 * nu, dtype=np.int32)
        indices[pos.ravel()] = (3 * uc[:, None] + ll[None, :]).ravel()
        indptr = np.empty(nv + 1, dtype=np.int64)
        indptr[:-1] = (9 * bptr[:-1, None] + 3 * np.arange(3)[None, :] * cnt[:, None]).ravel()
        indptr[-1] = 9 * nu
        self.indices, self.indptr = indices, indptr.astype(np.int32)
        self.nnz = 9 * nu
        # Where each kept per-edge block entry goes, and the data slots of the diagonal.
        self.kept = (kept[:, None] * 9 + np.arange(9)[None, :]).ravel()
        self.slot = pos[q].ravel()
        self.diag = np.sort(pos[ur == uc][:, [0, 4, 8]].ravel())
        self.nv = nv
        self.n = n
        # Gradient slots 3·vertex + component for the stacked (gi; gj) entries.
        self.slots = (3 * np.concatenate([i, j])[:, None] + np.arange(3)[None, :]).ravel()

    def matrix(self, blocks: FloatArray) -> sp.csc_matrix:
        """(M, 4, 3, 3) blocks (ii, ij, ji, jj) → the (3(N−1))² CSC matrix."""
        data = np.bincount(self.slot, weights=blocks.reshape(-1)[self.kept], minlength=self.nnz)
        return sp.csc_matrix((data, self.indices, self.indptr), shape=(self.nv, self.nv))

    def vector(self, gi: FloatArray, gj: FloatArray) -> FloatArray:
        """(M, 3) per-edge gradient parts of vertices i and j → the 3(N−1) gradient."""
        g = np.bincount(self.slots, weights=np.concatenate([gi, gj]).ravel(), minlength=3 * self.n)
        return np.asarray(g[3:], dtype=np.float64)


def _robust(s: FloatArray, robust: Robust | None, width: float) -> tuple[FloatArray, FloatArray]:
    """Robust cost ρ(s) and weight ρ'(s) of squared errors s (g2o's kernels, on the squared error)."""
    if robust is None:
        return s, np.ones_like(s)
    d2 = width * width
    if robust == "huber":
        root = np.sqrt(np.maximum(s, 1e-300))
        inside = s <= d2
        return np.where(inside, s, 2.0 * width * root - d2), np.where(inside, 1.0, width / root)
    if robust == "cauchy":
        return d2 * np.log1p(s / d2), 1.0 / (1.0 + s / d2)
    raise PoseGraphError(f"unknown robust kernel {robust!r} (use None, 'huber' or 'cauchy')")


class _Problem:
    """Residuals, Jacobians and normal equations of one objective."""

    def __init__(self, graph: PoseGraph, objective: Objective, robust: Robust | None, width: float) -> None:
        self.graph = graph
        self.objective = objective
        self.robust = robust
        self.width = width
        self.kappa, self.tau = sesync_weights(graph)
        self.asm = _Assembler(graph.edges, graph.num_vertices)

    def residuals(self, p: FloatArray) -> tuple[FloatArray, FloatArray]:
        """(M, k) whitened residuals and their per-edge squared norms."""
        if self.objective == "sesync":
            r = _sesync_residuals(self.graph, p, self.kappa, self.tau)
            return r, np.sum(r * r, axis=1)
        e = _g2o_errors(self.graph, p)
        return e, np.sum(e * (self.graph.information @ e[:, :, None])[:, :, 0], axis=1)

    def cost(self, p: FloatArray) -> tuple[float, tuple[FloatArray, FloatArray]]:
        """The cost ``Σ ρ(‖r‖²)`` at ``p``, and the residuals (to hand to :meth:`normal_equations`)."""
        r, s = self.residuals(p)
        rho, _ = _robust(s, self.robust, self.width)
        return float(np.sum(rho)), (r, s)

    def normal_equations(
        self, p: FloatArray, residuals: tuple[FloatArray, FloatArray] | None = None
    ) -> tuple[sp.csc_matrix, sp.csc_matrix, FloatArray, float]:
        """Half the Hessian twice — Gauss–Newton (positive semidefinite) and exact Newton (with the residuals'
        second derivatives) —, half the gradient, and the cost ``Σ ρ(‖r‖²)`` at ``p`` (IRLS-weighted)."""
        m = self.graph.num_edges
        r, s = self.residuals(p) if residuals is None else residuals
        rho, w = _robust(s, self.robust, self.width)
        blocks = np.zeros((m, 4, 3, 3))  # ii, ij, ji, jj
        if self.objective == "sesync":
            gi, gj, second = self._sesync_blocks(p, r, w, blocks)
        else:
            gi, gj = self._g2o_blocks(p, r, w, blocks)
            second = None
        blocks[:, 2] = np.swapaxes(blocks[:, 1], 1, 2)
        h_gn = self.asm.matrix(blocks)
        h_exact = h_gn
        if second is not None:
            h_exact = h_gn.copy()
            h_exact.data[self.asm.diag[2::3]] += second[1:]  # θθ entries of vertices 1…N−1
        return h_gn, h_exact, self.asm.vector(gi, gj), float(np.sum(rho))

    def _sesync_blocks(
        self, p: FloatArray, r: FloatArray, w: FloatArray, blocks: FloatArray
    ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Exact Newton blocks of F, written out (the Jacobians are mostly constant ±√τ).

        Residual Jacobians: vertex i ``[[0,0,A0],[0,0,A1],[−√τ,0,B0],[0,−√τ,B1]]``, vertex j
        ``[[0,0,C0],[0,0,C1],[√τ,0,0],[0,√τ,0]]``. The θθ entries also get ``Σ_k r_k ∂²r_k``: F's rotation residuals
        are chords, and Gauss–Newton alone overestimates their curvature and converges only linearly.
        """
        i, j = self.graph.edges[:, 0], self.graph.edges[:, 1]
        z = self.graph.measurements
        sk2, st2 = 2.0 * self.kappa, self.tau
        sk, st = np.sqrt(sk2), np.sqrt(st2)
        a = p[i, 2] + z[:, 2]
        ca, sa = np.cos(a), np.sin(a)
        cj, sj = np.cos(p[j, 2]), np.sin(p[j, 2])
        ci, si = np.cos(p[i, 2]), np.sin(p[i, 2])
        rzx = ci * z[:, 0] - si * z[:, 1]  # R_i t_ij
        rzy = si * z[:, 0] + ci * z[:, 1]
        a0, a1 = sk * sa, -sk * ca
        b0, b1 = st * rzy, -st * rzx
        c0, c1 = -sk * sj, sk * cj
        wr = r * w[:, None]
        wst2 = w * st2
        second_i = sk * (wr[:, 0] * ca + wr[:, 1] * sa) + st * (wr[:, 2] * rzx + wr[:, 3] * rzy)
        second_j = -sk * (wr[:, 0] * cj + wr[:, 1] * sj)
        hi = blocks[:, 0]
        hi[:, 0, 0] = wst2
        hi[:, 1, 1] = wst2
        hi[:, 0, 2] = hi[:, 2, 0] = -w * st * b0
        hi[:, 1, 2] = hi[:, 2, 1] = -w * st * b1
        hi[:, 2, 2] = w * (sk2 + b0 * b0 + b1 * b1)
        hij = blocks[:, 1]
        hij[:, 0, 0] = -wst2
        hij[:, 1, 1] = -wst2
        hij[:, 2, 0] = w * st * b0
        hij[:, 2, 1] = w * st * b1
        hij[:, 2, 2] = w * (a0 * c0 + a1 * c1)
        hj = blocks[:, 3]
        hj[:, 0, 0] = wst2
        hj[:, 1, 1] = wst2
        hj[:, 2, 2] = w * sk2
        n = self.graph.num_vertices
        second = np.bincount(i, weights=second_i, minlength=n) + np.bincount(j, weights=second_j, minlength=n)
        gi = np.stack(
            [-st * wr[:, 2], -st * wr[:, 3], a0 * wr[:, 0] + a1 * wr[:, 1] + b0 * wr[:, 2] + b1 * wr[:, 3]], 1
        )
        gj = np.stack([st * wr[:, 2], st * wr[:, 3], c0 * wr[:, 0] + c1 * wr[:, 1]], 1)
        return gi, gj, np.asarray(second, dtype=np.float64)

    def _g2o_blocks(
        self, p: FloatArray, r: FloatArray, w: FloatArray, blocks: FloatArray
    ) -> tuple[FloatArray, FloatArray]:
        """Gauss–Newton blocks of g2o's χ² (a numba kernel over the edges). Its exact Hessian is often
        indefinite away from the optimum (wrapped angles, large translational information), and measured on the
        SE-Sync graphs it took more iterations, not fewer."""
        g = self.graph
        return g2o_blocks(p, g.edges[:, 0].copy(), g.edges[:, 1].copy(), g.measurements, g.information, w, r, blocks)


def _check_connected(graph: PoseGraph) -> None:
    n = graph.num_vertices
    if n == 1:
        return
    adj = sp.csr_matrix((np.ones(graph.num_edges), (graph.edges[:, 0], graph.edges[:, 1])), shape=(n, n))
    count, _ = connected_components(adj, directed=False)
    if count != 1:
        raise PoseGraphError(f"the graph is disconnected ({count} components): the poses are not determined")


def optimize_pose_graph(
    graph: PoseGraph,
    method: Method = "lm",
    robust: Robust | None = None,
    *,
    objective: Objective = "sesync",
    init: Init = "auto",
    robust_width: float = DEFAULT_ROBUST_WIDTH,
    max_iterations: int = 100,
    tolerance: float = 1e-9,
    certify: bool = False,
    certificate_tolerance: float = 1e-6,
) -> PoseGraphResult:
    """Optimise the poses of an SE(2) pose graph; vertex 0 stays where the graph has it (the gauge).

    Args:
        graph: the pose graph; its poses are the initial guess for ``init="graph"``.
        method: ``"lm"`` (Levenberg–Marquardt, Marquardt's diagonal scaling, Nielsen's damping update) or
            ``"gn"`` (plain Gauss–Newton steps).
        robust: None (least squares), ``"huber"`` or ``"cauchy"``: a kernel ρ on each edge's squared error s
            (iteratively reweighted with ρ'(s)), g2o's definitions with width ``robust_width``.
        objective: ``"sesync"`` minimises SE-Sync's F (chordal on rotation matrices; the objective whose global
            optimum :func:`certify_global_optimality` can prove); ``"g2o"`` minimises g2o's χ².
        init: ``"chordal"`` starts from the chordal relaxation (rotations, then translations), ``"graph"`` from
            the graph's poses; ``"auto"`` is chordal without a robust kernel and the graph's poses with one (the
            relaxation itself is not robust to outliers).
        robust_width: kernel width δ on the error (√s), dimensionless; default √χ²₃(0.95) ≈ 2.80.
        max_iterations: iteration cap.
        tolerance: stop when the relative cost decrease of an accepted step is below this (or when the step is
            below 1e-10 of the pose magnitudes).
        certify: also run :func:`certify_global_optimality` on the result (only meaningful for
            ``objective="sesync"`` without a robust kernel).
        certificate_tolerance: relative tolerance passed to the certificate.

    Returns:
        A :class:`PoseGraphResult` with both objectives at the optimised poses.

    Raises:
        PoseGraphError: a disconnected graph, an unknown option or a singular system.
    """
    if method not in ("lm", "gn"):
        raise PoseGraphError(f"unknown method {method!r} (use 'lm' or 'gn')")
    if objective not in ("sesync", "g2o"):
        raise PoseGraphError(f"unknown objective {objective!r} (use 'sesync' or 'g2o')")
    if robust not in (None, "huber", "cauchy"):
        raise PoseGraphError(f"unknown robust kernel {robust!r} (use None, 'huber' or 'cauchy')")
    if init not in ("auto", "chordal", "graph"):
        raise PoseGraphError(f"unknown init {init!r} (use 'auto', 'chordal' or 'graph')")
    if not (robust_width > 0 and math.isfinite(robust_width)):
        raise PoseGraphError(f"robust_width must be positive and finite, got {robust_width}")
    if max_iterations < 0:
        raise PoseGraphError(f"max_iterations must be >= 0, got {max_iterations}")
    _check_connected(graph)
    initial_chi2, initial_f = g2o_chi2(graph), sesync_objective(graph)
    start = time.perf_counter()
    n = graph.num_vertices
    if n == 1 or graph.num_edges == 0:
        return PoseGraphResult(
            graph.poses.copy(), 0, time.perf_counter() - start, initial_chi2, initial_f, initial_chi2, initial_f,
            0.0, True,
        )  # fmt: skip
    problem = _Problem(graph, objective, robust, robust_width)
    use_chordal = init == "chordal" or (init == "auto" and robust is None)
    translations = None
    if (objective == "sesync" and robust is None) or use_chordal:
        translations = _Translations(graph, problem.tau)
    p = _chordal_guess(graph, translations) if use_chordal else graph.poses.copy()
    if objective != "sesync" or robust is not None:
        translations = None  # variable projection only where F is the cost: quadratic in the translations
    h_gn, h, g, cost = problem.normal_equations(p)
    factor = analyze(h, mode="simplicial", ordering_method="amd")
    diag_idx = problem.asm.diag
    lam = 1e-6 if method == "lm" else 0.0
    nu = 2.0
    iterations = 0
    converged = False
    fresh = False  # does `factor` hold a factorisation of an earlier damped Hessian?
    last_decrease = math.inf
    retry_pcg_at = 0
    while iterations < max_iterations:
        iterations += 1
        d = np.abs(h_gn.data[diag_idx])
        d = np.maximum(d, 1e-12 * max(1.0, float(np.max(d))))
        model = h  # exact Newton where it is positive definite, Gauss–Newton where it is not
        hd = h.copy()
        hd.data[diag_idx] += lam * d
        delta = None
        if fresh and last_decrease < 1e-3 * cost and iterations >= retry_pcg_at:
            # Near the optimum the Hessian changes little between steps: the previous Cholesky factor is an
            # excellent preconditioner, and a few conjugate-gradient iterations replace a new factorisation.
            delta = _pcg(hd, -g, factor, rtol=1e-6, maxiter=12)
            if delta is None:
                retry_pcg_at = iterations + 3  # the Hessian still moves too much: factor for a while
        if delta is None:
            ok = _factor_ok(factor, hd, 0.0)
            if not ok:
                model = h_gn
                hd = h_gn.copy()
                hd.data[diag_idx] += lam * d
                ok = _factor_ok(factor, hd, 0.0)
            if not ok:
                fresh = False
                if method == "gn":
                    raise PoseGraphError("Gauss–Newton system is not positive definite; use method='lm'") from None
                lam, nu = max(lam, 1e-9) * nu, 2.0 * nu
                continue
            fresh = True
            delta = -np.asarray(factor(g), dtype=np.float64)
        step = delta.reshape(n - 1, 3)
        trial = p.copy()
        trial[1:] += step
        if translations is not None:
            # Variable projection (Kaufman's form): keep the Newton step's rotations and move the translations to
            # their exact optimum for them; F is quadratic in the translations, so this only lowers the cost and
            # cuts the iterations of long chains (ais2klinik) several-fold.
            trial[1:, :2] = translations.solve(trial[:, 2])
        new_cost, trial_residuals = problem.cost(trial)
        # Model decrease of cost = Σ ρ(‖r‖²), whose gradient is 2g and (Gauss–)Newton Hessian 2H.
        predicted = -(2.0 * _dot(g, delta) + _dot(delta, model @ delta))
        if method == "gn" or (new_cost < cost and predicted > 0):
            rho = (cost - new_cost) / predicted if predicted > 0 else 0.0
            decrease = cost - new_cost
            last_decrease = decrease
            p = trial
            p[:, 2] = _wrap(p[:, 2])  # residuals are 2π-periodic in θ: trial_residuals still hold
            cost = new_cost
            small_step = float(np.max(np.abs(step))) <= 1e-10 * (1.0 + float(np.max(np.abs(p))))
            if abs(decrease) <= tolerance * max(cost, 1e-300) or small_step:
                converged = True
                break
            h_gn, h, g, cost = problem.normal_equations(p, trial_residuals)
            if method == "lm":
                lam *= max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3)
                nu = 2.0
        else:
            lam *= nu
            nu *= 2.0
            if lam > 1e16:
                converged = True  # no descent left at machine precision
                break
    p[:, 2] = _wrap(p[:, 2])
    elapsed = time.perf_counter() - start
    result = PoseGraphResult(
        poses=p,
        iterations=iterations,
        time_s=elapsed,
        chi2=g2o_chi2(graph, p),
        sesync_objective=sesync_objective(graph, p),
        initial_chi2=initial_chi2,
        initial_sesync_objective=initial_f,
        cost=problem.cost(p)[0],
        converged=converged,
    )
    if certify:
        t0 = time.perf_counter()
        cert = certify_global_optimality(graph, p, tolerance=certificate_tolerance)
        result = replace(result, certificate=cert, certificate_time_s=time.perf_counter() - t0)
    return result


# --------------------------------------------------------------------------------------------------------------------
# SE-Sync's certificate


def _sesync_matrix(graph: PoseGraph) -> sp.csr_matrix:
    """Hermitian M (2N × 2N, complex) with F = xᴴ M x, x = [p; z], p_k = x_k + i y_k, z_k = e^{iθ_k}."""
    n = graph.num_vertices
    kappa, tau = sesync_weights(graph)
    i, j = graph.edges[:, 0], graph.edges[:, 1]
    z = graph.measurements
    w = np.exp(1j * z[:, 2])
    t = z[:, 0] + 1j * z[:, 1]
    zi, zj = n + i, n + j
    # Rotation term 2κ |z_j − w z_i|².
    rows = [zi, zj, zj, zi]
    cols = [zi, zj, zi, zj]
    vals = [2 * kappa, 2 * kappa, -2 * kappa * w, -2 * kappa * np.conj(w)]
    # Translation term τ |cᵀ x|² with c = (p_j: 1, p_i: −1, z_i: −t): M_kl += τ conj(c_k) c_l.
    idx = [j, i, zi]
    coef = [np.ones(len(t), dtype=np.complex128), -np.ones(len(t), dtype=np.complex128), -t]
    for a in range(3):
        for b in range(3):
            rows.append(idx[a])
            cols.append(idx[b])
            vals.append(tau * np.conj(coef[a]) * coef[b])
    return sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(2 * n, 2 * n))


def certify_global_optimality(
    graph: PoseGraph, poses: FloatArray | None = None, tolerance: float = 1e-6
) -> OptimalityCertificate:
    """SE-Sync's minimum-eigenvalue test of global optimality of ``poses`` for the objective F.

    With ``x = [p; z]`` (translations and unit rotations as complex numbers), ``F(x) = xᴴ M x``. At a critical
    point of F on the rotations' unit circles, ``(M x)_k = λ_k z_k`` with real multipliers
    ``λ_k = Re(conj(z_k) (M x)_k)``. If ``S = M − diag(0, Λ)`` is positive semidefinite then for any feasible y,
    ``F(y) = yᴴ S y + Σ λ_k ≥ Σ λ_k = F(x)``: x is a global minimiser (the relaxation is exact). The smallest
    eigenvalue of S is found by shift-and-invert Lanczos around ``−tolerance·scale``, with a sparse Cholesky of
    ``S + tolerance·scale·I`` whose success alone proves ``λ_min > −tolerance·scale``.

    Args:
        graph: the pose graph.
        poses: (N, 3) candidate poses (the graph's own when None); should be a minimiser of F.
        tolerance: relative tolerance; the absolute one is ``tolerance × max diag(M)`` (F's units).

    Returns:
        An :class:`OptimalityCertificate`.
    """
    p = _check_poses(graph, poses)
    if not (tolerance > 0 and math.isfinite(tolerance)):
        raise PoseGraphError(f"tolerance must be positive and finite, got {tolerance}")
    n = graph.num_vertices
    _check_connected(graph)
    m = _sesync_matrix(graph)
    x = np.concatenate([p[:, 0] + 1j * p[:, 1], np.exp(1j * p[:, 2])])
    mx = m @ x
    lam = np.zeros(2 * n)
    lam[n:] = np.real(np.conj(x[n:]) * mx[n:])
    s = (m - sp.diags(lam)).tocsc()
    stationarity = float(np.linalg.norm(s @ x)) / max(float(np.linalg.norm(mx)), 1e-300)
    sr = sp.bmat([[s.real, -s.imag], [s.imag, s.real]], format="csc")  # same spectrum, each eigenvalue twice
    scale = max(1.0, float(np.max(np.abs(m.diagonal()))))
    tol_abs = tolerance * scale
    eye = sp.identity(sr.shape[0], format="csc")
    factor = analyze((sr + eye).tocsc(), mode="simplicial", ordering_method="amd")
    # The proof: S + tol·I has a Cholesky factor ⇔ λ_min(S) > −tol.
    if not _factor_ok(factor, (sr + tol_abs * eye).tocsc(), 0.0):
        return OptimalityCertificate(False, _lambda_min_negative(sr), tol_abs, stationarity)
    # The value: shift-and-invert Lanczos next to 0. A shift closer to 0 separates the zero eigenvalues (x and
    # the translation gauge are in S's null space) from the small positive ones of a long chain, so Lanczos
    # converges in a few steps.
    shift = tol_abs
    if _factor_ok(factor, (sr + 1e-3 * tol_abs * eye).tocsc(), 0.0):
        shift = 1e-3 * tol_abs
    else:
        _factor_ok(factor, (sr + tol_abs * eye).tocsc(), 0.0)
    op = LinearOperator(sr.shape, matvec=lambda v: factor(v), dtype=np.float64)
    try:
        vals = eigsh(sr, k=1, sigma=-shift, which="LM", OPinv=op, tol=1e-4, maxiter=1000, return_eigenvectors=False)
        lam_min = float(vals[0])
    except ArpackNoConvergence:
        lam_min = -shift  # the factor still proves λ_min > −shift
    return OptimalityCertificate(True, lam_min, tol_abs, stationarity)


def _dot(a: FloatArray, b: FloatArray) -> float:
    """Inner product without BLAS: on a busy machine OpenBLAS's worker threads, woken by a level-1 call and left
    spinning after it, slow the sparse solves around it by an order of magnitude."""
    return float(np.sum(a * b))


def _pcg(a: sp.csc_matrix, b: FloatArray, factor: Factor, rtol: float, maxiter: int) -> FloatArray | None:
    """Solve ``a x = b`` (a SPD) by conjugate gradients preconditioned with ``factor`` (a factorisation of a
    nearby matrix); None when it does not reach ``‖b − a x‖ ≤ rtol ‖b‖`` within ``maxiter`` iterations."""
    x = np.asarray(factor(b), dtype=np.float64)
    r = b - a @ x
    bound2 = rtol * rtol * _dot(b, b)
    if _dot(r, r) <= bound2:
        return x
    z = np.asarray(factor(r), dtype=np.float64)
    direction = z.copy()
    rz = _dot(r, z)
    for _ in range(maxiter):
        ad = a @ direction
        curvature = _dot(direction, ad)
        if curvature <= 0.0:
            return None  # not positive definite along this direction: let the caller factor
        alpha = rz / curvature
        x += alpha * direction
        r -= alpha * ad
        if _dot(r, r) <= bound2:
            return x
        z = np.asarray(factor(r), dtype=np.float64)
        rz_new = _dot(r, z)
        direction = z + (rz_new / rz) * direction
        rz = rz_new
    return None


def _factor_ok(factor: Factor, a: sp.csc_matrix, shift: float) -> bool:
    """Factor ``a + shift·I`` into ``factor``; False when it is not positive definite.

    CHOLMOD's simplicial factorisation is LDLᵀ, which goes through an indefinite matrix without complaint as
    long as no pivot is exactly zero: positive definiteness is the sign of every entry of D.
    """
    try:
        factor.cholesky_inplace(a, beta=shift)
    except CholmodNotPositiveDefiniteError:
        return False
    d = factor.D()
    return bool(np.all(d > 0.0) and np.all(np.isfinite(d)))


def _lambda_min_negative(sr: sp.csc_matrix) -> float:
    """Most negative eigenvalue of a symmetric matrix that is not PSD (SE-Sync's way: λ_max(λ_max·I − S))."""
    top = float(abs(sr).sum(axis=1).max())  # Gershgorin bound on the spectral radius
    try:
        flipped = top * sp.identity(sr.shape[0], format="csc") - sr
        return top - float(eigsh(flipped, k=1, which="LA", tol=1e-8, maxiter=20000, return_eigenvectors=False)[0])
    except ArpackNoConvergence as exc:
        if len(exc.eigenvalues):
            return top - float(np.max(exc.eigenvalues))
        return float("nan")
