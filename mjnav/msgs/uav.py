"""Builders and readers for the UAV stack's messages: 3-D poses and odometry, GPS fixes, pressure, trajectories.

Everything on the wire follows REP-103 (ENU world, FLU body) unless a frame id says otherwise (``map_ned``);
quaternions are passed as (w, x, y, z) arrays here and written in ROS order.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from mjnav.msgs.codec import typestore
from mjnav.msgs.ros import header, seconds

_types = typestore().types
_NavSatFix = _types["sensor_msgs/msg/NavSatFix"]
_NavSatStatus = _types["sensor_msgs/msg/NavSatStatus"]
_FluidPressure = _types["sensor_msgs/msg/FluidPressure"]
_Odometry = _types["nav_msgs/msg/Odometry"]
_Path = _types["nav_msgs/msg/Path"]
_Point = _types["geometry_msgs/msg/Point"]
_Pose = _types["geometry_msgs/msg/Pose"]
_PoseStamped = _types["geometry_msgs/msg/PoseStamped"]
_PoseWithCovariance = _types["geometry_msgs/msg/PoseWithCovariance"]
_Quaternion = _types["geometry_msgs/msg/Quaternion"]
_Twist = _types["geometry_msgs/msg/Twist"]
_TwistWithCovariance = _types["geometry_msgs/msg/TwistWithCovariance"]
_Vector3 = _types["geometry_msgs/msg/Vector3"]
_Bool = _types["std_msgs/msg/Bool"]
_String = _types["std_msgs/msg/String"]
_ZERO36 = np.zeros(36)
_ZERO36.setflags(write=False)
#: sensor_msgs/NavSatStatus STATUS_FIX, SERVICE_GPS and NavSatFix COVARIANCE_TYPE_DIAGONAL_KNOWN.
_STATUS_FIX, _SERVICE_GPS, _COVARIANCE_DIAGONAL_KNOWN = 0, 1, 2


def pose3d_msg(position_m: Any, quat_wxyz: Any) -> Any:
    """geometry_msgs/Pose of a position (3,) m and a (w, x, y, z) quaternion."""
    p = [float(v) for v in position_m]
    w, x, y, z = (float(v) for v in quat_wxyz)
    return _Pose(position=_Point(x=p[0], y=p[1], z=p[2]), orientation=_Quaternion(x=x, y=y, z=z, w=w))


def pose_stamped3d(t_s: float, frame_id: str, position_m: Any, quat_wxyz: Any = (1.0, 0.0, 0.0, 0.0)) -> Any:
    """geometry_msgs/PoseStamped of a 3-D pose."""
    return _PoseStamped(header=header(t_s, frame_id), pose=pose3d_msg(position_m, quat_wxyz))


def position(pose: Any) -> np.ndarray:
    """(3,) position of a geometry_msgs/Pose, m."""
    p = pose.position
    return np.array([p.x, p.y, p.z])


def quat_wxyz(pose: Any) -> np.ndarray:
    """(4,) (w, x, y, z) orientation of a geometry_msgs/Pose."""
    q = pose.orientation
    return np.array([q.w, q.x, q.y, q.z])


def odometry3d(
    t_s: float,
    frame_id: str,
    child_frame_id: str,
    position_m: Any,
    quat: Any,
    velocity_mps: Any,
    angular_velocity_radps: Any,
    *,
    position_variance_m2: Any = None,
    velocity_variance: Any = None,
) -> Any:
    """nav_msgs/Odometry of a 3-D state.

    Args:
        position_m: (3,) in ``frame_id``; quat: (w, x, y, z), ``child_frame_id`` → ``frame_id``.
        velocity_mps: (3,) linear velocity, expressed in ``frame_id`` (the convention of the UAV stack; ROS
            expresses the twist in ``child_frame_id``: the INS and mocap say which in their docs).
        angular_velocity_radps: (3,) body rates in ``child_frame_id``.
        position_variance_m2, velocity_variance: optional (3, 3) covariances for the pose / twist blocks.
    """
    v = [float(x) for x in velocity_mps]
    r = [float(x) for x in angular_velocity_radps]
    pcov, tcov = _ZERO36, _ZERO36
    if position_variance_m2 is not None:
        pcov = np.zeros((6, 6))
        pcov[0:3, 0:3] = position_variance_m2
        pcov = pcov.reshape(36)
    if velocity_variance is not None:
        tcov = np.zeros((6, 6))
        tcov[0:3, 0:3] = velocity_variance
        tcov = tcov.reshape(36)
    return _Odometry(
        header=header(t_s, frame_id),
        child_frame_id=child_frame_id,
        pose=_PoseWithCovariance(pose=pose3d_msg(position_m, quat), covariance=pcov),
        twist=_TwistWithCovariance(
            twist=_Twist(linear=_Vector3(x=v[0], y=v[1], z=v[2]), angular=_Vector3(x=r[0], y=r[1], z=r[2])),
            covariance=tcov,
        ),
    )


def odometry_state(msg: Any) -> tuple[float, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(stamp s, position (3,), quaternion (w, x, y, z), velocity (3,), body rates (3,)) of a nav_msgs/Odometry."""
    tw = msg.twist.twist
    return (
        seconds(msg.header.stamp),
        position(msg.pose.pose),
        quat_wxyz(msg.pose.pose),
        np.array([tw.linear.x, tw.linear.y, tw.linear.z]),
        np.array([tw.angular.x, tw.angular.y, tw.angular.z]),
    )


def nav_sat_fix(t_s: float, lat_deg: float, lon_deg: float, alt_m: float, sigma_m: float) -> Any:
    """sensor_msgs/NavSatFix (GPS service, status FIX) with a diagonal covariance of ``sigma_m``² per axis."""
    return _NavSatFix(
        header=header(t_s, "gps"),
        status=_NavSatStatus(status=_STATUS_FIX, service=_SERVICE_GPS),
        latitude=float(lat_deg),
        longitude=float(lon_deg),
        altitude=float(alt_m),
        position_covariance=np.diag([sigma_m**2] * 3).reshape(9).astype(np.float64),
        position_covariance_type=_COVARIANCE_DIAGONAL_KNOWN,
    )


def fluid_pressure(t_s: float, pressure_pa: float, variance_pa2: float) -> Any:
    """sensor_msgs/FluidPressure (Pa) from the barometer."""
    return _FluidPressure(header=header(t_s, "baro"), fluid_pressure=float(pressure_pa), variance=float(variance_pa2))


def trajectory(frame_id: str, stamps_s: Any, positions_m: Any, yaws_rad: Any = None, t_s: float = 0.0) -> Any:
    """nav_msgs/Path whose poses are stamped with the sim time each is due (ENU, yaw about +z)."""
    pts = np.asarray(positions_m, dtype=np.float64).reshape(-1, 3)
    ts = np.asarray(stamps_s, dtype=np.float64).reshape(-1)
    yaw = np.zeros(len(pts)) if yaws_rad is None else np.asarray(yaws_rad, dtype=np.float64).reshape(-1)
    if not (len(ts) == len(pts) == len(yaw)):
        raise ValueError(f"trajectory needs as many stamps, positions and yaws: {len(ts)}, {len(pts)}, {len(yaw)}")
    poses = [
        pose_stamped3d(float(t), frame_id, p, (np.cos(0.5 * y), 0.0, 0.0, np.sin(0.5 * y)))
        for t, p, y in zip(ts, pts, yaw, strict=True)
    ]
    return _Path(header=header(t_s, frame_id), poses=poses)


def trajectory_arrays(msg: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(stamps (N,) s, positions (N, 3) m, yaws (N,) rad) of a trajectory Path."""
    rows = [
        (
            seconds(ps.header.stamp),
            ps.pose.position.x,
            ps.pose.position.y,
            ps.pose.position.z,
            ps.pose.orientation,
        )
        for ps in msg.poses
    ]
    data = np.array([r[:4] for r in rows], dtype=np.float64).reshape(-1, 4)
    yaw = np.array(
        [math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z)) for *_, q in rows],
        dtype=np.float64,
    )
    return data[:, 0].copy(), data[:, 1:4].copy(), yaw


def boolean(value: bool) -> Any:
    """std_msgs/Bool."""
    return _Bool(data=bool(value))


def string(text: str) -> Any:
    """std_msgs/String."""
    return _String(data=text)
