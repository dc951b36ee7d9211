"""State estimation (pure): Kalman filters, EKF-SLAM, FastSLAM, data association.

Arrays are float64 numpy arrays in SI units (metres, radians, seconds); failures raise
:class:`~mjnav.estimation.errors.EstimationError` subclasses.
"""

from mjnav.estimation.association import Association, chi2_gate, jcbb, nearest_neighbor, pairwise_mahalanobis
from mjnav.estimation.ekf_slam import EKFSLAM
from mjnav.estimation.errors import EstimationError, InvalidMeasurement, InvalidModel, NotPositiveDefinite
from mjnav.estimation.fastslam import FastSLAM
from mjnav.estimation.kalman import ExtendedKalmanFilter, KalmanFilter

__all__ = [
    "EKFSLAM",
    "Association",
    "EstimationError",
    "ExtendedKalmanFilter",
    "FastSLAM",
    "InvalidMeasurement",
    "InvalidModel",
    "KalmanFilter",
    "NotPositiveDefinite",
    "chi2_gate",
    "jcbb",
    "nearest_neighbor",
    "pairwise_mahalanobis",
]
