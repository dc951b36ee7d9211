"""Start-up benchmark: how long ``mjnav up`` takes to bring every service up, and ``mjnav demo`` to move the robot.

Each run starts a fresh process, as a user does, with warm numba caches (``mjnav warmup`` first; ``make setup`` does
that once at install):

* time-to-healthy: from starting ``mjnav up --headless`` until the launcher reports every service's liveliness
  token up (its line ``all N service(s) alive``); the time each service reported itself active is printed beside
  it, so the slowest one is named, and the CPU seconds the launcher and its services had used by then (on a
  shared machine the wall time grows with the load; the CPU seconds hardly do);
* time-to-motion: from starting ``mjnav demo --headless`` until the robot moves (the sim's ``odom`` reports a
  forward or turn speed above 0.02 m/s or 0.05 rad/s; this client subscribes on the demo's router).

Goals (issue 17): median time-to-healthy <= 2 s, median time-to-motion <= 3 s. The machine's load is printed: on a
shared machine both times grow with it.

    python benchmarks/startup.py                # 5 runs of each
    python benchmarks/startup.py --runs 3 --json
    python benchmarks/startup.py --quick        # 1 run of each (make bench)
    python benchmarks/startup.py --repo ../other-checkout --skip-warmup   # another checkout's mjnav, same way
"""

from __future__ import annotations

import argparse
import json
import os
import re
import signal
import socket
import statistics
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

from mjnav.bus import Bus, BusConfig, BusUnavailable

REPO = Path(__file__).resolve().parent.parent
GOAL_HEALTHY_S = 2.0
GOAL_MOTION_S = 3.0
#: The robot moves: odom's forward speed (m/s) or turn rate (rad/s) above these.
MOVING_MPS = 0.02
MOVING_RADPS = 0.05
#: Wall seconds a run may take before it counts as failed.
RUN_TIMEOUT_S = 120.0
_ALL_ALIVE = re.compile(r"all (\d+) service\(s\) alive")
_ACTIVE = re.compile(r"^\[(\w+)\] .*: active: ")
_TICKS = os.sysconf("SC_CLK_TCK")


def _tree_cpu_s(root: int) -> float:
    """CPU seconds (user + system) used so far by process ``root`` and its running descendants (/proc)."""
    parents: dict[int, int] = {}
    cpu: dict[int, float] = {}
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            fields = (entry / "stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue  # gone meanwhile
        parents[int(entry.name)] = int(fields[1])
        cpu[int(entry.name)] = (int(fields[11]) + int(fields[12])) / _TICKS
    tree, frontier = {root}, [root]
    while frontier:
        pid = frontier.pop()
        kids = [p for p, parent in parents.items() if parent == pid and p not in tree]
        tree.update(kids)
        frontier += kids
    return sum(cpu.get(pid, 0.0) for pid in tree)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _stop(proc: subprocess.Popen[str]) -> None:
    """Stop a launcher (SIGINT: it stops its services in order) and wait for it."""
    if proc.poll() is None:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(30.0)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


def _env(repo: Path) -> dict[str, str]:
    return {**os.environ, "PYTHONPATH": str(repo)}


def time_to_healthy(repo: Path, world: str) -> dict[str, Any]:
    """One ``mjnav up``: seconds until every service is alive (and the CPU seconds used by then), and until each
    reported itself active."""
    port = _free_port()
    cmd = [sys.executable, "-m", "mjnav", "up", "--headless", "--port", str(port), "--world", world]
    t0 = time.monotonic()
    proc = subprocess.Popen(
        cmd, cwd=repo, env=_env(repo), stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, bufsize=1
    )
    active: dict[str, float] = {}
    healthy = cpu = None
    try:
        assert proc.stdout is not None
        deadline = t0 + RUN_TIMEOUT_S
        for line in proc.stdout:
            now = time.monotonic() - t0
            if (m := _ACTIVE.search(line)) is not None:
                active.setdefault(m.group(1), now)
            if _ALL_ALIVE.search(line):
                healthy = now
                cpu = _tree_cpu_s(proc.pid)
                break
            if time.monotonic() > deadline:
                break
    finally:
        _stop(proc)
    return {"healthy_s": healthy, "cpu_s": cpu, "active_s": active}


def time_to_motion(repo: Path, world: str) -> dict[str, Any]:
    """One ``mjnav demo``: seconds until the sim's odometry says the robot moves."""
    port = _free_port()
    cmd = [sys.executable, "-m", "mjnav", "demo", "--headless", "--port", str(port), "--world", world]
    t0 = time.monotonic()
    proc = subprocess.Popen(
        cmd, cwd=repo, env=_env(repo), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, text=True
    )
    moved = threading.Event()
    motion: list[float] = []

    def on_odom(msg: Any) -> None:
        twist = msg.twist.twist
        if not moved.is_set() and (abs(twist.linear.x) > MOVING_MPS or abs(twist.angular.z) > MOVING_RADPS):
            motion.append(time.monotonic() - t0)
            moved.set()

    try:
        bus = None
        while bus is None and proc.poll() is None and time.monotonic() - t0 < RUN_TIMEOUT_S:
            try:
                bus = Bus.open(BusConfig(mode="client", connect=(f"tcp/127.0.0.1:{port}",), connect_timeout_s=1.0))
            except BusUnavailable:
                continue  # the demo's router is not listening yet
        if bus is not None:
            with bus:
                bus.subscribe("odom", callback=on_odom, immediate=True)
                moved.wait(max(0.0, RUN_TIMEOUT_S - (time.monotonic() - t0)))
    finally:
        _stop(proc)
    return {"motion_s": motion[0] if motion else None}


def _median(values: list[float | None]) -> float | None:
    done = [v for v in values if v is not None]
    return statistics.median(done) if len(done) == len(values) and done else None


def _verdict(value: float | None, goal: float) -> str:
    if value is None:
        return "FAILED (a run did not get there)"
    return f"{'meets' if value <= goal else 'misses'} the goal of <= {goal:.1f} s ({value / goal:.2f}x the goal)"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--runs", type=int, default=5, help="runs of each measurement (default 5)")
    parser.add_argument("--world", default="rooms", help="the sim's world (default rooms)")
    parser.add_argument("--quick", action="store_true", help="one run of each (for make bench)")
    parser.add_argument("--skip-warmup", action="store_true", help="do not run 'mjnav warmup' first")
    parser.add_argument("--json", action="store_true", help="print the results as JSON")
    parser.add_argument("--repo", type=Path, default=REPO, help="checkout whose mjnav runs (default this one)")
    args = parser.parse_args()
    runs = 1 if args.quick else args.runs
    if runs < 1:
        parser.error("--runs must be >= 1")
    repo = args.repo.resolve()
    if not args.skip_warmup:
        subprocess.run([sys.executable, "-m", "mjnav", "warmup", "--quiet"], cwd=repo, env=_env(repo), check=True)
    load = os.getloadavg()[0]
    healthy, motion = [], []
    for i in range(runs):
        h = time_to_healthy(repo, args.world)
        m = time_to_motion(repo, args.world)
        healthy.append(h)
        motion.append(m)
        order = sorted(h["active_s"].items(), key=lambda kv: kv[1])
        active = ", ".join(f"{name} {t:.2f}" for name, t in order)
        h_s = "-" if h["healthy_s"] is None else f"{h['healthy_s']:.2f} s, {h['cpu_s']:.1f} CPU s"
        m_s = "-" if m["motion_s"] is None else f"{m['motion_s']:.2f}"
        if not args.json:
            print(f"run {i + 1}: healthy {h_s} (active at: {active}); motion {m_s} s", flush=True)
    med_h = _median([h["healthy_s"] for h in healthy])
    med_m = _median([m["motion_s"] for m in motion])
    med_cpu = _median([h["cpu_s"] for h in healthy])
    result = {
        "repo": str(repo),
        "world": args.world,
        "runs": runs,
        "load_1min": round(load, 2),
        "cpus": os.cpu_count(),
        "healthy_s": [h["healthy_s"] for h in healthy],
        "motion_s": [m["motion_s"] for m in motion],
        "median_healthy_s": med_h,
        "median_motion_s": med_m,
        "healthy_cpu_s": [h["cpu_s"] for h in healthy],
        "median_healthy_cpu_s": med_cpu,
        "goal_healthy_s": GOAL_HEALTHY_S,
        "goal_motion_s": GOAL_MOTION_S,
    }
    if args.json:
        print(json.dumps(result))
    else:
        print(f"{repo}: load average {load:.2f} on {os.cpu_count()} CPUs; world {args.world}; median of {runs} run(s)")
        h_text = "-" if med_h is None else f"{med_h:.2f} s"
        print(f"time-to-healthy (mjnav up): {h_text}: {_verdict(med_h, GOAL_HEALTHY_S)}")
        print(f"CPU used by then (launcher + services): {'-' if med_cpu is None else f'{med_cpu:.1f} s'}")
        m_text = "-" if med_m is None else f"{med_m:.2f} s"
        print(f"time-to-motion (mjnav demo): {m_text}: {_verdict(med_m, GOAL_MOTION_S)}")
    return 0 if med_h is not None and med_m is not None else 1


if __name__ == "__main__":
    sys.exit(main())
