"""Mission benchmark: the whole stack (sim, mapper, planner, smoother, controller, viz) driving to a goal.

For each world and seed the shipped stack runs as real processes on an embedded router (``mjnav up``, headless), in
lockstep by default (the mission client is a participant, so each run is repeatable to the last bit), and the
robot drives from the world's start to its default goal on an unknown map. It prints, per run:

* the outcome, collisions and the minimum clearance (smallest lidar range − robot radius);
* time-to-goal (sim s) beside the bound 1.25 × optimal length / v_max, where the optimal length is the shortest
  collision-free path for the robot's radius on the true map;
* the real-time factor the stack achieved while the robot drove (sim s per wall s, start-up excluded);
* what each sim second costs in CPU over the drive: per process (from /proc: the sim, the container of the
  navigation services or each of them alone, viz, and the launcher that hosts the Zenoh router), per service (CPU
  of its step() calls, from its status; what it does in message callbacks counts only in its process) and for the
  whole stack (every process, the router included);
* the share of wall time the sim's lockstep barrier waited for the participants (from ``sim_status``).

Issue 29: ``--baseline DIR`` runs each mission first with another checkout (``git worktree add /tmp/base HEAD~5``,
its own ``benchmarks/mission.py``) and prints both side by side with the ratios, interleaved so that both see the
same machine; ``--process-per-service`` runs every service alone instead of the stack file's containers.

Goals (issue 10): every world × 5 seeds at ``--rtf max``: reached, 0 collisions, min clearance >= 0.05 m, time
ratio <= 1; the whole stack at >= 10x real time. Issue 13: the same runs navigate on SLAM with the sim's
``ground_truth`` off; ATE (SLAM's pose against the truth) <= 0.03 m, map accuracy >= 0.95 both ways; and the maze
with 3x the default odometry noise: reached, at least one loop closure, ATE <= 0.05 m. A loop closure needs a place
seen again: the default goal's route goes out and never looks back (nothing it sees was seen 10 m of driving
earlier), so that check drives a round trip, to the maze's goal and back to its start (``--round-trip``; it runs
after the worlds unless ``--no-noisy-maze``).

    python benchmarks/mission.py                              # every world with a goal, seeds 0-4, rtf max
    python benchmarks/mission.py --world warehouse --seeds 0,1 --rtf 4
    python benchmarks/mission.py --quick                      # rooms, seed 0
    python benchmarks/mission.py --world maze --round-trip --set sim.odom_noise_scale=3 --no-noisy-maze
    python benchmarks/mission.py --no-noisy-maze --baseline /tmp/base     # issue 29's figures
"""

from __future__ import annotations

import argparse
import json
import math
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

from mjnav.bus import Bus, BusConfig, wait_until
from mjnav.msgs import ros
from mjnav.runtime.mission import MissionClient
from mjnav.sim.truth import FootprintClearance, map_accuracy, shortest_length_m
from mjnav.sim.worlds import available_worlds, world_info

REPO = Path(__file__).resolve().parent.parent
SERVICES = ("sim", "slam", "mapper", "planner", "smoother", "controller", "viz")
#: Issue 13's noisy-odometry setting: 3x the sim's default wheel-odometry errors.
NOISY_MAZE = "sim.odom_noise_scale=3"
_TICKS = os.sysconf("SC_CLK_TCK")
#: The ``mjnav up`` process: the Zenoh router every message goes through, and the supervision.
LAUNCHER = "launcher (router)"
#: Services that step on wall time (their statuses' stamps are wall time): their steps are not counted per sim second.
WALL_TIME_SERVICES = ("sim", "viz")


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _cpu_s(pid: int) -> float:
    """CPU seconds (user + system) of a running process; NaN once it is gone (the launcher replaced it)."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return math.nan
    return (int(fields[11]) + int(fields[12])) / _TICKS  # utime + stime


def run_once(
    world: str,
    rtf: str,
    seed: int,
    free_running: bool = False,
    overrides: tuple[str, ...] = (),
    round_trip: bool = False,
    packed: bool = True,
) -> dict[str, Any]:
    """One mission at one real-time factor ("max" = as fast as the services allow); ``overrides``: extra
    ``service.key=value`` settings for ``mjnav up --set``; ``round_trip``: to the goal and back to the start (time,
    length and bound are the two legs' sums); ``packed``: the stack file's containers (False: a process per
    service)."""
    info = world_info(world)
    assert info.goal is not None, f"world {world} has no default goal"
    port = _free_port()
    participants = ["slam", "mapper", "planner", "smoother", "controller", "mission"]
    cmd = [sys.executable, "-m", "mjnav", "up", "--port", str(port), "--headless", "--seed", str(seed)]
    cmd += ["--set", f"sim.world={world}", "--set", f"sim.rtf={'0' if rtf == 'max' else rtf}"]
    cmd += ["--set", "sim.publish_ground_truth=false"]  # the stack navigates on SLAM; the truth is only evaluated
    cmd += [] if packed else ["--process-per-service"]
    for item in overrides:
        cmd += ["--set", item]
    cmd += ["--free-running"] if free_running else ["--set", f"sim.lockstep_participants={json.dumps(participants)}"]
    proc = subprocess.Popen(cmd, cwd=REPO, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        with Bus.open(BusConfig(mode="client", connect=(f"tcp/127.0.0.1:{port}",))) as bus:
            footprint = FootprintClearance(info.path)  # scoring: the robot's disc against the true static map
            client = MissionClient(bus, name="mission", clearance=footprint.clearance_m)
            status = bus.subscribe("status", service="*", immediate=True)  # wall-time reports, not staged
            sim_status = bus.subscribe("sim_status", immediate=True)
            if not wait_until(lambda: set(SERVICES) <= set(bus.alive_services(0.5)), 180.0):
                raise RuntimeError("the stack did not come up")
            if not wait_until(lambda: set(SERVICES) <= {s.service for s in status.latest_by_key().values()}, 30.0):
                raise RuntimeError("no status from every service")
            before = _Costs.now(status, sim_status, proc.pid)
            config = json.loads(bus.call("config", service="controller").data)
            goals = [(info.goal.x, info.goal.y)] + ([(info.start.x, info.start.y)] if round_trip else [])
            outcomes = client.run_goals(goals, timeout_s=300.0, wall_timeout_s=900.0)
            after = _Costs.now(status, sim_status, proc.pid)
            restarted = sorted(name for name, pid in before.pids.items() if after.pids.get(name) != pid)
            collisions = max(client.collisions(), client.overlaps())  # an overlap counts as a collision
            clearance = client.min_clearance_m()
            rtf_got = client.achieved_rtf
            ate = client.ate_rms_m()
            loops = int(json.loads(bus.call("slam_info", timeout_s=10.0).data)["loop_closures"])
            map_msg = client.final_map()
    finally:
        proc.send_signal(signal.SIGINT)
        proc.wait(60)
    reached = len(outcomes) == len(goals) and all(o.result == "reached" for o in outcomes)
    optimal = sum(shortest_length_m(world, o.start, o.goal) for o in outcomes)
    time_s = sum(o.time_s for o in outcomes)
    recall, precision = map_accuracy(info.path, *ros.grid_frame(map_msg)) if map_msg is not None else (0.0, 0.0)
    v_max = float(config["max_speed_mps"])
    bound = 1.25 * optimal / v_max
    return {
        "world": world,
        "seed": seed,
        "rtf_requested": rtf,
        "lockstep": not free_running,
        "packed": packed,
        "round_trip": round_trip,
        "result": "reached" if reached else outcomes[-1].result,
        "time_to_goal_s": time_s,
        "bound_s": bound,
        "time_ratio": time_s / bound,
        "driven_m": sum(o.path_length_m for o in outcomes),
        "optimal_m": optimal,
        "min_clearance_m": clearance,
        "rtf_achieved": rtf_got,
        "collisions": collisions,
        "ate_rms_m": ate,
        "loop_closures": loops,
        "map_accuracy": [recall, precision],
        **before.per_sim_second(after),
        "restarted": restarted,
    }


class _Costs:
    """What the stack has spent up to a moment: CPU per process (/proc), step CPU per service and the sim time of
    its newest status, the sim's time and its lockstep wait."""

    def __init__(
        self,
        pids: dict[str, int],
        processes: dict[str, int],
        step: dict[str, tuple[float, float, float]],
        sim: tuple[float, float],
        wall: float,
    ) -> None:
        self.pids = pids  # service -> pid
        self.cpu = {name: _cpu_s(pid) for name, pid in processes.items()}  # process -> CPU s
        self.step = step  # service -> (stamp, step CPU s, step wall s)
        self.sim = sim  # (sim time, lockstep wait s)
        self.wall = wall

    @classmethod
    def now(cls, status: Any, sim_status: Any, launcher_pid: int) -> _Costs:
        latest = {m.service: m for m in status.latest_by_key().values()}
        pids = {name: int(m.pid) for name, m in latest.items()}
        by_pid: dict[int, list[str]] = {}
        for name, pid in pids.items():
            by_pid.setdefault(pid, []).append(name)
        processes = {"+".join(names): pid for pid, names in by_pid.items()}
        processes[LAUNCHER] = launcher_pid
        step = {
            name: (ros.seconds(m.header.stamp), float(m.step_cpu_s), 1e-3 * float(m.step_mean_ms) * int(m.steps))
            for name, m in latest.items()
        }
        last = sim_status.latest()  # None before sim time starts (the mission client is a participant)
        sim = (ros.seconds(last.header.stamp), float(last.lockstep_wait_s)) if last is not None else (0.0, 0.0)
        return cls(pids, processes, step, sim, time.monotonic())

    def per_sim_second(self, end: _Costs) -> dict[str, Any]:
        """CPU milliseconds per sim second from here to ``end``, and the barrier's share of the wall time."""
        sim_s = end.sim[0] - self.sim[0]
        procs = {n: 1e3 * (end.cpu[n] - c) / sim_s for n, c in self.cpu.items() if n in end.cpu}
        steps, step_wall = {}, {}
        for name, (t0, c0, w0) in self.step.items():
            t1, c1, w1 = end.step.get(name, (t0, c0, w0))
            if t1 > t0 and name not in WALL_TIME_SERVICES:  # their statuses are stamped in wall time
                steps[name] = 1e3 * (c1 - c0) / (t1 - t0)
                step_wall[name] = 1e3 * (w1 - w0) / (t1 - t0)
        return {
            "cpu_ms_per_sim_s": procs,
            "stack_cpu_ms_per_sim_s": sum(v for v in procs.values() if math.isfinite(v)),
            "services_cpu_ms_per_sim_s": sum(v for n, v in procs.items() if math.isfinite(v) and n != LAUNCHER),
            "step_cpu_ms_per_sim_s": steps,
            "step_wall_ms_per_sim_s": step_wall,
            "barrier_wait_share": (end.sim[1] - self.sim[1]) / (end.wall - self.wall),
        }


def run_baseline(directory: Path, world: str, rtf: str, seed: int, args: argparse.Namespace) -> dict[str, Any]:
    """The same mission with the checkout in ``directory``, through its own benchmark script."""
    cmd = [sys.executable, "benchmarks/mission.py", "--world", world, "--seeds", str(seed), "--rtf", rtf, "--json"]
    cmd += ["--no-noisy-maze"] + (["--free-running"] if args.free_running else [])
    cmd += ["--round-trip"] if args.round_trip else []
    for item in args.set:
        cmd += ["--set", item]
    env = {**os.environ, "PYTHONPATH": str(directory)}
    out = subprocess.run(cmd, cwd=directory, env=env, capture_output=True, text=True, check=True, timeout=1800)
    (row,) = json.loads(out.stdout.strip().splitlines()[-1])
    if "services_cpu_ms_per_sim_s" not in row:  # an older script: CPU per wall second of each service process
        row["services_cpu_ms_per_sim_s"] = 1e3 * sum(row["cpu_share"].values()) / row["rtf_achieved"]
    return row


def _verdict(r: dict[str, Any]) -> bool:
    """Issue 10's goal for one run: reached, no collision, clearance >= 5 cm, time within the bound."""
    clearance = float(r["min_clearance_m"])
    return (
        r["result"] == "reached"
        and r["collisions"] == 0
        and not r["restarted"]
        and (clearance >= 0.05 or math.isnan(clearance))  # NaN: no obstacle in the world
        and float(r["time_ratio"]) <= 1.0
    )


def _slam_verdict(r: dict[str, Any]) -> bool:
    """Issue 13's goal for one run: reached, no collision, ATE <= 3 cm, map accuracy >= 0.95 both ways."""
    acc = r["map_accuracy"]
    return (
        r["result"] == "reached"
        and r["collisions"] == 0
        and float(r["ate_rms_m"]) <= 0.03
        and all(a >= 0.95 or math.isnan(a) for a in acc)  # NaN: nothing to map
    )


def _noisy_loop_verdict(r: dict[str, Any]) -> bool:
    """Issue 13's goal for the maze at 3x odometry noise (and how any round trip is judged): reached, no collision,
    a loop closure, ATE <= 5 cm."""
    return (
        r["result"] == "reached"
        and r["collisions"] == 0
        and int(r["loop_closures"]) >= 1
        and float(r["ate_rms_m"]) <= 0.05
    )


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--world", help="one world (default: every bundled world with a default goal)")
    parser.add_argument("--seeds", default="0,1,2,3,4", help="comma-separated seeds (default 0,1,2,3,4)")
    parser.add_argument("--rtf", default="max", help="real-time factor: max (default) or a number")
    parser.add_argument("--free-running", action="store_true", help="sim on wall time instead of lockstep")
    parser.add_argument("--quick", action="store_true", help="rooms, seed 0 only")
    parser.add_argument("--round-trip", action="store_true", help="drive to the goal and back to the start")
    parser.add_argument(
        "--no-noisy-maze",
        action="store_true",
        help="skip the issue-13 check after the worlds (maze round trip at 3x odometry noise, same seeds)",
    )
    parser.add_argument(
        "--set", action="append", default=[], metavar="SERVICE.KEY=VALUE", help="a stack setting (repeatable)"
    )
    parser.add_argument(
        "--process-per-service",
        action="store_true",
        help="every service in a process of its own (default: the stack file's containers)",
    )
    parser.add_argument(
        "--baseline",
        metavar="DIR",
        type=Path,
        help="another checkout (e.g. 'git worktree add /tmp/base HEAD~5'): run each mission with it first, "
        "through its own benchmarks/mission.py, and print the ratios",
    )
    parser.add_argument("--json", action="store_true", help="print JSON")
    args = parser.parse_args()
    if args.quick:
        worlds, seeds = ["rooms"], [0]
    else:
        worlds = [args.world] if args.world else [w for w in available_worlds() if world_info(w).goal is not None]
        seeds = [int(s) for s in args.seeds.split(",") if s.strip()]
    rows = []
    base: list[dict[str, Any]] = []
    packed = not args.process_per_service
    for world in worlds:
        for seed in seeds:
            if args.baseline is not None:
                base.append(run_baseline(args.baseline, world, args.rtf, seed, args))
            rows.append(run_once(world, args.rtf, seed, args.free_running, tuple(args.set), args.round_trip, packed))
            if not args.json:
                _print_row(rows[-1])
                if base:
                    _print_versus(base[-1], rows[-1])
    noisy = []
    if not (args.quick or args.no_noisy_maze or args.free_running):
        for seed in seeds:
            noisy.append(run_once("maze", args.rtf, seed, False, (*args.set, NOISY_MAZE), round_trip=True))
            if not args.json:
                _print_row(noisy[-1])
    if args.json:
        print(json.dumps(rows + noisy))
        return 0
    rtfs = sorted(float(r["rtf_achieved"]) for r in rows)
    round_trips = noisy
    if args.round_trip:  # issue 10's time goal is for one goal from the start; a round trip is judged as below
        round_trips = rows + noisy
    else:
        ok = [r for r in rows if _verdict(r)]
        print(
            f"goal: reached, 0 collisions, clearance >= 0.05 m, time ratio <= 1: {len(ok)}/{len(rows)} runs "
            f"{'met' if len(ok) == len(rows) else 'NOT met'}"
        )
    slam_ok = [r for r in rows if _slam_verdict(r)]
    print(
        f"goal: on SLAM with ground truth off, reached, 0 collisions, ATE <= 0.03 m, map accuracy >= 0.95: "
        f"{len(slam_ok)}/{len(rows)} runs {'met' if len(slam_ok) == len(rows) else 'NOT met'}"
    )
    if round_trips:
        ok3 = [r for r in round_trips if _noisy_loop_verdict(r)]
        print(
            f"goal (issue 13's loop closure; the noisy maze's at 3x odometry noise): round trip reached, "
            f"0 collisions, >= 1 loop closure, ATE <= 0.05 m: "
            f"{len(ok3)}/{len(round_trips)} runs {'met' if len(ok3) == len(round_trips) else 'NOT met'}"
        )
    median = rtfs[len(rtfs) // 2]
    cpu = sorted(float(r["stack_cpu_ms_per_sim_s"]) for r in rows)
    waits = sorted(float(r["barrier_wait_share"]) for r in rows)
    print(
        f"goal (issue 29): stack >= 15x real time (median), >= 10x (min): median {median:.1f}x (min {rtfs[0]:.1f}x) "
        f"{'met' if median >= 15 and rtfs[0] >= 10 else 'NOT met'}; CPU per sim second <= 60 ms: median "
        f"{cpu[len(cpu) // 2]:.0f} ms (max {cpu[-1]:.0f} ms, router included) "
        f"{'met' if cpu[-1] <= 60 else 'NOT met'}; the barrier waits {100 * waits[len(waits) // 2]:.0f} % of the "
        f"wall time (median)"
    )
    if base:
        ratio = sorted(float(r["rtf_achieved"]) / float(b["rtf_achieved"]) for r, b in zip(rows, base, strict=True))
        cpu_ratio = sorted(
            float(r["services_cpu_ms_per_sim_s"]) / float(b["services_cpu_ms_per_sim_s"])
            for r, b in zip(rows, base, strict=True)
        )
        base_rtf = sorted(float(b["rtf_achieved"]) for b in base)
        print(
            f"versus {args.baseline} (interleaved): real-time factor median {base_rtf[len(base_rtf) // 2]:.1f}x -> "
            f"{median:.1f}x, ratio median {ratio[len(ratio) // 2]:.2f} (min {ratio[0]:.2f}); services' CPU per sim "
            f"second ratio median {cpu_ratio[len(cpu_ratio) // 2]:.2f}"
        )
    return 0


def _print_versus(b: dict[str, Any], r: dict[str, Any]) -> None:
    print(
        f"    baseline: {b['result']} t {float(b['time_to_goal_s']):.2f} s rtf {float(b['rtf_achieved']):.1f}x "
        f"services CPU {float(b['services_cpu_ms_per_sim_s']):.0f} ms/sim s -> this: rtf x"
        f"{float(r['rtf_achieved']) / float(b['rtf_achieved']):.2f}, CPU x"
        f"{float(r['services_cpu_ms_per_sim_s']) / float(b['services_cpu_ms_per_sim_s']):.2f}",
        flush=True,
    )


def _print_row(r: dict[str, Any]) -> None:
    cpu = "  ".join(f"{k} {v:.0f}" for k, v in r["cpu_ms_per_sim_s"].items())
    walls = r.get("step_wall_ms_per_sim_s", {})
    steps = "  ".join(f"{k} {v:.1f} ({walls.get(k, math.nan):.1f} wall)" for k, v in r["step_cpu_ms_per_sim_s"].items())
    recall, precision = (float(a) for a in r["map_accuracy"])
    restarted = r["restarted"]
    if r["round_trip"]:  # the time bound is issue 10's for single goals: a round trip is judged on its loops
        verdict = f"loop goal {'ok' if _noisy_loop_verdict(r) else 'FAIL'}"
    else:
        verdict = "ok" if _verdict(r) else "FAIL"
    print(
        f"{r['world']:>9s}{' (round trip)' if r['round_trip'] else ''} seed {r['seed']} rtf {r['rtf_requested']}: "
        f"{r['result']:>8s} coll {r['collisions']} "
        f"clear {r['min_clearance_m']:.3f} m  t {r['time_to_goal_s']:.2f}/{r['bound_s']:.1f} s "
        f"(ratio {r['time_ratio']:.2f})  rtf {r['rtf_achieved']:.1f}x  {verdict}  "
        f"ATE {r['ate_rms_m']:.4f} m  loops {r['loop_closures']}  map {recall:.3f}/"
        f"{precision:.3f} {'ok' if _slam_verdict(r) else 'FAIL'}\n"
        f"    CPU ms per sim s: stack {float(r['stack_cpu_ms_per_sim_s']):.0f} = {cpu}; in steps: {steps}; "
        f"barrier waits {100 * float(r['barrier_wait_share']):.0f} % of wall time"
        + (f"  RESTARTED: {', '.join(restarted)}" if restarted else ""),
        flush=True,
    )


if __name__ == "__main__":
    sys.exit(main())
