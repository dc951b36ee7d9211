"""Mission benchmark: the whole stack (sim, mapper, planner, smoother, controller) driving to a goal.

For each requested real-time factor the shipped stack runs as real processes on an embedded router (``mjnav up``),
the robot drives from the world's start to its goal on an unknown map, and this prints:

* time-to-goal (sim s) beside the bound 1.25 × optimal length / v_max (the goal), where the optimal length is
  the shortest collision-free path for the robot's radius on the true map;
* the real-time factor the stack achieved over the mission (sim s per wall s; goal >= 4);
* each service's CPU share over the mission (CPU seconds per wall second, from /proc; 2 cores = 200 %).

    python benchmarks/mission.py                 # rooms, rtf 4 and max
    python benchmarks/mission.py --world warehouse --rtf 4,8
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

from mjnav.bus import Bus, BusConfig, wait_until
from mjnav.runtime.mission import MissionClient
from mjnav.sim.truth import shortest_length_m
from mjnav.sim.worlds import world_info

REPO = Path(__file__).resolve().parent.parent
SERVICES = ("sim", "mapper", "planner", "smoother", "controller", "viz")
_TICKS = os.sysconf("SC_CLK_TCK")


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _cpu_s(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / _TICKS  # utime + stime


def run_once(world: str, rtf: str) -> dict[str, object]:
    """One mission at one real-time factor ("max" = as fast as possible)."""
    info = world_info(world)
    assert info.goal is not None, f"world {world} has no default goal"
    port = _free_port()
    sim_rtf = "0" if rtf == "max" else rtf
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "mjnav",
            "up",
            "--port",
            str(port),
            "--headless",
            "--set",
            f"sim.world={world}",
            "--set",
            f"sim.rtf={sim_rtf}",
        ],
        cwd=REPO,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    try:
        with Bus.open(BusConfig(connect=(f"tcp/127.0.0.1:{port}",))) as bus:
            client = MissionClient(bus)
            status = bus.subscribe("status", service="*")
            if not wait_until(lambda: set(SERVICES) <= set(bus.alive_services(0.5)), 180.0):
                raise RuntimeError("the stack did not come up")
            if not wait_until(lambda: set(SERVICES) <= {s.service for s in status.latest_by_key().values()}, 30.0):
                raise RuntimeError("no status from every service")
            pids = {s.service: int(s.pid) for s in status.latest_by_key().values()}
            config = json.loads(bus.call("config", service="controller").data)
            client.truth.wait(30.0)
            cpu0 = {name: _cpu_s(pid) for name, pid in pids.items()}
            wall0, sim0 = time.monotonic(), client.now()
            outcome = client.run_goal(info.goal.x, info.goal.y, timeout_s=300.0, wall_timeout_s=600.0)
            wall = time.monotonic() - wall0
            sim_s = client.now() - sim0
            cpu = {name: (_cpu_s(pid) - cpu0[name]) / wall for name, pid in pids.items()}
            collisions = client.collisions()
    finally:
        proc.send_signal(signal.SIGINT)
        proc.wait(60)
    optimal = shortest_length_m(world, outcome.start, outcome.goal)
    v_max = float(config["max_speed_mps"])
    bound = 1.25 * optimal / v_max
    return {
        "world": world,
        "rtf_requested": rtf,
        "result": outcome.result,
        "time_to_goal_s": outcome.time_s,
        "bound_s": bound,
        "time_ratio": outcome.time_s / bound,
        "driven_m": outcome.path_length_m,
        "optimal_m": optimal,
        "rtf_achieved": sim_s / wall,
        "collisions": collisions,
        "cpu_share": cpu,
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--world", default="rooms", help="world with a default goal (default rooms)")
    parser.add_argument("--rtf", default="4,max", help="comma-separated real-time factors (default 4,max)")
    parser.add_argument("--quick", action="store_true", help="only rtf 4")
    parser.add_argument("--json", action="store_true", help="print JSON")
    args = parser.parse_args()
    rtfs = ["4"] if args.quick else [r.strip() for r in args.rtf.split(",") if r.strip()]
    rows = [run_once(args.world, rtf) for rtf in rtfs]
    if args.json:
        print(json.dumps(rows))
        return 0
    print(f"world {args.world}: start → default goal on an unknown map, whole stack as processes")
    head = f"{'rtf':>5s} {'result':>8s} {'t goal s':>9s} {'bound s':>8s} {'ratio':>6s} {'rtf got':>8s} {'coll':>5s}"
    print(head + "  CPU share per service (CPU s / wall s)")
    for r in rows:
        cpu = "  ".join(f"{k} {100 * v:.0f}%" for k, v in r["cpu_share"].items())  # type: ignore[attr-defined]
        print(
            f"{r['rtf_requested']:>5s} {r['result']:>8s} {r['time_to_goal_s']:9.1f} {r['bound_s']:8.1f} "
            f"{r['time_ratio']:6.2f} {r['rtf_achieved']:8.2f} {r['collisions']:5d}  {cpu}"
        )
    print("goals: time-to-goal <= 1.25 x optimal / v_max (ratio <= 1), stack at >= 4x real time")
    return 0


if __name__ == "__main__":
    sys.exit(main())
