"""Bus benchmark: a 360-range LaserScan through mjnav's codec + bus vs raw Zenoh bytes of the same size.

A third variant, ``mjnav (rosbags codec)``, runs the same bus with rosbags' serialisers in place of the compiled
codecs of ``mjnav.msgs.cdr``: the end-to-end figure that module is kept for.

Both run in the same invocation, over the same in-process router on loopback, publisher in a child process and
subscriber here (two processes, like two services). Latency is one-way, publish call → subscriber callback with the
decoded message, from CLOCK_MONOTONIC stamps carried in the payload (the header stamp for mjnav, the first 8 bytes
for raw). Throughput is the rate at which the subscriber receives when the publisher sends as fast as it can.

    python benchmarks/bus.py            # 3 × 3,000 latency samples, 50,000 throughput messages per variant
    python benchmarks/bus.py --quick
"""

from __future__ import annotations

import argparse
import json
import socket
import struct
import subprocess
import sys
import threading
import time
from typing import Any

import numpy as np

from mjnav.bus import Bus, BusConfig, cdr_encoding
from mjnav.bus.bus import publisher_qos
from mjnav.msgs import codec, encode, from_dict, ros, topic

BEAMS = 360
#: Variants in the order they run: raw Zenoh, the bus, the bus with rosbags' codec instead of the compiled one.
VARIANTS = ("raw", "mjnav", "mjnav_rosbags")
LABELS = {"raw": "raw zenoh", "mjnav": "mjnav bus", "mjnav_rosbags": "bus+rosbags"}


def _use_variant_codec(variant: str) -> None:
    """For ``mjnav_rosbags``: make every publisher and subscription of this process use rosbags' codec."""
    if variant == "mjnav_rosbags":
        setattr(codec, "encoder", codec.rosbags_encoder)  # noqa: B010 (replaces the module function on purpose)
        setattr(codec, "decoder", codec.rosbags_decoder)  # noqa: B010


def _scan() -> Any:
    """A 360-beam scan with realistic ranges (its header is restamped per message)."""
    return from_dict(
        "sensor_msgs/msg/LaserScan",
        {
            "header": {"frame_id": "laser"},
            "angle_min": -np.pi,
            "angle_max": np.pi,
            "angle_increment": 2 * np.pi / BEAMS,
            "scan_time": 0.1,
            "range_min": 0.05,
            "range_max": 12.0,
            "ranges": np.linspace(0.5, 11.0, BEAMS).astype(np.float32).tolist(),
        },
    )


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def publisher(endpoint: str, variant: str, count: int, rate_hz: float) -> None:
    """Child process: publish ``count`` scans (mjnav) or same-size byte payloads (raw)."""
    template = _scan()
    stamp = template.header.stamp
    period = 1.0 / rate_hz if rate_hz > 0 else 0.0
    _use_variant_codec(variant)
    bus = Bus.open(BusConfig(connect=(endpoint,)))
    try:
        if variant != "raw":
            pub = bus.publisher("scan")
            pub.wait_for_subscribers(10.0)
            put = None
        else:
            # Plain Zenoh with the same options as mjnav's snapshot publisher: only the codec and bus differ.
            raw = bus.session.declare_publisher(
                bus.key("scan"),
                encoding=cdr_encoding("sensor_msgs/msg/LaserScan"),
                **publisher_qos(topic("scan")),
            )
            payload = bytearray(encode(template))
            put = raw.put
            time.sleep(0.5)  # raw Zenoh has no matching wait here: give discovery a moment
        start = time.perf_counter()
        for i in range(count):
            if period:
                delay = start + i * period - time.perf_counter()
                if delay > 0:
                    time.sleep(delay)
            now = time.monotonic()
            if put is None:
                # Restamp in place, as the raw variant rewrites its payload in place: the figure is the bus's cost.
                stamp.sec, stamp.nanosec = divmod(round(now * 1e9), 1_000_000_000)
                pub.put(template)
            else:
                struct.pack_into("<d", payload, 8, now)
                put(bytes(payload))
        time.sleep(0.2)
    finally:
        bus.close()


def measure(endpoint: str, variant: str, count: int, rate_hz: float) -> dict[str, float]:
    """Run one publisher child and collect what arrives here."""
    latencies: list[float] = []
    arrivals: list[float] = []
    lock = threading.Lock()
    bus = Bus.open(BusConfig(connect=(endpoint,)))
    try:
        if variant != "raw":

            def on_msg(msg: Any) -> None:
                now = time.monotonic()
                with lock:
                    latencies.append(now - ros.seconds(msg.header.stamp))
                    arrivals.append(now)

            bus.subscribe("scan", callback=on_msg)
        else:

            def on_sample(sample: Any) -> None:
                data = sample.payload.to_bytes()
                now = time.monotonic()
                with lock:
                    latencies.append(now - struct.unpack_from("<d", data, 8)[0])
                    arrivals.append(now)

            bus.session.declare_subscriber(bus.key("scan"), on_sample)
        child = subprocess.run(
            [
                sys.executable,
                __file__,
                "--role",
                "publisher",
                "--endpoint",
                endpoint,
                "--variant",
                variant,
                "--count",
                str(count),
                "--rate",
                str(rate_hz),
            ],
            check=True,
        )
        del child
        quiet_since = time.monotonic()
        seen = -1
        while time.monotonic() - quiet_since < 0.3:  # drain what is still in flight
            with lock:
                n = len(arrivals)
            if n != seen:
                seen, quiet_since = n, time.monotonic()
            time.sleep(0.02)
    finally:
        bus.close()
    lat = np.array(latencies[min(200, len(latencies) // 10) :]) * 1e6
    span = arrivals[-1] - arrivals[0] if len(arrivals) > 1 else float("nan")
    return {
        "received": len(arrivals),
        "sent": count,
        "p50_us": float(np.percentile(lat, 50)) if lat.size else float("nan"),
        "p99_us": float(np.percentile(lat, 99)) if lat.size else float("nan"),
        "rate_per_s": (len(arrivals) - 1) / span if span > 0 else float("nan"),
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true", help="fewer messages (for make bench)")
    parser.add_argument("--json", action="store_true", help="print results as JSON")
    parser.add_argument("--repeat", type=int, default=3, help="alternating latency runs per variant (default 3)")
    parser.add_argument("--role", default="main", help=argparse.SUPPRESS)
    parser.add_argument("--endpoint", help=argparse.SUPPRESS)
    parser.add_argument("--variant", help=argparse.SUPPRESS)
    parser.add_argument("--count", type=int, help=argparse.SUPPRESS)
    parser.add_argument("--rate", type=float, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.role == "publisher":
        publisher(args.endpoint, args.variant, args.count, args.rate)
        return 0

    lat_n, thr_n = (1000, 10_000) if args.quick else (3000, 50_000)
    endpoint = f"tcp/127.0.0.1:{_free_port()}"
    router = Bus.open(BusConfig(mode="router", connect=(), listen=(endpoint,)))
    runs: dict[str, list[dict[str, float]]] = {v: [] for v in VARIANTS}
    results: dict[str, dict[str, dict[str, float]]] = {}
    try:
        # Latency runs alternate between the variants so that drift on a shared machine hits all alike; the
        # figures are the medians over the repeats.
        for _ in range(args.repeat):
            for variant in VARIANTS:
                runs[variant].append(measure(endpoint, variant, lat_n, 500.0))
        for variant in VARIANTS:
            latency = {k: float(np.median([r[k] for r in runs[variant]])) for k in runs[variant][0]}
            results[variant] = {"latency": latency, "throughput": measure(endpoint, variant, thr_n, 0.0)}
    finally:
        router.close()
    size = len(encode(_scan()))
    ratios = {v: [m["p50_us"] / r["p50_us"] for r, m in zip(runs["raw"], runs[v], strict=True)] for v in VARIANTS[1:]}
    if args.json:
        print(json.dumps({"payload_bytes": size, "p50_ratio_per_repeat": ratios, **results}))
        return 0
    print(f"LaserScan, {BEAMS} ranges, {size} bytes; publisher and subscriber in separate processes via a router")
    print(f"latency: median of {args.repeat} alternating runs of {lat_n} messages at 500 Hz per variant")
    print(
        f"{'':24s}" + "".join(f" {LABELS[v]:>12s}" for v in VARIANTS) + "".join(f" {'ratio':>6s}" for _ in VARIANTS[1:])
    )
    for label, phase, key in (
        ("latency p50 (µs)", "latency", "p50_us"),
        ("latency p99 (µs)", "latency", "p99_us"),
        ("throughput (msg/s)", "throughput", "rate_per_s"),
    ):
        values = [results[v][phase][key] for v in VARIANTS]
        print(
            f"{label:24s}"
            + "".join(f" {x:12.1f}" for x in values)
            + "".join(f" {x / values[0]:6.2f}" for x in values[1:])
        )
    for variant in VARIANTS:
        r = results[variant]["throughput"]
        print(
            f"{variant}: received {r['received']} of {r['sent']} in the throughput run (snapshot topic: drops allowed)"
        )
    for variant in VARIANTS[1:]:
        print(f"p50 ratio per repeat, {LABELS[variant]}: " + ", ".join(f"{r:.2f}" for r in ratios[variant]))
    print("goal: latency <= 1.3x raw, >= 50,000 scans/s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
