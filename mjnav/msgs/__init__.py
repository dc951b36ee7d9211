"""Messages on the wire: ROS 2 types in CDR (via the rosbags typestore), the project's own .msg types, and the
topic table that names every key.
"""

from mjnav.msgs.codec import (
    MessageError,
    UnknownMessageType,
    decode,
    encode,
    from_dict,
    message_definition,
    msg_class,
    to_dict,
    typestore,
)
from mjnav.msgs.topics import (
    DEFAULT_NAMESPACE,
    ENDPOINTS,
    TOPICS,
    Endpoint,
    Kind,
    Topic,
    alive_key,
    endpoint,
    lockstep_key,
    resolve_key,
    topic,
)
from mjnav.msgs.validate import validate

__all__ = [
    "DEFAULT_NAMESPACE",
    "ENDPOINTS",
    "TOPICS",
    "Endpoint",
    "Kind",
    "MessageError",
    "Topic",
    "UnknownMessageType",
    "alive_key",
    "decode",
    "encode",
    "endpoint",
    "from_dict",
    "lockstep_key",
    "message_definition",
    "msg_class",
    "resolve_key",
    "to_dict",
    "topic",
    "typestore",
    "validate",
]
