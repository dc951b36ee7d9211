"""Laser scans with the wheel odometry at their time, read from a bag (the input of an offline SLAM run).

A bag recorded by ``mjnav record`` or ``mjnav demo --record`` holds ``<ns>/scan`` (sensor_msgs/LaserScan) and
``<ns>/odom`` (nav_msgs/Odometry). Each scan is paired with the odometry pose at its header stamp, linearly
interpolated between the two odometry messages around it (heading interpolated on the unwrapped angle); scans
before the first or after the last odometry message are dropped. Times are the messages' header stamps (sim time).
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from mjnav.bag.errors import BagError, BagFormatError
from mjnav.bag.keys import key_for_topic

__all__ = ["ScanLog", "read_scans"]

SCAN_TYPE = "sensor_msgs/msg/LaserScan"
ODOM_TYPE = "nav_msgs/msg/Odometry"


@dataclass(frozen=True, eq=False)
class ScanLog:
    """Scans of one namespace with the odometry at their stamps.

    Attributes:
        namespace: the namespace the keys were in (``robot0``).
        stamps: (S,) scan header stamps, seconds.
        odometry: (S, 3) ``base_link`` pose in ``odom`` (x, y, θ) at each scan's stamp.
        ranges: S (N,) float arrays of ranges, metres (REP-117 values as recorded).
        angles: S (N,) float arrays of beam angles in the laser frame, radians.
        range_min: (S,) sensor minimum ranges, metres.
        range_max: (S,) sensor maximum ranges, metres.
        dropped: scans without odometry around their stamp (not included).
    """

    namespace: str
    stamps: NDArray[np.float64]
    odometry: NDArray[np.float64]
    ranges: tuple[NDArray[np.float64], ...]
    angles: tuple[NDArray[np.float64], ...]
    range_min: NDArray[np.float64]
    range_max: NDArray[np.float64]
    dropped: int

    def __len__(self) -> int:
        return int(self.stamps.shape[0])


def _stamp(header: object) -> float:
    st = header.stamp  # type: ignore[attr-defined]
    return float(st.sec) + 1e-9 * float(st.nanosec)


def _messages(path: Path) -> Iterator[tuple[str, str, bytes]]:
    from mcap.exceptions import McapError
    from mcap.reader import make_reader

    try:
        with open(path, "rb") as f:
            reader = make_reader(f)
            for schema, channel, message in reader.iter_messages(log_time_order=True):
                if schema is None or schema.name not in (SCAN_TYPE, ODOM_TYPE):
                    continue
                key = channel.metadata.get("zenoh_key") or key_for_topic(channel.topic)
                yield key, schema.name, message.data
    except OSError as exc:
        raise BagError(f"cannot read {path}: {exc.strerror}") from exc
    except McapError as exc:
        raise BagFormatError(f"{path} is not a readable MCAP file: {exc}") from exc


def read_scans(path: str | Path, namespace: str | None = None) -> ScanLog:
    """Read the scans and odometry of one namespace from an MCAP bag.

    Args:
        path: the bag.
        namespace: which robot (``robot0``); default: the only namespace with both ``scan`` and ``odom``.

    Returns:
        :class:`ScanLog` in stamp order.

    Raises:
        BagError: unreadable file, no (or an ambiguous) namespace with scans and odometry, or no scan within the
            odometry's time span.
        BagFormatError: not an MCAP file, or an undecodable message.
    """
    from mjnav.geometry import quaternion_to_yaw
    from mjnav.msgs import MessageError, decode

    p = Path(path)
    scans: dict[str, list[tuple[float, NDArray[np.float64], NDArray[np.float64], float, float]]] = {}
    odoms: dict[str, list[tuple[float, float, float, float]]] = {}
    for key, typename, data in _messages(p):
        ns, _, name = key.rpartition("/")
        if (typename == SCAN_TYPE) != (name == "scan") or (typename == ODOM_TYPE) != (name == "odom"):
            continue
        try:
            msg = decode(data, typename)
        except MessageError as exc:
            raise BagFormatError(f"{p}: undecodable {typename} on {key}: {exc}") from exc
        if typename == SCAN_TYPE:
            r = np.asarray(msg.ranges, dtype=np.float64)
            a = float(msg.angle_min) + float(msg.angle_increment) * np.arange(r.size, dtype=np.float64)
            scans.setdefault(ns, []).append((_stamp(msg.header), r, a, float(msg.range_min), float(msg.range_max)))
        else:
            q = msg.pose.pose.orientation
            heading = quaternion_to_yaw(float(q.x), float(q.y), float(q.z), float(q.w))
            pos = msg.pose.pose.position
            odoms.setdefault(ns, []).append((_stamp(msg.header), float(pos.x), float(pos.y), heading))
    both = sorted(set(scans) & set(odoms))
    if namespace is None:
        if len(both) != 1:
            found = ", ".join(both) if both else "none"
            raise BagError(f"{p}: need exactly one namespace with scan and odom (found: {found}); pick one")
        namespace = both[0]
    if namespace not in both:
        raise BagError(f"{p}: namespace {namespace!r} has no scan and odom (namespaces with both: {both})")
    od = np.array(sorted(odoms[namespace]), dtype=np.float64)
    t_od = od[:, 0]
    od_yaw = np.unwrap(od[:, 3])
    rows = sorted(scans[namespace], key=lambda s: s[0])
    kept = [s for s in rows if t_od[0] <= s[0] <= t_od[-1]]
    if not kept:
        raise BagError(f"{p}: no scan of {namespace} lies within the odometry's time span")
    t = np.array([s[0] for s in kept])
    odom = np.column_stack((np.interp(t, t_od, od[:, 1]), np.interp(t, t_od, od[:, 2]), np.interp(t, t_od, od_yaw)))
    odom[:, 2] = np.remainder(odom[:, 2] + math.pi, 2.0 * math.pi) - math.pi
    return ScanLog(
        namespace=namespace,
        stamps=t,
        odometry=odom,
        ranges=tuple(s[1] for s in kept),
        angles=tuple(s[2] for s in kept),
        range_min=np.array([s[3] for s in kept]),
        range_max=np.array([s[4] for s in kept]),
        dropped=len(rows) - len(kept),
    )
