"""RIHS01 type hashes of ROS 2 message types (REP-2011), computed from the typestore's field definitions.

A ROS 2 type hash is the SHA-256 of a canonical JSON text of the type's description — its fields (name, field type
id, array capacity, string capacity, nested type name; no constants, no defaults, no comments) followed by the
descriptions of every type it references, directly or not, sorted by name — written ``RIHS01_<64 hex digits>``.
rmw_zenoh puts it in every key expression and liveliness token, so a subscriber only matches a publisher of the
same type definition. The field type ids are those of ``type_description_interfaces/msg/FieldType``.
"""

from __future__ import annotations

import hashlib
import json
from functools import cache
from typing import Any

from rosbags.interfaces import Nodetype

from mjnav.msgs.codec import msg_class, typestore

#: ``type_description_interfaces/msg/FieldType`` ids of the primitive types, by ``.msg`` spelling (``byte`` is the
#: IDL ``octet``; ``char`` is ``uint8`` in the IDL that ``.msg`` files are converted to).
_TYPE_IDS = {
    "int8": 2,
    "uint8": 3,
    "char": 3,
    "int16": 4,
    "uint16": 5,
    "int32": 6,
    "uint32": 7,
    "int64": 8,
    "uint64": 9,
    "float32": 10,
    "float64": 11,
    "bool": 15,
    "byte": 16,
    "string": 17,
    "wstring": 18,
}
_NESTED = 1
_BOUNDED_STRING = 21
_BOUNDED_WSTRING = 22
#: Offsets of the container kinds: fixed array, bounded sequence, unbounded sequence.
_ARRAY, _BOUNDED_SEQUENCE, _SEQUENCE = 48, 96, 144


def _field_type(desc: tuple[Nodetype, Any]) -> tuple[dict[str, Any], str | None]:
    """The FieldType dict of one rosbags field description, and the nested type it names (if any)."""
    node, arg = desc
    capacity = 0
    offset = 0
    if node in (Nodetype.ARRAY, Nodetype.SEQUENCE):
        (node, arg), size = arg
        if desc[0] is Nodetype.ARRAY:
            offset, capacity = _ARRAY, size
        elif size:
            offset, capacity = _BOUNDED_SEQUENCE, size
        else:
            offset = _SEQUENCE
    string_capacity = 0
    nested = None
    if node is Nodetype.NAME:
        type_id = _NESTED
        nested = str(arg)
    else:
        base, bound = arg
        type_id = _TYPE_IDS[base]
        if base in ("string", "wstring") and bound:
            type_id = _BOUNDED_STRING if base == "string" else _BOUNDED_WSTRING
            string_capacity = bound
    field_type = {
        "type_id": type_id + offset,
        "capacity": capacity,
        "string_capacity": string_capacity,
        "nested_type_name": nested or "",
    }
    return field_type, nested


def _description(typename: str) -> tuple[dict[str, Any], list[str]]:
    """The IndividualTypeDescription of ``typename`` (hashable form) and the types its fields name."""
    _, fields = typestore().fielddefs[typename]
    out = []
    nested = []
    for name, desc in fields:
        field_type, ref = _field_type(desc)
        out.append({"name": name, "type": field_type})
        if ref is not None:
            nested.append(ref)
    return {"type_name": typename, "fields": out}, nested


def type_description(typename: str) -> dict[str, Any]:
    """The hashable TypeDescription of ``typename``: its own description and every referenced one, sorted.

    Raises:
        UnknownMessageType: ``typename`` is not in the typestore.
    """
    msg_class(typename)
    main, pending = _description(typename)
    referenced: dict[str, dict[str, Any]] = {}
    while pending:
        name = pending.pop()
        if name in referenced:
            continue
        referenced[name], more = _description(name)
        pending.extend(more)
    return {
        "type_description": main,
        "referenced_type_descriptions": [referenced[name] for name in sorted(referenced)],
    }


@cache
def type_hash(typename: str) -> str:
    """The RIHS01 hash of ``typename``, e.g. ``RIHS01_9c45bf16…`` for ``geometry_msgs/msg/Twist``.

    Raises:
        UnknownMessageType: ``typename`` is not in the typestore.
    """
    text = json.dumps(type_description(typename), separators=(", ", ": "), ensure_ascii=True, allow_nan=False)
    return "RIHS01_" + hashlib.sha256(text.encode()).hexdigest()


def dds_type_name(typename: str) -> str:
    """The DDS name of a ROS 2 type as rmw implementations spell it: ``geometry_msgs::msg::dds_::Twist_``."""
    package, kind, name = typename.split("/")
    return f"{package}::{kind}::dds_::{name}_"
