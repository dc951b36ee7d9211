"""``mjnav posegraph``: optimise an SE(2) g2o pose graph with :func:`mjnav.estimation.optimize_pose_graph`.

Exit codes: 0 optimised; 1 the optimiser failed (e.g. a singular system); 2 bad arguments or an unreadable file.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from mjnav import jsonsafe

DESCRIPTION = """\
Optimise the poses of a 2D pose graph read from a g2o file (VERTEX_SE2 / EDGE_SE2 lines; where a file lists no
vertices, as manhattan and CSAIL, the initial guess composes the odometry edges k-1 -> k) and report both
objectives at the result:

  chi2  g2o's chi-square, sum over edges of e' Omega e with e = t2v(Z^-1 X_i^-1 X_j): what g2o and gtsam minimise.
  F     SE-Sync's objective (Rosen et al., IJRR 2019): sum of kappa*||R_j - R_i Rot(dth)||_F^2
        + tau*||t_j - t_i - R_i t_ij||^2, with kappa = I33 and tau = 2/trace(inv(translational 2x2 information)),
        R the 2x2 rotation matrices. It replaces the angle error by the chord between rotation matrices, which
        makes the problem a quadratic over (translations, unit complex rotations) whose semidefinite relaxation
        is usually exact: that is what lets SE-Sync prove a solution is the global optimum.

By default the optimiser minimises F (--objective g2o minimises chi2 instead) by sparse Levenberg-Marquardt from
a chordal initialisation: the rotations are solved first as unconstrained complex numbers (a linear least-squares
problem) and projected onto the unit circle, then the translations by one more linear solve, then LM refines all
poses (CHOLMOD sparse Cholesky under an AMD fill-reducing ordering). Vertex 0 stays where the file has it.

The certificate (SE-Sync's minimum-eigenvalue test): at a critical point of F the first-order conditions give one
Lagrange multiplier per rotation; S = M - diag(0, Lambda) is the objective's matrix minus those multipliers. If
S is positive semidefinite (lambda_min(S) >= -tol), no other set of poses has a lower F: the result is the GLOBAL
optimum, not merely a local one. A clearly negative lambda_min means a local minimum (or an unconverged run) that
the certificate cannot vouch for. The test applies to F without a robust kernel.
"""


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add the ``posegraph`` sub-command."""
    p = subparsers.add_parser(
        "posegraph",
        help="optimise a 2D g2o pose graph (reports g2o chi2, SE-Sync's F and a global-optimality certificate)",
        description=DESCRIPTION,
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog=(
            "Examples: mjnav posegraph intel.g2o --out intel_opt.g2o; "
            "mjnav posegraph manhattan.g2o --json; mjnav posegraph noisy.g2o --robust cauchy --objective g2o"
        ),
    )
    p.add_argument("file", type=Path, metavar="FILE.g2o", help="input pose graph (g2o SE(2) text format)")
    p.add_argument("--out", type=Path, default=None, metavar="OPT.g2o", help="write the optimised graph here")
    p.add_argument(
        "--robust",
        choices=("huber", "cauchy"),
        default=None,
        help="robust kernel on each edge's squared error (down-weights outlier loop closures; starts from the "
        "file's poses instead of the chordal relaxation; no certificate)",
    )
    p.add_argument(
        "--robust-width",
        type=float,
        default=None,
        metavar="DELTA",
        help="kernel width on the error sqrt(e' Omega e) (default 2.80 = sqrt of chi2(3 dof) at 95%%)",
    )
    p.add_argument(
        "--objective",
        choices=("sesync", "g2o"),
        default="sesync",
        help="what to minimise: SE-Sync's F (default; certifiable) or g2o's chi2",
    )
    p.add_argument("--method", choices=("lm", "gn"), default="lm", help="Levenberg-Marquardt (default) or Gauss-Newton")
    p.add_argument(
        "--init",
        choices=("auto", "chordal", "graph"),
        default="auto",
        help="initial guess: chordal relaxation, the file's poses, or auto (chordal unless --robust)",
    )
    p.add_argument("--max-iterations", type=int, default=100, help="iteration cap (default 100)")
    p.add_argument("--no-certify", action="store_true", help="skip the global-optimality certificate")
    p.add_argument("--json", action="store_true", help="print one JSON object on the last line")
    p.set_defaults(func=run)


def _fail(code: int, message: str) -> int:
    print(f"mjnav posegraph: error: {message}", file=sys.stderr)
    return code


def run(args: argparse.Namespace) -> int:
    """Read, optimise, report (and write); returns the exit code."""
    from mjnav.estimation import PoseGraphError, optimize_pose_graph, read_g2o, write_g2o
    from mjnav.estimation.posegraph import DEFAULT_ROBUST_WIDTH

    if args.max_iterations < 0:
        return _fail(2, f"--max-iterations must be >= 0, got {args.max_iterations}")
    width = DEFAULT_ROBUST_WIDTH if args.robust_width is None else args.robust_width
    if not width > 0:
        return _fail(2, f"--robust-width must be positive, got {width}")
    try:
        graph = read_g2o(args.file)
    except PoseGraphError as exc:
        return _fail(2, str(exc))
    certify = not args.no_certify and args.robust is None and args.objective == "sesync"
    try:
        res = optimize_pose_graph(
            graph,
            method=args.method,
            robust=args.robust,
            objective=args.objective,
            init=args.init,
            robust_width=width,
            max_iterations=args.max_iterations,
            certify=certify,
        )
    except PoseGraphError as exc:
        return _fail(1, str(exc))
    if args.out is not None:
        try:
            write_g2o(args.out, graph, res.poses)
        except PoseGraphError as exc:
            return _fail(2, str(exc))
    cert = res.certificate
    result: dict[str, Any] = {
        "file": str(args.file),
        "vertices": graph.num_vertices,
        "edges": graph.num_edges,
        "objective": args.objective,
        "robust": args.robust,
        "chi2": res.chi2,
        "sesync_objective": res.sesync_objective,
        "initial_chi2": res.initial_chi2,
        "initial_sesync_objective": res.initial_sesync_objective,
        "iterations": res.iterations,
        "converged": res.converged,
        "time_s": res.time_s,
        "certified": None if cert is None else cert.certified,
        "lambda_min": None if cert is None else cert.lambda_min,
        "certificate_tolerance": None if cert is None else cert.tolerance,
        "certificate_time_s": res.certificate_time_s if cert is not None else None,
        "out": None if args.out is None else str(args.out),
    }
    if args.json:
        print(jsonsafe.dumps(result))
        return 0
    print(f"graph:       {args.file} ({graph.num_vertices} vertices, {graph.num_edges} edges)")
    print(f"minimised:   {args.objective}{'' if args.robust is None else f' with a {args.robust} kernel'}")
    print(f"g2o chi2:    {res.initial_chi2:.6g} -> {res.chi2:.6g}")
    print(f"SE-Sync F:   {res.initial_sesync_objective:.6g} -> {res.sesync_objective:.6g}")
    print(f"iterations:  {res.iterations} ({'converged' if res.converged else 'NOT converged'}) in {res.time_s:.3f} s")
    if cert is not None:
        verdict = "globally optimal (certified)" if cert.certified else "NOT certified (local minimum or unconverged)"
        print(f"certificate: {verdict}: lambda_min(S) = {cert.lambda_min:.3g} (tolerance -{cert.tolerance:.3g})")
    if args.out is not None:
        print(f"wrote:       {args.out}")
    return 0
