"""``mjnav scanmatch``: consecutive-scan matching on a CARMEN log against its corrected poses.

For each pair of consecutive FLASER scans (i, i+1) the reference answer is the relative pose of the logged
(corrected) laser poses, Pᵢ⁻¹·Pᵢ₊₁; the matcher starts from that answer perturbed by a seeded error of the
given size (translation of exactly ``--init-error`` metres in a uniformly random direction, rotation of
exactly the given degrees with a random sign) and its result is compared with the reference.

Definitions (also used by ``benchmarks/scanmatch.py``):

* error: translational ‖(x, y) − (x, y)_ref‖ in metres and rotational |wrap(θ − θ_ref)| in degrees; a match
  that raises (too few correspondences) has infinite error.
* success: translational error < 5 cm **and** rotational error < 1° (``success_rate``); the looser
  < 10 cm and < 2° is reported as ``success_rate_10cm_2deg``.
* medians are over all pairs (failures included); time is the wall time of one ``scan_match`` call.

Exit codes: 0 done; 2 bad arguments or an unreadable log.
"""

from __future__ import annotations

import argparse
import contextlib
import math
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from mjnav import jsonsafe

if TYPE_CHECKING:
    import numpy as np
    from numpy.typing import NDArray

    from mjnav.estimation.carmen import CarmenLog

METHODS = ("icp", "plicp", "csm")
SUCCESS_M = 0.05
SUCCESS_DEG = 1.0
LOOSE_M = 0.10
LOOSE_DEG = 2.0


def parse_init_error(text: str) -> tuple[float, float]:
    """``METRES,DEGREES`` → (m, deg), both finite and >= 0."""
    parts = text.split(",")
    try:
        if len(parts) != 2:
            raise ValueError
        m, d = float(parts[0]), float(parts[1])
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected METRES,DEGREES (two numbers), got {text!r}") from None
    if not (math.isfinite(m) and math.isfinite(d) and m >= 0 and d >= 0):
        raise argparse.ArgumentTypeError(f"METRES,DEGREES must be finite and >= 0, got {text!r}")
    return m, d


def _positive_int(text: str) -> int:
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}") from None
    if v < 1:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}")
    return v


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add the ``scanmatch`` sub-command."""
    p = subparsers.add_parser(
        "scanmatch",
        help="match consecutive laser scans of a CARMEN log and report success rate, error and time",
        description=(
            "Scan-to-scan matching benchmark on a CARMEN log (e.g. the Radish/Freiburg 'corrected' logs). "
            "Each consecutive pair of FLASER scans is matched with mjnav.estimation.scan_match, starting "
            "from the logged relative pose perturbed by a seeded error of exactly --init-error (metres in a "
            "random direction, degrees with a random sign). Reported: success rate (error < 5 cm and < 1°; "
            "also < 10 cm and < 2°), median translational/rotational error over all pairs and median time "
            "per match. In corrected logs the logged poses are a SLAM solution, so the reference is itself "
            "approximate and part of every reported error is the reference's own."
        ),
        epilog=(
            "Examples: mjnav scanmatch intel-corrected.log.gz --method plicp --limit 200; "
            "mjnav scanmatch intel-corrected.log.gz --method csm --init-error 0.1,5 --seed 3 --json"
        ),
    )
    p.add_argument("log", type=Path, metavar="LOG", help="CARMEN log (.log or .log.gz) with FLASER lines")
    p.add_argument("--method", choices=METHODS, default="plicp", help="matcher (default plicp)")
    p.add_argument("--limit", type=_positive_int, default=None, metavar="N", help="match only the first N pairs")
    p.add_argument(
        "--init-error",
        type=parse_init_error,
        default=(0.1, 5.0),
        metavar="M,DEG",
        help="initial-guess error: metres,degrees (default 0.1,5)",
    )
    p.add_argument("--seed", type=int, default=0, help="seed of the initial perturbations (default 0)")
    p.add_argument(
        "--max-range",
        type=float,
        default=80.0,
        metavar="M",
        help="ranges at or beyond this are no-return and dropped (default 80 m; the Intel log uses 81.83)",
    )
    p.add_argument("--json", action="store_true", help="print one JSON object on the last line")
    p.set_defaults(func=run)


@dataclass(frozen=True)
class PairStats:
    """Per-pair outcome arrays of :func:`evaluate_consecutive` (length = number of pairs)."""

    trans_err_m: NDArray[np.float64]
    rot_err_deg: NDArray[np.float64]
    time_s: NDArray[np.float64]

    def summary(self) -> dict[str, Any]:
        """Success rates, medians and counts as a JSON-ready dict."""
        import numpy as np

        t, r = self.trans_err_m, self.rot_err_deg
        return {
            "pairs": int(t.size),
            "success_rate": float(np.mean((t < SUCCESS_M) & (r < SUCCESS_DEG))),
            "success_rate_10cm_2deg": float(np.mean((t < LOOSE_M) & (r < LOOSE_DEG))),
            "median_trans_error_m": float(np.median(t)),
            "median_rot_error_deg": float(np.median(r)),
            "median_time_s": float(np.median(self.time_s)),
            "failures_raised": int(np.sum(~np.isfinite(t))),
        }


def perturbations(n: int, init_error: tuple[float, float], seed: int) -> NDArray[np.float64]:
    """(n, 3) seeded initial errors: |(dx, dy)| = init_error[0] m in a uniform direction, dθ = ±init_error[1]°."""
    import numpy as np

    rng = np.random.default_rng(seed)
    phi = rng.uniform(-math.pi, math.pi, n)
    sign = rng.choice([-1.0, 1.0], n)
    m, deg = init_error
    return np.column_stack((m * np.cos(phi), m * np.sin(phi), sign * math.radians(deg)))


def relative_poses(poses: NDArray[np.float64]) -> NDArray[np.float64]:
    """(S − 1, 3) Pᵢ⁻¹·Pᵢ₊₁ of (S, 3) poses (x, y, θ)."""
    import numpy as np

    a, b = poses[:-1], poses[1:]
    c, s = np.cos(a[:, 2]), np.sin(a[:, 2])
    dx, dy = b[:, 0] - a[:, 0], b[:, 1] - a[:, 1]
    dth = np.mod(b[:, 2] - a[:, 2] + np.pi, 2 * np.pi) - np.pi
    return np.column_stack((c * dx + s * dy, -s * dx + c * dy, dth))


def evaluate_consecutive(
    log: CarmenLog,
    method: str,
    *,
    limit: int | None = None,
    init_error: tuple[float, float] = (0.1, 5.0),
    seed: int = 0,
    max_range_m: float = 80.0,
) -> PairStats:
    """Match every consecutive scan pair of ``log`` (up to ``limit`` pairs) as the module doc describes."""
    import numpy as np

    from mjnav.estimation import ScanMatchError, scan_match

    truth = relative_poses(log.poses)
    n = truth.shape[0] if limit is None else min(limit, truth.shape[0])
    delta = perturbations(n, init_error, seed)
    pts = [log.points(i, max_range_m=max_range_m) for i in range(n + 1)]
    # Warm-up: load the compiled kernels outside the timed region.
    with contextlib.suppress(ScanMatchError):
        scan_match(pts[0], pts[0], (0.0, 0.0, 0.0), method=method)  # type: ignore[arg-type]
    te = np.full(n, np.inf)
    re = np.full(n, np.inf)
    ts = np.zeros(n)
    for i in range(n):
        init = truth[i] + delta[i]
        t0 = time.perf_counter()
        try:
            res = scan_match(pts[i], pts[i + 1], init, method=method)  # type: ignore[arg-type]
        except ScanMatchError:
            ts[i] = time.perf_counter() - t0
            continue
        ts[i] = time.perf_counter() - t0
        te[i] = math.hypot(res.pose[0] - truth[i, 0], res.pose[1] - truth[i, 1])
        re[i] = abs(math.degrees((res.pose[2] - truth[i, 2] + math.pi) % (2 * math.pi) - math.pi))
    return PairStats(te, re, ts)


def _fail(message: str) -> int:
    print(f"mjnav scanmatch: error: {message}", file=sys.stderr)
    return 2


def run(args: argparse.Namespace) -> int:
    """Read the log, match consecutive pairs, print the summary; returns the exit code."""
    from mjnav.estimation.carmen import CarmenFormatError, read_carmen

    if not (math.isfinite(args.max_range) and args.max_range > 0):
        return _fail(f"--max-range must be finite and > 0, got {args.max_range}")
    try:
        log = read_carmen(args.log)
    except (OSError, CarmenFormatError) as exc:
        return _fail(f"cannot read CARMEN log {args.log}: {exc}")
    if len(log) < 2:
        return _fail(f"{args.log}: needs at least 2 FLASER scans, found {len(log)}")
    stats = evaluate_consecutive(
        log, args.method, limit=args.limit, init_error=args.init_error, seed=args.seed, max_range_m=args.max_range
    )
    out: dict[str, Any] = {
        "log": str(args.log),
        "method": args.method,
        "init_error_m": args.init_error[0],
        "init_error_deg": args.init_error[1],
        "seed": args.seed,
        "beams": int(log.ranges.shape[1]),
        **stats.summary(),
    }
    print(f"log:        {args.log} ({len(log)} scans, {out['beams']} beams)")
    print(
        f"method:     {args.method}, {out['pairs']} consecutive pairs, initial error "
        f"{args.init_error[0]:g} m / {args.init_error[1]:g}° (seed {args.seed})"
    )
    print(
        f"success:    {out['success_rate']:.1%} (< {SUCCESS_M * 100:g} cm and < {SUCCESS_DEG:g}°), "
        f"{out['success_rate_10cm_2deg']:.1%} (< {LOOSE_M * 100:g} cm and < {LOOSE_DEG:g}°)"
    )
    print(
        f"median:     {out['median_trans_error_m'] * 100:.2f} cm, {out['median_rot_error_deg']:.3f}°, "
        f"{out['median_time_s'] * 1e3:.3f} ms per match ({out['failures_raised']} raised)"
    )
    if args.json:
        print(jsonsafe.dumps(out))
    return 0
