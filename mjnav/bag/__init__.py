"""Bags: record mjnav keys to MCAP (ROS 2 profile), replay them with their timing, summarise them.

* :func:`record` / :class:`BagWriter` — Zenoh samples → MCAP with ``ros2msg`` schemas and ``cdr`` messages, readable
  by Foxglove and ``mcap_ros2.reader.read_ros2_messages``.
* :func:`play` — MCAP → the bus, at the recorded log times scaled by a real-time factor.
* :func:`bag_info` / :func:`format_info` — what a bag holds.
"""

from mjnav.bag.errors import BagError, BagFormatError
from mjnav.bag.info import BagInfo, ChannelInfo, bag_info, format_info
from mjnav.bag.keys import key_expressions, key_for_topic, topic_for_key
from mjnav.bag.play import PlayStats, play
from mjnav.bag.record import COMPRESSIONS, BagWriter, RecordStats, record

__all__ = [
    "COMPRESSIONS",
    "BagError",
    "BagFormatError",
    "BagInfo",
    "BagWriter",
    "ChannelInfo",
    "PlayStats",
    "RecordStats",
    "bag_info",
    "format_info",
    "key_expressions",
    "key_for_topic",
    "play",
    "record",
    "topic_for_key",
]
