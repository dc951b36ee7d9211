"""Motion models and differential-drive kinematics (pure NumPy).

Poses are (x, y, θ) in metres and radians, as (3,) or (N, 3) float arrays or :class:`mjnav.geometry.Pose2D`.
"""

from mjnav.motion.diffdrive import DiffDriveKinematics
from mjnav.motion.gyrodometry import GyroOdometry
from mjnav.motion.odometry import (
    apply_odometry_delta,
    odometry_delta,
    odometry_likelihood,
    sample_odometry_motion,
)
from mjnav.motion.simple import sample_simple_motion, simple_motion
from mjnav.motion.velocity import sample_velocity_motion, velocity_motion

__all__ = [
    "DiffDriveKinematics",
    "GyroOdometry",
    "apply_odometry_delta",
    "odometry_delta",
    "odometry_likelihood",
    "sample_odometry_motion",
    "sample_simple_motion",
    "sample_velocity_motion",
    "simple_motion",
    "velocity_motion",
]
