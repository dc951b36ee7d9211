"""Bus benchmark: a 360-range LaserScan through mjnav's codec + bus vs raw Zenoh bytes of the same size.

Three variants: ``raw`` (plain Zenoh, the same publisher options, bytes in and out), ``mjnav`` (the bus: compiled
CDR codec, validation, delivery), and ``mjnav_rosbags`` (the same bus with rosbags' serialisers in place of the
compiled codecs of ``mjnav.msgs.cdr``: the end-to-end figure that module is kept for). Publisher in a child process,
subscriber here (two processes, like two services), over the same in-process router on loopback, each variant on a
namespace of its own.

Latency is one-way, publish call → subscriber callback with the decoded message, from CLOCK_MONOTONIC stamps carried
in the payload (the header stamp for the bus, the first 8 bytes after the header for raw). The variants are
interleaved message by message (raw, mjnav, mjnav_rosbags, raw, …; each at 500 Hz), so that the load of a shared
machine, which changes from second to second, hits them alike: the ratios compare messages sent within the same
2 ms. Throughput is the rate at which the subscriber receives when the publisher sends one variant as fast as it can.

    python benchmarks/bus.py            # 3 × 3,000 latency samples per variant, 50,000 throughput messages each
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
from collections.abc import Callable
from typing import Any

import numpy as np

from mjnav.bus import Bus, BusConfig, cdr_encoding
from mjnav.bus.bus import publisher_qos
from mjnav.msgs import codec, encode, from_dict, ros, topic

BEAMS = 360
SCAN = "sensor_msgs/msg/LaserScan"
#: Variants: raw Zenoh, the bus, the bus with rosbags' codec instead of the compiled one.
VARIANTS = ("raw", "mjnav", "mjnav_rosbags")
LABELS = {"raw": "raw zenoh", "mjnav": "mjnav bus", "mjnav_rosbags": "bus+rosbags"}
#: Latency runs send every variant in turn (``--variant interleaved``).
INTERLEAVED = "interleaved"


def _scan() -> Any:
    """A 360-beam scan with realistic ranges (its header is restamped per message)."""
    return from_dict(
        SCAN,
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


def _variant_bus(bus: Bus, variant: str) -> Bus:
    """A bus on ``bus``'s session in the variant's own namespace (``bench_raw/scan`` …)."""
    return Bus(bus.session, f"bench_{variant}")


def _sender(bus: Bus, variant: str) -> Callable[[], None]:
    """A function that publishes one scan of ``variant``, stamped with CLOCK_MONOTONIC when it is called."""
    vbus = _variant_bus(bus, variant)
    if variant == "raw":
        # Plain Zenoh with the same options as mjnav's snapshot publisher: only the codec and bus differ.
        raw = bus.session.declare_publisher(
            vbus.key("scan"), encoding=cdr_encoding(SCAN), **publisher_qos(topic("scan"))
        )
        payload = bytearray(encode(_scan()))

        def send_raw() -> None:
            struct.pack_into("<d", payload, 8, time.monotonic())
            raw.put(bytes(payload))

        time.sleep(0.5)  # raw Zenoh has no matching wait here: give discovery a moment
        return send_raw
    pub = vbus.publisher("scan")
    if variant == "mjnav_rosbags":
        pub._encode = codec.rosbags_encoder(SCAN)
    pub.wait_for_subscribers(10.0)
    template = _scan()
    stamp = template.header.stamp

    def send_msg() -> None:
        # Restamp in place, as the raw variant rewrites its payload in place: the figure is the bus's cost.
        stamp.sec, stamp.nanosec = divmod(round(time.monotonic() * 1e9), 1_000_000_000)
        pub.put(template)

    return send_msg


def _receiver(bus: Bus, variant: str, sink: Callable[[float, float], None]) -> None:
    """Subscribe to ``variant``'s scans; ``sink(latency_s, arrival)`` for each."""
    vbus = _variant_bus(bus, variant)
    if variant == "raw":

        def on_sample(sample: Any) -> None:
            data = sample.payload.to_bytes()
            now = time.monotonic()
            sink(now - struct.unpack_from("<d", data, 8)[0], now)

        bus.session.declare_subscriber(vbus.key("scan"), on_sample)
        return

    def on_msg(msg: Any) -> None:
        now = time.monotonic()
        sink(now - ros.seconds(msg.header.stamp), now)

    sub = vbus.subscribe("scan", callback=on_msg)
    if variant == "mjnav_rosbags":
        sub._decode = codec.rosbags_decoder(SCAN)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def publisher(endpoint: str, variant: str, count: int, rate_hz: float) -> None:
    """Child process: publish ``count`` scans of ``variant`` (or of every variant in turn: ``interleaved``)."""
    period = 1.0 / rate_hz if rate_hz > 0 else 0.0
    bus = Bus.open(BusConfig(connect=(endpoint,)))
    try:
        variants = VARIANTS if variant == INTERLEAVED else (variant,)
        senders = [_sender(bus, v) for v in variants]
        start = time.perf_counter()
        for i in range(count):
            for k, send in enumerate(senders):
                if period:
                    delay = start + (i + k / len(senders)) * period - time.perf_counter()
                    if delay > 0:
                        time.sleep(delay)
                send()
        time.sleep(0.2)
    finally:
        bus.close()


def measure(endpoint: str, variant: str, count: int, rate_hz: float) -> dict[str, dict[str, float]]:
    """Run one publisher child and collect what arrives here: figures per variant."""
    variants = VARIANTS if variant == INTERLEAVED else (variant,)
    latencies: dict[str, list[float]] = {v: [] for v in variants}
    arrivals: dict[str, list[float]] = {v: [] for v in variants}
    lock = threading.Lock()
    bus = Bus.open(BusConfig(connect=(endpoint,)))
    try:
        for v in variants:

            def sink(latency: float, now: float, v: str = v) -> None:
                with lock:
                    latencies[v].append(latency)
                    arrivals[v].append(now)

            _receiver(bus, v, sink)
        args = ["--role", "publisher", "--endpoint", endpoint, "--variant", variant]
        subprocess.run([sys.executable, __file__, *args, "--count", str(count), "--rate", str(rate_hz)], check=True)
        quiet_since = time.monotonic()
        seen = -1
        while time.monotonic() - quiet_since < 0.3:  # drain what is still in flight
            with lock:
                n = sum(len(a) for a in arrivals.values())
            if n != seen:
                seen, quiet_since = n, time.monotonic()
            time.sleep(0.02)
    finally:
        bus.close()
    out = {}
    for v in variants:
        lat = np.array(latencies[v][min(200, len(latencies[v]) // 10) :]) * 1e6
        got = arrivals[v]
        span = got[-1] - got[0] if len(got) > 1 else float("nan")
        out[v] = {
            "received": len(got),
            "sent": count,
            "p50_us": float(np.percentile(lat, 50)) if lat.size else float("nan"),
            "p99_us": float(np.percentile(lat, 99)) if lat.size else float("nan"),
            "rate_per_s": (len(got) - 1) / span if span > 0 else float("nan"),
        }
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true", help="fewer messages (for make bench)")
    parser.add_argument("--json", action="store_true", help="print results as JSON")
    parser.add_argument("--repeat", type=int, default=3, help="interleaved latency runs (default 3)")
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
        for _ in range(args.repeat):
            for variant, figures in measure(endpoint, INTERLEAVED, lat_n, 500.0).items():
                runs[variant].append(figures)
        for variant in VARIANTS:
            latency = {k: float(np.median([r[k] for r in runs[variant]])) for k in runs[variant][0]}
            results[variant] = {"latency": latency, "throughput": measure(endpoint, variant, thr_n, 0.0)[variant]}
    finally:
        router.close()
    size = len(encode(_scan()))
    ratios = {v: [m["p50_us"] / r["p50_us"] for r, m in zip(runs["raw"], runs[v], strict=True)] for v in VARIANTS[1:]}
    if args.json:
        print(json.dumps({"payload_bytes": size, "p50_ratio_per_repeat": ratios, **results}))
        return 0
    print(f"LaserScan, {BEAMS} ranges, {size} bytes; publisher and subscriber in separate processes via a router")
    print(f"latency: median of {args.repeat} runs of {lat_n} messages per variant at 500 Hz, variants interleaved")
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
