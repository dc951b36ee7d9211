"""State estimation (pure): Kalman filters, EKF-SLAM, FastSLAM, data association, scan matching, line extraction,
pose graphs.

Filters (:mod:`~mjnav.estimation.kalman`, :mod:`~mjnav.estimation.ekf_slam`, :mod:`~mjnav.estimation.fastslam`,
:mod:`~mjnav.estimation.association`); scan matching (:mod:`~mjnav.estimation.scan_matching`): :func:`scan_match`
(ICP, PL-ICP, CSM) and :class:`CorrelativeGridMatcher` (branch-and-bound matching against an occupancy grid); line
extraction (:mod:`~mjnav.estimation.split_merge`); SE(2) pose-graph optimisation with SE-Sync's certificate
(:mod:`~mjnav.estimation.posegraph`). File readers live at the edge (:mod:`~mjnav.estimation.carmen`,
:mod:`~mjnav.estimation.g2o`).
Arrays are float64 numpy arrays in SI units (metres, radians, seconds); failures raise
:class:`~mjnav.estimation.errors.EstimationError` subclasses.
"""

from mjnav.estimation.association import Association, chi2_gate, jcbb, nearest_neighbor, pairwise_mahalanobis
from mjnav.estimation.carmen import CarmenFormatError, CarmenLog, parse_carmen, read_carmen
from mjnav.estimation.ekf_slam import EKFSLAM
from mjnav.estimation.errors import EstimationError, InvalidMeasurement, InvalidModel, NotPositiveDefinite
from mjnav.estimation.fastslam import FastSLAM
from mjnav.estimation.g2o import G2OFormatError, read_g2o, write_g2o
from mjnav.estimation.kalman import ExtendedKalmanFilter, KalmanFilter
from mjnav.estimation.posegraph import (
    OptimalityCertificate,
    PoseGraph,
    PoseGraphError,
    PoseGraphResult,
    certify_global_optimality,
    g2o_chi2,
    odometry_guess,
    optimize_pose_graph,
    sesync_objective,
    sesync_weights,
)
from mjnav.estimation.scan_matching import (
    CorrelativeGridMatcher,
    InsufficientPointsError,
    NoMatchError,
    ScanMatchError,
    ScanMatchResult,
    scan_match,
    scan_to_points,
)
from mjnav.estimation.split_merge import Corner, LineSegment, SplitMergeError, fit_line, line_corners, split_and_merge

__all__ = [
    "EKFSLAM",
    "Association",
    "CarmenFormatError",
    "CarmenLog",
    "Corner",
    "CorrelativeGridMatcher",
    "EstimationError",
    "ExtendedKalmanFilter",
    "FastSLAM",
    "G2OFormatError",
    "InsufficientPointsError",
    "InvalidMeasurement",
    "InvalidModel",
    "KalmanFilter",
    "LineSegment",
    "NoMatchError",
    "NotPositiveDefinite",
    "OptimalityCertificate",
    "PoseGraph",
    "PoseGraphError",
    "PoseGraphResult",
    "ScanMatchError",
    "ScanMatchResult",
    "SplitMergeError",
    "certify_global_optimality",
    "chi2_gate",
    "fit_line",
    "g2o_chi2",
    "jcbb",
    "line_corners",
    "nearest_neighbor",
    "odometry_guess",
    "optimize_pose_graph",
    "pairwise_mahalanobis",
    "parse_carmen",
    "read_carmen",
    "read_g2o",
    "scan_match",
    "scan_to_points",
    "sesync_objective",
    "sesync_weights",
    "split_and_merge",
    "write_g2o",
]
