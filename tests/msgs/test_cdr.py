"""The compiled CDR codecs (mjnav.msgs.cdr) against rosbags' own serialiser, on every type of the typestore.

Random messages (seeded) exercise what the generator's alignment bookkeeping has to get right: strings of every
length mod 4 before 8-byte fields, empty and non-empty float64 sequences, sequences and fixed arrays of nested
messages, unicode. For each, the compiled encoder must produce rosbags' bytes exactly and the compiled decoder
rosbags' object; for truncated payloads both paths must agree on accept/reject.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from rosbags.interfaces import Nodetype

from mjnav.msgs import MessageError, decode, encode, from_dict, to_dict, typestore
from mjnav.msgs.cdr import compiled
from mjnav.msgs.codec import encoder, rosbags_decoder, rosbags_encoder

STORE = typestore()
ALL_TYPES = sorted(STORE.types)
INT_BOUNDS = {
    "byte": (0, 255),  # an unsigned octet, as in ROS 2
    "char": (0, 255),
    "int8": (-128, 127),
    "uint8": (0, 255),
    "int16": (-(2**15), 2**15 - 1),
    "uint16": (0, 2**16 - 1),
    "int32": (-(2**31), 2**31 - 1),
    "uint32": (0, 2**32 - 1),
    "int64": (-(2**63), 2**63 - 1),
    "uint64": (0, 2**64 - 1),
}
DTYPES = {
    "bool": np.bool_,
    "byte": np.uint8,
    "char": np.uint8,
    "float32": np.float32,
    "float64": np.float64,
    **{k: getattr(np, k) for k in ("int8", "uint8", "int16", "uint16", "int32", "uint32", "int64", "uint64")},
}
STRINGS = ["", "a", "ab", "abc", "abcd", "map", "base_link", "ünïcødé ✓"]


def _scalar(base: str, rng: np.random.Generator) -> Any:
    if base == "string":
        return STRINGS[rng.integers(len(STRINGS))]
    if base == "bool":
        return bool(rng.integers(2))
    if base in ("float32", "float64"):
        return float(np.float32(rng.normal(0.0, 100.0))) if base == "float32" else float(rng.normal(0.0, 1e6))
    lo, hi = INT_BOUNDS[base]
    return int(rng.integers(lo, hi, endpoint=True, dtype=np.int64 if hi < 2**63 else np.uint64))


def _array(base: str, n: int, rng: np.random.Generator) -> Any:
    if base == "string":
        return [_scalar(base, rng) for _ in range(n)]
    return np.array([_scalar(base, rng) for _ in range(n)], dtype=DTYPES[base])


def random_message(typename: str, rng: np.random.Generator) -> Any:
    """A message of ``typename`` with random values, sequence lengths 0–3 (0 often, to test alignment)."""
    values = {}
    for name, (nodetype, desc) in STORE.fielddefs[typename][1]:
        if nodetype == Nodetype.BASE:
            values[name] = _scalar(desc[0], rng)
        elif nodetype == Nodetype.NAME:
            values[name] = random_message(desc, rng)
        else:
            (subtype, subdesc), length = desc
            n = length if nodetype == Nodetype.ARRAY else int(rng.integers(0, 4))
            if subtype == Nodetype.NAME:
                values[name] = [random_message(subdesc, rng) for _ in range(n)]
            else:
                values[name] = _array(subdesc[0], n, rng)
    return STORE.types[typename](**values)


def _same(a: Any, b: Any) -> bool:
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return (
            isinstance(a, np.ndarray)
            and isinstance(b, np.ndarray)
            and a.dtype == b.dtype
            and np.array_equal(a, b, equal_nan=a.dtype.kind == "f")
        )
    if hasattr(a, "__msgtype__"):
        return a.__msgtype__ == getattr(b, "__msgtype__", None) and all(
            _same(getattr(a, f), getattr(b, f)) for f in a.__dataclass_fields__
        )
    if isinstance(a, list):
        return isinstance(b, list) and len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b, strict=True))
    return type(a) is type(b) and a == b


@pytest.mark.e2e
@pytest.mark.parametrize("typename", ALL_TYPES)
def test_compiled_codec_matches_rosbags_on_random_messages(typename: str) -> None:
    codec = compiled(STORE, typename)
    assert codec is not None, f"{typename} has no compiled codec"
    rng = np.random.default_rng(7)
    for _ in range(12):
        msg = random_message(typename, rng)
        reference = rosbags_encoder(typename)(msg)
        assert codec.encode(msg) == reference, codec.source
        ours = codec.decode(reference)
        assert _same(ours, rosbags_decoder(typename)(reference)), codec.source
        assert _same(ours, msg)
        assert _same(decode(memoryview(reference), typename), msg)  # what Zenoh hands over may be a view


@pytest.mark.parametrize(
    "typename",
    ["sensor_msgs/msg/LaserScan", "nav_msgs/msg/Odometry", "tf2_msgs/msg/TFMessage", "sensor_msgs/msg/JointState"],
)
def test_truncated_payloads_are_rejected_exactly_when_rosbags_rejects_them(typename: str) -> None:
    rng = np.random.default_rng(3)
    codec = compiled(STORE, typename)
    assert codec is not None
    msg = random_message(typename, rng)
    data = bytes(STORE.serialize_cdr(msg, typename))
    for cut in range(4, len(data) + 8):
        payload = data[:cut] + bytes(max(0, cut - len(data)))
        try:
            expected: Any = STORE.deserialize_cdr(payload, typename)
        except Exception:
            expected = None
        if expected is None:
            with pytest.raises(MessageError):
                decode(payload, typename)
        else:
            assert _same(decode(payload, typename), expected)


def test_values_the_compiled_path_leaves_to_rosbags() -> None:
    scan = from_dict("sensor_msgs/msg/LaserScan", {"range_min": 0.1, "range_max": 5.0, "ranges": [1.0, 2.0]})
    reference = bytes(STORE.serialize_cdr(scan, "sensor_msgs/msg/LaserScan"))
    # a non-contiguous float32 view is still an exactly-typed array: same bytes
    scan.ranges = np.array([1.0, 9.0, 2.0], dtype=np.float32)[::2]
    assert encode(scan) == reference
    # a float64 array in a float32 sequence is rosbags' to judge: it refuses, and so do we, with a typed error
    scan.ranges = np.array([1.0, 2.0])
    with pytest.raises(MessageError):
        encode(scan)
    # a resolved encoder refuses a message of another type (it would otherwise encode by attribute names)
    with pytest.raises(MessageError, match="expected a geometry_msgs/msg/Twist"):
        encoder("geometry_msgs/msg/Twist")(scan)
    # an out-of-range integer is refused with a typed error
    twist_time = from_dict("builtin_interfaces/msg/Time", {"sec": 1})
    twist_time.sec = 2**40
    with pytest.raises(MessageError):
        encode(twist_time)


def test_big_endian_payloads_decode_through_rosbags() -> None:
    rng = np.random.default_rng(5)
    msg = random_message("nav_msgs/msg/Odometry", rng)
    big = bytes(STORE.serialize_cdr(msg, "nav_msgs/msg/Odometry", little_endian=False))
    assert big[:2] == b"\x00\x00"
    assert to_dict(decode(big, "nav_msgs/msg/Odometry")) == to_dict(msg)


def _float_paths(typename: str, prefix: tuple[str, ...] = ()) -> list[tuple[str, ...]]:
    """Attribute paths of the float scalars of ``typename`` (nested messages followed, sequences not)."""
    out = []
    for name, (nodetype, desc) in STORE.fielddefs[typename][1]:
        if nodetype == Nodetype.BASE and desc[0] in ("float32", "float64"):
            out.append((*prefix, name))
        elif nodetype == Nodetype.NAME:
            out += _float_paths(desc, (*prefix, name))
    return out


@pytest.mark.parametrize("typename", [t for t in ALL_TYPES if _float_paths(t)])
def test_generated_finite_check_agrees_with_the_field_by_field_walk(typename: str) -> None:
    from mjnav.msgs.codec import _first_nonfinite, all_finite

    rng = np.random.default_rng(11)
    msg = random_message(typename, rng)
    assert all_finite(typename)(msg) and _first_nonfinite(msg) is None
    for path in _float_paths(typename):
        owner = msg
        for name in path[:-1]:
            owner = getattr(owner, name)
        saved = getattr(owner, path[-1])
        setattr(owner, path[-1], float("nan"))
        assert not all_finite(typename)(msg), path
        assert _first_nonfinite(msg) is not None, path
        setattr(owner, path[-1], saved)


#: Types with a byte field of their own (scalar or array); DiagnosticArray holds them through DiagnosticStatus.
BYTE_TYPES = [t for t in ALL_TYPES if "'byte'" in repr(STORE.fielddefs[t][1])]


def test_byte_is_an_unsigned_octet_on_every_path() -> None:
    """ROS 2 ``byte`` is the IDL ``octet``, 0..255: a DiagnosticStatus of level 200 builds, encodes (compiled and
    rosbags paths, same octet 0xC8), decodes to 200 on both paths and reads 200 in an independent decoder."""
    from mcap_ros2._dynamic import generate_dynamic

    from mjnav.msgs import message_definition

    typename = "diagnostic_msgs/msg/DiagnosticStatus"
    msg = from_dict(typename, {"level": 200, "name": "motor", "message": "hot"})
    data = encode(msg)
    assert data[4] == 200
    assert rosbags_encoder(typename)(msg) == data
    assert decode(data, typename).level == 200
    assert rosbags_decoder(typename)(data).level == 200
    theirs = generate_dynamic(typename, message_definition(typename))[typename](data)
    assert theirs.level == 200
    big = bytes(STORE.serialize_cdr(from_dict(typename, {"level": 2}), typename, little_endian=False))
    assert decode(big, typename).level == 2  # big-endian payloads go through rosbags
    for bad in (256, -1):
        with pytest.raises(MessageError, match="byte"):
            from_dict(typename, {"level": bad})
        msg.level = bad
        with pytest.raises(MessageError):
            encode(msg)
        with pytest.raises(MessageError, match=r"outside the byte range"):
            rosbags_encoder(typename)(msg)


def test_byte_sequences_and_nested_bytes_round_trip_unsigned() -> None:
    arr = from_dict("std_msgs/msg/ByteMultiArray", {"data": [0, 1, 127, 128, 200, 255]})
    assert arr.data.dtype == np.uint8
    data = encode(arr)
    assert data.endswith(bytes([0, 1, 127, 128, 200, 255]))
    for back in (decode(data, "std_msgs/msg/ByteMultiArray"), rosbags_decoder("std_msgs/msg/ByteMultiArray")(data)):
        assert back.data.dtype == np.uint8
        assert back.data.tolist() == [0, 1, 127, 128, 200, 255]
    # A message sequence holding bytes, through the rosbags path (a list where an array is declared is left to it).
    array = from_dict("diagnostic_msgs/msg/DiagnosticArray", {"status": [{"level": 255}, {"level": 3}, {"level": 128}]})
    data = encode(array)
    assert rosbags_encoder("diagnostic_msgs/msg/DiagnosticArray")(array) == data
    via_rosbags = rosbags_decoder("diagnostic_msgs/msg/DiagnosticArray")(data)
    assert [s.level for s in via_rosbags.status] == [255, 3, 128]
    assert [s.level for s in decode(data, "diagnostic_msgs/msg/DiagnosticArray").status] == [255, 3, 128]
    assert [s.level for s in array.status] == [255, 3, 128]  # the caller's message is not modified


@pytest.mark.parametrize("typename", BYTE_TYPES)
def test_every_type_with_bytes_encodes_whatever_from_dict_builds(typename: str) -> None:
    """Any message that builds must encode: the extreme byte values on both paths, the same bytes."""
    for value in (0, 255):
        msg = random_message(typename, np.random.default_rng(value))
        _set_bytes(msg, value)
        data = encode(msg)
        assert rosbags_encoder(typename)(msg) == data
        assert _same(decode(data, typename), msg)
        assert _same(rosbags_decoder(typename)(data), msg)


def _set_bytes(msg: Any, value: int) -> None:
    for name, (nodetype, desc) in STORE.fielddefs[msg.__msgtype__][1]:
        if nodetype == Nodetype.BASE and desc[0] == "byte":
            setattr(msg, name, value)
        elif nodetype in (Nodetype.ARRAY, Nodetype.SEQUENCE) and desc[0] == (Nodetype.BASE, ("byte", 0)):
            getattr(msg, name)[:] = value
