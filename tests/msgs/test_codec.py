"""Codec: round trips for every type on the wire, an independent decoder, dict conversion, validation."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from mcap_ros2._dynamic import generate_dynamic
from rosbags.interfaces import Nodetype

from mjnav.geometry import Pose2D
from mjnav.msgs import (
    ENDPOINTS,
    TOPICS,
    MessageError,
    UnknownMessageType,
    decode,
    encode,
    from_dict,
    message_definition,
    msg_class,
    ros,
    to_dict,
    typestore,
    validate,
)

WIRE_TYPES = sorted(
    {t.msgtype for t in TOPICS.values()}
    | {e.request_type for e in ENDPOINTS.values()}
    | {e.response_type for e in ENDPOINTS.values()}
)


def random_dict(typename: str, rng: np.random.Generator) -> dict[str, Any]:
    """Every field of ``typename`` filled with random values exactly representable in its wire type."""
    _, fields = typestore().fielddefs[typename]
    return {name: _random_field(nt, desc, rng) for name, (nt, desc) in fields}


def _random_base(base: str, rng: np.random.Generator) -> Any:
    if base == "string":
        return "".join(rng.choice(list("abcxyz_/ é")) for _ in range(int(rng.integers(0, 12))))
    if base == "bool":
        return bool(rng.integers(0, 2))
    if base == "float32":
        return float(np.float32(rng.normal(0, 100)))
    if base == "float64":
        return float(rng.normal(0, 100))
    bits = {
        "int8": 7,
        "int16": 15,
        "int32": 31,
        "int64": 62,
        "uint8": 8,
        "byte": 8,
        "char": 8,
        "uint16": 16,
        "uint32": 32,
        "uint64": 63,
    }[base]
    signed = base.startswith("int")
    return int(rng.integers(-(2**bits) if signed else 0, 2**bits))


def _random_field(nodetype: int, desc: Any, rng: np.random.Generator) -> Any:
    if nodetype == Nodetype.BASE:
        return _random_base(desc[0], rng)
    if nodetype == Nodetype.NAME:
        return random_dict(desc, rng)
    (subtype, subdesc), length = desc
    n = length if nodetype == Nodetype.ARRAY else int(rng.integers(0, 5))
    return [_random_field(subtype, subdesc, rng) for _ in range(n)]


@pytest.mark.parametrize("typename", WIRE_TYPES)
def test_round_trip_preserves_every_field(typename: str) -> None:
    rng = np.random.default_rng(7)
    for _ in range(5):
        data = random_dict(typename, rng)
        msg = from_dict(typename, data)
        back = decode(encode(msg, typename), typename)
        assert to_dict(back) == to_dict(msg) == data


@pytest.mark.parametrize("typename", WIRE_TYPES)
def test_independent_decoder_reads_our_bytes(typename: str) -> None:
    """mcap_ros2's dynamic decoder, fed only the .msg text, decodes our CDR to the same values."""
    decoders = generate_dynamic(typename, message_definition(typename))
    rng = np.random.default_rng(11)
    for _ in range(3):
        data = random_dict(typename, rng)
        theirs = decoders[typename](encode(from_dict(typename, data)))
        assert _namespace_to_dict(theirs) == _normalise(data)


def _namespace_to_dict(obj: Any) -> Any:
    if hasattr(obj, "__slots__") or hasattr(obj, "__dict__"):
        names = getattr(obj, "__slots__", None) or [k for k in vars(obj) if not k.startswith("_")]
        return {n: _namespace_to_dict(getattr(obj, n)) for n in names}
    if isinstance(obj, bytes | bytearray):
        return list(obj)
    if isinstance(obj, list | tuple):
        return [_namespace_to_dict(v) for v in obj]
    return obj


def _normalise(data: Any) -> Any:
    if isinstance(data, dict):
        # rosbags gives empty messages (std_msgs/Empty) the IDL placeholder byte; .msg-based decoders show no field
        return {k: _normalise(v) for k, v in data.items() if k != "structure_needs_at_least_one_member"}
    if isinstance(data, list):
        return [_normalise(v) for v in data]
    return data


def test_twist_bytes_are_the_standard_layout() -> None:
    """Hand-checked CDR: 4-byte header (LE) then six float64s — what any ROS 2 node would send."""
    data = encode(ros.twist(0.25, -0.5))
    assert data[:4] == b"\x00\x01\x00\x00"
    assert np.frombuffer(data[4:], dtype="<f8").tolist() == [0.25, 0.0, 0.0, 0.0, 0.0, -0.5]


def test_project_messages_have_their_constants() -> None:
    cls = msg_class("mjnav_msgs/msg/GoalStatus")
    assert cls.STATE_REACHED == 4 and cls.ERROR_GOAL_OCCUPIED == 2
    text = message_definition("mjnav_msgs/msg/ServiceStatus")
    assert "uint64 messages_rejected" in text and "MSG: std_msgs/Header" in text


@pytest.mark.parametrize(
    "payload",
    [b"", b"\x00", b"\x07\x07\x00\x00abcd", b"\x00\x01\x00\x00\x01", bytes(range(256)) * 3],
)
def test_decode_rejects_garbage_with_a_typed_error(payload: bytes) -> None:
    for typename in ("sensor_msgs/msg/LaserScan", "geometry_msgs/msg/Twist", "nav_msgs/msg/OccupancyGrid"):
        with pytest.raises(MessageError):
            decode(payload, typename)


def test_decode_rejects_truncated_and_padded_payloads() -> None:
    scan = from_dict("sensor_msgs/msg/LaserScan", {"range_max": 10.0, "ranges": [1.0] * 360})
    data = encode(scan)
    for cut in (5, 20, len(data) // 2, len(data) - 4):
        with pytest.raises(MessageError):
            decode(data[:cut], "sensor_msgs/msg/LaserScan")
    with pytest.raises(MessageError):
        decode(data + b"\x00" * 16, "sensor_msgs/msg/LaserScan")


def test_unknown_type_and_type_mismatch() -> None:
    with pytest.raises(UnknownMessageType):
        decode(b"\x00\x01\x00\x00", "nope_msgs/msg/Nope")
    with pytest.raises(MessageError, match="expected a sensor_msgs/msg/LaserScan"):
        encode(ros.twist(0, 0), "sensor_msgs/msg/LaserScan")


def test_from_dict_errors_name_the_field() -> None:
    with pytest.raises(MessageError, match="unknown field"):
        from_dict("geometry_msgs/msg/Twist", {"linear": {"w": 1.0}})
    with pytest.raises(MessageError, match=r"Twist\.linear\.x: expected a number"):
        from_dict("geometry_msgs/msg/Twist", {"linear": {"x": "fast"}})
    with pytest.raises(MessageError, match="outside the uint8 range"):
        from_dict("mjnav_msgs/msg/GoalStatus", {"state": 300})
    with pytest.raises(MessageError, match="exactly 36 elements"):
        from_dict("nav_msgs/msg/Odometry", {"pose": {"covariance": [0.0] * 5}})


def test_validate_rejects_nan_and_bad_structure_but_keeps_rep117_ranges() -> None:
    with pytest.raises(MessageError, match=r"linear\.x is nan"):
        validate(from_dict("geometry_msgs/msg/Twist", {"linear": {"x": math.nan}}))
    scan = from_dict(
        "sensor_msgs/msg/LaserScan",
        {"range_min": 0.1, "range_max": 10.0, "angle_increment": 0.1, "ranges": [1.0, math.inf, math.nan]},
    )
    validate(scan)  # +inf (no return) and NaN (invalid) are legal per REP-117
    with pytest.raises(MessageError, match="range limits"):
        validate(from_dict("sensor_msgs/msg/LaserScan", {"range_min": 5.0, "range_max": 1.0}))
    grid = from_dict(
        "nav_msgs/msg/OccupancyGrid",
        {"info": {"width": 2, "height": 2, "resolution": 0.05}, "data": [0, 100, -1, 50]},
    )
    validate(grid)
    with pytest.raises(MessageError, match="cells"):
        validate(
            from_dict(
                "nav_msgs/msg/OccupancyGrid",
                {"info": {"width": 3, "height": 2, "resolution": 0.05}, "data": [0] * 5},
            )
        )
    with pytest.raises(MessageError, match="unit quaternion"):
        validate(from_dict("geometry_msgs/msg/PoseStamped", {"pose": {"orientation": {"z": 0.1, "w": 0.0}}}))
    # Left out, the orientation is the identity (ROS 2's w = 1); all zeros means "no orientation" and passes.
    assert from_dict("geometry_msgs/msg/PoseStamped", {}).pose.orientation.w == 1.0
    validate(from_dict("geometry_msgs/msg/PoseStamped", {"pose": {"orientation": {"w": 0.0}}}))
    validate(ros.pose_stamped(1.5, "map", Pose2D(1.0, 2.0, 0.3)))


def test_ros_builders_round_trip() -> None:
    pose = Pose2D(1.0, -2.0, 2.5)
    msg = decode(encode(ros.pose_stamped(12.25, "map", pose)), "geometry_msgs/msg/PoseStamped")
    assert ros.seconds(msg.header.stamp) == 12.25 and msg.header.frame_id == "map"
    back = ros.pose2d(msg.pose)
    assert (back.x, back.y) == (1.0, -2.0) and math.isclose(back.theta, 2.5, abs_tol=1e-12)
    odom = ros.odometry(3.0, pose, 0.4, -0.1, pose_variance=(0.01, 0.02, 0.03))
    validate(odom)
    assert odom.pose.covariance[0] == 0.01 and odom.pose.covariance[35] == 0.03
    with pytest.raises(ValueError):
        ros.time_msg(-1.0)
    assert ros.time_msg(1.999999999_7).sec == 2
