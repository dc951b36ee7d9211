"""rmw_zenoh's key expressions, liveliness tokens and attachments (ROS 2 Jazzy and later over Zenoh).

The format is rmw_zenoh's ``docs/design.md``:

- data key: ``<domain_id>/<fully qualified topic>/<dds type name>/<RIHS01 type hash>``, e.g.
  ``0/robot0/cmd_vel/geometry_msgs::msg::dds_::Twist_/RIHS01_9c45…``;
- node token: ``@ros2_lv/<domain_id>/<session id>/<node id>/<node id>/NN/<enclave>/<namespace>/<node name>``;
- publisher / subscription token: ``@ros2_lv/<domain_id>/<session id>/<node id>/<entity id>/MP|MS/<enclave>/
  <namespace>/<node name>/<topic>/<dds type name>/<type hash>/<qos>``, names mangled (``/`` → ``%``, empty →
  ``%``);
- attachment of every published sample: sequence number (int64), source timestamp (int64, ns since the UNIX epoch),
  GID length (one byte, 16) and the publisher's 16-byte GID, little endian.

This module spells those keys, as :mod:`mjnav.msgs.topics` spells mjnav's own; the bridge service
(:mod:`mjnav.services.ros_bridge`) declares them.
"""

from __future__ import annotations

import struct

from mjnav.msgs.rihs import dds_type_name, type_hash
from mjnav.msgs.topics import Kind, Topic, check_namespace

#: The hermetic prefix of rmw_zenoh's graph tokens.
ADMIN_SPACE = "@ros2_lv"
#: Length of a publisher GID, bytes.
GID_BYTES = 16
_ATTACHMENT = struct.Struct("<qqB")
#: QoS of the bridge's endpoints in rmw_zenoh's compact token form
#: ``<reliability>:<durability>:<history>,<depth>:<deadline>:<lifespan>:<liveliness>`` (empty = default: reliable,
#: volatile, automatic liveliness, infinite durations). Snapshot topics keep the last message; event topics keep all.
QOS = {Kind.SNAPSHOT: "::,1:,:,:,,", Kind.EVENT: "::2,:,:,:,,"}


def mangle(name: str) -> str:
    """A ROS name as a single key chunk: ``/`` → ``%`` (``%`` alone for the empty name)."""
    return name.replace("/", "%") or "%"


def check_domain(domain_id: int) -> None:
    """Raise ValueError unless ``domain_id`` is a ROS domain id (0..232, as ``ROS_DOMAIN_ID``)."""
    if isinstance(domain_id, bool) or not isinstance(domain_id, int) or not 0 <= domain_id <= 232:
        raise ValueError(f"ROS domain id must be an integer 0..232, got {domain_id!r}")


def topic_name(row: Topic, namespace: str) -> str:
    """The fully qualified ROS 2 name of a (not per-service) topic: ``/<namespace>/<topic>``."""
    check_namespace(namespace)
    if row.per_service:
        raise ValueError(f"topic {row.name!r} is per service: it has no ROS 2 name")
    return f"/{namespace}/{row.name}"


def data_key(domain_id: int, row: Topic, namespace: str) -> str:
    """The rmw_zenoh key expression that carries topic ``row`` of ``namespace`` in ROS domain ``domain_id``."""
    check_domain(domain_id)
    return f"{domain_id}{topic_name(row, namespace)}/{dds_type_name(row.msgtype)}/{type_hash(row.msgtype)}"


def node_token(domain_id: int, session_id: str, node_id: int, namespace: str, node: str) -> str:
    """The liveliness token of ROS 2 node ``/<namespace>/<node>`` (no enclave)."""
    check_domain(domain_id)
    return f"{ADMIN_SPACE}/{domain_id}/{session_id}/{node_id}/{node_id}/NN/%/{mangle('/' + namespace)}/{node}"


def endpoint_token(
    domain_id: int,
    session_id: str,
    node_id: int,
    entity_id: int,
    kind: str,
    namespace: str,
    node: str,
    row: Topic,
) -> str:
    """The liveliness token of a publisher (``kind="MP"``) or subscription (``"MS"``) of topic ``row``, owned by
    node ``/<namespace>/<node>``."""
    if kind not in ("MP", "MS"):
        raise ValueError(f"endpoint kind must be MP or MS, got {kind!r}")
    check_domain(domain_id)
    return (
        f"{ADMIN_SPACE}/{domain_id}/{session_id}/{node_id}/{entity_id}/{kind}/%/{mangle('/' + namespace)}/{node}/"
        f"{mangle(topic_name(row, namespace))}/{dds_type_name(row.msgtype)}/{type_hash(row.msgtype)}/"
        f"{QOS[row.kind]}"
    )


def attachment(sequence: int, stamp_ns: int, gid: bytes) -> bytes:
    """The attachment rmw_zenoh puts on a published sample."""
    if len(gid) != GID_BYTES:
        raise ValueError(f"a GID has {GID_BYTES} bytes, got {len(gid)}")
    return _ATTACHMENT.pack(sequence, stamp_ns, GID_BYTES) + gid


def parse_attachment(data: bytes) -> tuple[int, int, bytes]:
    """``(sequence, stamp_ns, gid)`` of an rmw_zenoh sample attachment.

    Raises:
        ValueError: too short, or the GID length does not match the bytes.
    """
    if len(data) < _ATTACHMENT.size:
        raise ValueError(f"rmw_zenoh attachment too short: {len(data)} bytes")
    sequence, stamp_ns, n = _ATTACHMENT.unpack_from(data)
    gid = bytes(data[_ATTACHMENT.size :])
    if len(gid) != n:
        raise ValueError(f"rmw_zenoh attachment: GID length {n} but {len(gid)} bytes follow")
    return sequence, stamp_ns, gid
