"""Builders and readers for the standard messages the services exchange (stamps, headers, poses, twists)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from mjnav.geometry import Pose2D, quaternion_to_yaw, yaw_to_quaternion
from mjnav.mapping.frame import GridFrame
from mjnav.msgs.codec import typestore

_NS_PER_S = 1_000_000_000

# Message classes resolved once: these builders run on hot paths (the sim publishes thousands per second).
_types = typestore().types
_Clock = _types["rosgraph_msgs/msg/Clock"]
_DiagnosticStatus = _types["diagnostic_msgs/msg/DiagnosticStatus"]
_KeyValue = _types["diagnostic_msgs/msg/KeyValue"]
_Header = _types["std_msgs/msg/Header"]
_Imu = _types["sensor_msgs/msg/Imu"]
_JointState = _types["sensor_msgs/msg/JointState"]
_LaserScan = _types["sensor_msgs/msg/LaserScan"]
_MapMetaData = _types["nav_msgs/msg/MapMetaData"]
_OccupancyGrid = _types["nav_msgs/msg/OccupancyGrid"]
_Path = _types["nav_msgs/msg/Path"]
_Odometry = _types["nav_msgs/msg/Odometry"]
_Point = _types["geometry_msgs/msg/Point"]
_Pose = _types["geometry_msgs/msg/Pose"]
_PoseStamped = _types["geometry_msgs/msg/PoseStamped"]
_PoseWithCovariance = _types["geometry_msgs/msg/PoseWithCovariance"]
_PoseWithCovarianceStamped = _types["geometry_msgs/msg/PoseWithCovarianceStamped"]
_Quaternion = _types["geometry_msgs/msg/Quaternion"]
_TFMessage = _types["tf2_msgs/msg/TFMessage"]
_Time = _types["builtin_interfaces/msg/Time"]
_Transform = _types["geometry_msgs/msg/Transform"]
_TransformStamped = _types["geometry_msgs/msg/TransformStamped"]
_Twist = _types["geometry_msgs/msg/Twist"]
_TwistWithCovariance = _types["geometry_msgs/msg/TwistWithCovariance"]
_Vector3 = _types["geometry_msgs/msg/Vector3"]
_ZERO36 = np.zeros(36)
_ZERO36.setflags(write=False)
_ZERO9 = np.zeros(9)
_ZERO9.setflags(write=False)
_NO_FLOATS32 = np.zeros(0, dtype=np.float32)
_NO_FLOATS32.setflags(write=False)
_NO_FLOATS64 = np.zeros(0)
_NO_FLOATS64.setflags(write=False)


def _diagonal36(index: tuple[int, ...], values: tuple[float, ...]) -> Any:
    if not any(values):
        return _ZERO36
    cov = np.zeros(36)
    cov[list(index)] = values
    return cov


def _diagonal9(variance: float) -> Any:
    if variance == 0.0:
        return _ZERO9
    return np.diag([variance] * 3).reshape(9)


#: Largest stamp a builtin_interfaces/Time holds (``sec`` is an int32), seconds.
MAX_STAMP_S = float(2**31 - 1)


class StampOutOfRange(ValueError):
    """A time that a ROS 2 stamp cannot hold: NaN, negative, or beyond ``sec``'s int32 range."""


def time_msg(t_s: float) -> Any:
    """builtin_interfaces/Time for ``t_s`` seconds (0 <= t_s < 2³¹, rounded to the nanosecond).

    Raises:
        StampOutOfRange: ``t_s`` is NaN, negative or too large for the message's int32 seconds.
    """
    if not (math.isfinite(t_s) and 0.0 <= t_s < MAX_STAMP_S):
        raise StampOutOfRange(f"a stamp needs a time in [0, 2^31 - 1) s, got {t_s}")
    ns = round(t_s * _NS_PER_S)
    return _Time(sec=ns // _NS_PER_S, nanosec=ns % _NS_PER_S)


def seconds(stamp: Any) -> float:
    """Seconds of a builtin_interfaces/Time."""
    return float(stamp.sec) + float(stamp.nanosec) / 1e9


def header(t_s: float, frame_id: str) -> Any:
    """std_msgs/Header stamped ``t_s`` (sim seconds) in ``frame_id``."""
    return _Header(stamp=time_msg(t_s), frame_id=frame_id)


def clock(t_s: float) -> Any:
    """rosgraph_msgs/Clock at ``t_s`` seconds."""
    return _Clock(clock=time_msg(t_s))


def pose_msg(pose: Pose2D, z_m: float = 0.0) -> Any:
    """geometry_msgs/Pose of a planar pose (yaw about +z)."""
    qx, qy, qz, qw = yaw_to_quaternion(pose.theta)
    return _Pose(
        position=_Point(x=pose.x, y=pose.y, z=z_m),
        orientation=_Quaternion(x=qx, y=qy, z=qz, w=qw),
    )


def pose_stamped(t_s: float, frame_id: str, pose: Pose2D) -> Any:
    """geometry_msgs/PoseStamped of a planar pose."""
    return _PoseStamped(header=header(t_s, frame_id), pose=pose_msg(pose))


def position_goal(t_s: float, frame_id: str, x_m: float, y_m: float) -> Any:
    """geometry_msgs/PoseStamped at (x, y) without orientation (all-zero quaternion): a goal reached with any
    final heading (see :func:`has_orientation`)."""
    return _PoseStamped(
        header=header(t_s, frame_id),
        pose=_Pose(position=_Point(x=x_m, y=y_m, z=0.0), orientation=_Quaternion(x=0.0, y=0.0, z=0.0, w=0.0)),
    )


def pose2d(pose: Any) -> Pose2D:
    """Planar pose (x, y, yaw) of a geometry_msgs/Pose; z, roll and pitch are dropped."""
    q = pose.orientation
    return Pose2D(pose.position.x, pose.position.y, quaternion_to_yaw(q.x, q.y, q.z, q.w))


#: Indices of x, y and yaw in a row-major 6×6 ROS pose covariance (x, y, z, roll, pitch, yaw).
_XY_YAW = np.array([0, 1, 5])


def pose_with_covariance_stamped(t_s: float, frame_id: str, pose: Pose2D, covariance: Any) -> Any:
    """geometry_msgs/PoseWithCovarianceStamped of a planar pose; ``covariance``: (3, 3) over (x, y, yaw) in m² and
    rad², placed in the 6×6 matrix (the other entries 0)."""
    cov = np.zeros((6, 6))
    cov[np.ix_(_XY_YAW, _XY_YAW)] = np.asarray(covariance, dtype=np.float64).reshape(3, 3)
    return _PoseWithCovarianceStamped(
        header=header(t_s, frame_id), pose=_PoseWithCovariance(pose=pose_msg(pose), covariance=cov.reshape(36))
    )


def planar_covariance(msg: Any) -> Any:
    """(3, 3) covariance over (x, y, yaw) of a geometry_msgs/PoseWithCovariance(Stamped)."""
    inner = msg.pose if hasattr(msg.pose, "covariance") else msg
    return np.asarray(inner.covariance, dtype=np.float64).reshape(6, 6)[np.ix_(_XY_YAW, _XY_YAW)]


#: Topic of each pose source a service can navigate on: SLAM's estimate (map frame), the sim's ground truth (map
#: frame; evaluation and comparisons only), wheel odometry (odom frame, drifts).
POSE_TOPICS = {"slam": "pose", "ground_truth": "ground_truth", "odom": "odom"}


def pose_of(msg: Any) -> Pose2D:
    """Planar pose of a PoseStamped, PoseWithCovarianceStamped or Odometry message."""
    pose = msg.pose
    return pose2d(pose.pose if hasattr(pose, "pose") else pose)


def has_orientation(pose: Any) -> bool:
    """False for a geometry_msgs/Pose whose quaternion is all zeros: the orientation was left out (a goal with any
    final heading)."""
    q = pose.orientation
    return not (q.x == q.y == q.z == q.w == 0.0)


def twist(v_mps: float, omega_radps: float) -> Any:
    """geometry_msgs/Twist with forward speed ``v_mps`` and yaw rate ``omega_radps``."""
    vec = _Vector3
    return _Twist(linear=vec(x=v_mps, y=0.0, z=0.0), angular=vec(x=0.0, y=0.0, z=omega_radps))


def odometry(
    t_s: float,
    pose: Pose2D,
    v_mps: float,
    omega_radps: float,
    *,
    frame_id: str = "odom",
    child_frame_id: str = "base_link",
    pose_variance: tuple[float, float, float] = (0.0, 0.0, 0.0),
    twist_variance: tuple[float, float] = (0.0, 0.0),
) -> Any:
    """nav_msgs/Odometry: planar pose in ``frame_id`` and body twist (v, ω) in ``child_frame_id``.

    Args:
        pose_variance: variances of x (m²), y (m²) and yaw (rad²) placed on the 6×6 covariance diagonal.
        twist_variance: variances of v (m²/s²) and ω (rad²/s²).
    """
    pose_cov = _diagonal36((0, 7, 35), pose_variance)
    twist_cov = _diagonal36((0, 35), twist_variance)
    return _Odometry(
        header=header(t_s, frame_id),
        child_frame_id=child_frame_id,
        pose=_PoseWithCovariance(pose=pose_msg(pose), covariance=pose_cov),
        twist=_TwistWithCovariance(twist=twist(v_mps, omega_radps), covariance=twist_cov),
    )


def transform_stamped(t_s: float, parent_frame: str, child_frame: str, pose: Pose2D) -> Any:
    """geometry_msgs/TransformStamped placing ``child_frame`` at ``pose`` in ``parent_frame``."""
    qx, qy, qz, qw = yaw_to_quaternion(pose.theta)
    return _TransformStamped(
        header=header(t_s, parent_frame),
        child_frame_id=child_frame,
        transform=_Transform(
            translation=_Vector3(x=pose.x, y=pose.y, z=0.0),
            rotation=_Quaternion(x=qx, y=qy, z=qz, w=qw),
        ),
    )


def transform2d(transform: Any) -> Pose2D:
    """Planar pose (x, y, yaw) of a geometry_msgs/Transform; z, roll and pitch are dropped."""
    q = transform.rotation
    return Pose2D(transform.translation.x, transform.translation.y, quaternion_to_yaw(q.x, q.y, q.z, q.w))


def transform_stamped_3d(
    t_s: float, parent_frame: str, child_frame: str, position_m: Any, orientation_xyzw: Any
) -> Any:
    """geometry_msgs/TransformStamped placing ``child_frame`` at a 3D position and (x, y, z, w) orientation."""
    px, py, pz = (float(v) for v in position_m)
    qx, qy, qz, qw = (float(v) for v in orientation_xyzw)
    return _TransformStamped(
        header=header(t_s, parent_frame),
        child_frame_id=child_frame,
        transform=_Transform(translation=_Vector3(x=px, y=py, z=pz), rotation=_Quaternion(x=qx, y=qy, z=qz, w=qw)),
    )


def diagnostic_status(level: int, name: str, message: str, values: dict[str, str], hardware_id: str = "") -> Any:
    """diagnostic_msgs/DiagnosticStatus: ``level`` 0 OK, 1 WARN, 2 ERROR, 3 STALE; ``values`` as its KeyValue list."""
    pairs = [_KeyValue(key=k, value=v) for k, v in values.items()]
    return _DiagnosticStatus(level=level, name=name, message=message, hardware_id=hardware_id, values=pairs)


def diagnostic_values(msg: Any) -> dict[str, str]:
    """The KeyValue list of a diagnostic_msgs/DiagnosticStatus as a dict."""
    return {kv.key: kv.value for kv in msg.values}


def tf_message(*transforms: Any) -> Any:
    """tf2_msgs/TFMessage holding ``transforms`` (geometry_msgs/TransformStamped)."""
    return _TFMessage(transforms=list(transforms))


def imu(
    t_s: float,
    frame_id: str,
    orientation_xyzw: Any,
    angular_velocity_radps: Any,
    linear_acceleration_mps2: Any,
    *,
    gyro_variance: float = 0.0,
    accel_variance: float = 0.0,
) -> Any:
    """sensor_msgs/Imu; variances go on the covariance diagonals (orientation covariance left at 0)."""
    vec = _Vector3
    q = [float(v) for v in orientation_xyzw]
    g = [float(v) for v in angular_velocity_radps]
    a = [float(v) for v in linear_acceleration_mps2]
    return _Imu(
        header=header(t_s, frame_id),
        orientation=_Quaternion(x=q[0], y=q[1], z=q[2], w=q[3]),
        orientation_covariance=_ZERO9,
        angular_velocity=vec(x=g[0], y=g[1], z=g[2]),
        angular_velocity_covariance=_diagonal9(gyro_variance),
        linear_acceleration=vec(x=a[0], y=a[1], z=a[2]),
        linear_acceleration_covariance=_diagonal9(accel_variance),
    )


def joint_state(t_s: float, names: Any, position_rad: Any, velocity_radps: Any) -> Any:
    """sensor_msgs/JointState with positions and velocities (no efforts)."""
    return _JointState(
        header=header(t_s, ""),
        name=list(names),
        position=np.asarray(position_rad, dtype=np.float64),
        velocity=np.asarray(velocity_radps, dtype=np.float64),
        effort=_NO_FLOATS64,
    )


def laser_scan(
    t_s: float,
    frame_id: str,
    *,
    angle_min_rad: float,
    angle_increment_rad: float,
    scan_time_s: float,
    range_min_m: float,
    range_max_m: float,
    ranges_m: Any,
) -> Any:
    """sensor_msgs/LaserScan; ``ranges_m`` keeps REP-117 values (+inf: no return, -inf: too close)."""
    ranges = np.asarray(ranges_m, dtype=np.float32)
    return _LaserScan(
        header=header(t_s, frame_id),
        angle_min=float(angle_min_rad),
        angle_max=float(angle_min_rad + angle_increment_rad * (len(ranges) - 1)),
        angle_increment=float(angle_increment_rad),
        time_increment=0.0,
        scan_time=float(scan_time_s),
        range_min=float(range_min_m),
        range_max=float(range_max_m),
        ranges=ranges,
        intensities=_NO_FLOATS32,
    )


def occupancy_grid(t_s: float, frame_id: str, cells: Any, resolution_m: float, origin_m: tuple[float, float]) -> Any:
    """nav_msgs/OccupancyGrid from an (H, W) int8 array (row 0 = lowest y; values -1 or 0..100).

    Args:
        origin_m: world position (x, y) of the corner of cell (0, 0), metres; the grid is not rotated.
    """
    grid = np.asarray(cells, dtype=np.int8)
    if grid.ndim != 2:
        raise ValueError(f"an occupancy grid needs an (H, W) array, got shape {grid.shape}")
    h, w = grid.shape
    info = _MapMetaData(
        map_load_time=time_msg(t_s),
        resolution=float(resolution_m),
        width=w,
        height=h,
        origin=pose_msg(Pose2D(float(origin_m[0]), float(origin_m[1]), 0.0)),
    )
    return _OccupancyGrid(header=header(t_s, frame_id), info=info, data=grid.reshape(-1))


def grid_frame(msg: Any) -> tuple[Any, GridFrame]:
    """The (H, W) int8 cells of a nav_msgs/OccupancyGrid (row 0 = lowest y) and their placement in its frame."""
    info = msg.info
    cells = np.asarray(msg.data, dtype=np.int8).reshape(info.height, info.width)
    origin = pose2d(info.origin)
    return cells, GridFrame(float(info.resolution), (origin.x, origin.y), cells.shape, origin.theta)


def path_msg(t_s: float, frame_id: str, points: Any) -> Any:
    """nav_msgs/Path through (N, 2) points (metres); each pose faces the next point (the last keeps the previous)."""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    head = header(t_s, frame_id)
    poses = []
    yaw = 0.0
    for i, (x, y) in enumerate(pts):
        if i + 1 < len(pts):
            dx, dy = pts[i + 1] - pts[i]
            if dx or dy:
                yaw = math.atan2(dy, dx)
        poses.append(_PoseStamped(header=head, pose=pose_msg(Pose2D(float(x), float(y), yaw))))
    return _Path(header=head, poses=poses)


def path_points(msg: Any) -> Any:
    """(N, 2) float array of the positions of a nav_msgs/Path, metres."""
    return np.array([(p.pose.position.x, p.pose.position.y) for p in msg.poses], dtype=np.float64).reshape(-1, 2)
