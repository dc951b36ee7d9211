"""Path smoothing: gradient descent, moving averages, an OSQP quadratic programme, CasADi splines,
path utilities and a speed profile.

Paths are (N, 2) float arrays of (x, y) positions in metres; every smoother returns the same shape.
"""

from mjnav.smoothing._bounds import half_widths
from mjnav.smoothing.errors import InfeasibleProblem, PathError, SolverError
from mjnav.smoothing.gradient_descent import gradient_descent
from mjnav.smoothing.moving_average import moving_average, triangular_weights, weighted_moving_average
from mjnav.smoothing.path import (
    check_path,
    cumulative_length,
    curvature,
    headings,
    path_length,
    remove_duplicates,
    resample,
    roughness,
    segment_lengths,
)
from mjnav.smoothing.profile import SpeedLimits, profile_times, velocity_profile
from mjnav.smoothing.qp import QPSmoothResult, qp_smooth, qp_smooth_detailed, smoothing_cost
from mjnav.smoothing.spline import PiecewiseCubic, fit_spline

__all__ = [
    "InfeasibleProblem",
    "PathError",
    "PiecewiseCubic",
    "QPSmoothResult",
    "SolverError",
    "SpeedLimits",
    "check_path",
    "cumulative_length",
    "curvature",
    "fit_spline",
    "gradient_descent",
    "half_widths",
    "headings",
    "moving_average",
    "path_length",
    "profile_times",
    "qp_smooth",
    "qp_smooth_detailed",
    "remove_duplicates",
    "resample",
    "roughness",
    "segment_lengths",
    "smoothing_cost",
    "triangular_weights",
    "velocity_profile",
    "weighted_moving_average",
]
