"""State estimation: pose graphs (SE(2), g2o files at the edge)."""

from mjnav.estimation.g2o import G2OFormatError, read_g2o, write_g2o
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

__all__ = [
    "G2OFormatError",
    "OptimalityCertificate",
    "PoseGraph",
    "PoseGraphError",
    "PoseGraphResult",
    "certify_global_optimality",
    "g2o_chi2",
    "odometry_guess",
    "optimize_pose_graph",
    "read_g2o",
    "sesync_objective",
    "sesync_weights",
    "write_g2o",
]
