"""Benchmark: CPU seconds per sim second of every process of the UAV stack during a lockstep flight (Linux).

Wall-time real-time factors swing with whatever else runs on the machine; the CPU each process spends per second
of sim time does much less. This runs `mjnav fly … --rtf max` (every service a process, lockstep), samples the CPU
time of each process and of its threads (utime + stime from /proc, grouped by thread name: `python` is the
interpreter's threads, `rx`/`tx`/`acc`/`app`/`net` are Zenoh's runtime threads) and reports the CPU spent between
sim time starting (uav_sim's "sim time starts") and the flight controller disarming after the landing, divided by
the flight's sim time. The `fly` row is the command itself: the Zenoh router and the flight client.

Run: .venv/bin/python benchmarks/uav_cpu.py [--state ins|mocap] [--controller pid|rpt|lqr|hinf] [--runs N]
[--repo DIR] [--baseline DIR]
(--repo: the checkout whose `mjnav` runs, default this one; --baseline: another checkout, flown in turn with it —
interleaved, the order alternating run by run, so both see the same machine load — and compared: the medians of
both and their ratios are printed at the end.)
"""

from __future__ import annotations

import argparse
import collections
import json
import math
import os
import re
import socket
import statistics
import subprocess
import sys
import threading
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
TICK = os.sysconf("SC_CLK_TCK") if hasattr(os, "sysconf") else 100

Snapshot = dict[tuple[str, str], float]  # (process, thread group) -> CPU seconds; (process, WAKEUPS) -> count
#: The snapshot's key for the voluntary context switches of all threads of a process: how often its threads went to
#: sleep waiting for something (a message, the GIL, a lock) — the wake-ups a lockstep round's latency is made of.
WAKEUPS = "wakeups"


def free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _children(pid: int) -> list[int]:
    out: list[int] = []
    try:
        for tid in os.listdir(f"/proc/{pid}/task"):
            out += [int(x) for x in Path(f"/proc/{pid}/task/{tid}/children").read_text().split()]
    except OSError:
        pass
    return out


def snapshot(root: int) -> Snapshot:
    """CPU seconds of every thread group of ``root`` and its descendants, by service name."""
    snap: Snapshot = collections.defaultdict(float)
    stack = [root]
    while stack:
        pid = stack.pop()
        stack += _children(pid)
        try:
            argv = Path(f"/proc/{pid}/cmdline").read_text().split("\0")
            name = argv[argv.index("run") + 1] if "run" in argv else ("fly" if "fly" in argv else "")
            if not name:
                continue
            for tid in os.listdir(f"/proc/{pid}/task"):
                stat = Path(f"/proc/{pid}/task/{tid}/stat").read_text()
                comm = re.sub(r"[-/]?\d+$", "", stat[stat.index("(") + 1 : stat.rindex(")")])
                fields = stat.rsplit(")", 1)[1].split()
                snap[(name, comm)] += (int(fields[11]) + int(fields[12])) / TICK
                status = Path(f"/proc/{pid}/task/{tid}/status").read_text()
                switches = re.search(r"^voluntary_ctxt_switches:\s*(\d+)", status, re.MULTILINE)
                snap[(name, WAKEUPS)] += float(switches.group(1)) if switches else 0.0
        except (OSError, ValueError, IndexError):
            continue
    return snap


def fly(repo: Path, state: str, controller: str) -> tuple[dict[str, object], Snapshot, Snapshot]:
    """One figure-8; returns its summary and the CPU snapshots at sim-time start and at the landing."""
    cmd = [
        sys.executable, "-m", "mjnav", "fly", "--trajectory", "figure8", "--controller", controller, "--state", state,
        "--rtf", "max", "--json", "--headless", "--log-level", "INFO", "--port", str(free_port()),
    ]  # fmt: skip
    env = {k: v for k, v in os.environ.items() if not k.startswith("MJNAV_ZENOH_")}
    env["PYTHONPATH"] = str(repo)
    proc = subprocess.Popen(cmd, cwd=repo, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    marks: dict[str, Snapshot] = {}
    stdout: list[str] = []
    reader = threading.Thread(target=lambda: stdout.extend(proc.stdout or []), daemon=True)
    reader.start()
    for line in proc.stderr or []:
        if "start" not in marks and "sim time starts" in line:
            marks["start"] = snapshot(proc.pid)
        elif "end" not in marks and re.search(r"(landing|failsafe_land) -> disarmed", line):
            marks["end"] = snapshot(proc.pid)
    proc.wait(timeout=900)
    reader.join(10.0)
    if "start" not in marks or "end" not in marks or not stdout:
        raise RuntimeError(f"mjnav fly in {repo} did not fly to the end (exit {proc.returncode})")
    return json.loads(stdout[-1]), marks["start"], marks["end"]


def per_service(start: Snapshot, end: Snapshot, sim_s: float) -> tuple[dict[str, dict[str, float]], dict[str, float]]:
    """(ms of CPU per sim second per process and thread group, wake-ups per sim second per process) between the two
    snapshots."""
    per: dict[str, dict[str, float]] = collections.defaultdict(dict)
    wakeups: dict[str, float] = {}
    for key, value in end.items():
        if key[1] == WAKEUPS:
            wakeups[key[0]] = (value - start.get(key, 0.0)) / sim_s
        else:
            per[key[0]][key[1]] = 1e3 * (value - start.get(key, 0.0)) / sim_s
    return per, wakeups


def report(
    label: str, summary: dict[str, object], per: dict[str, dict[str, float]], wakeups: dict[str, float], load: float
) -> None:
    print(
        f"{label}: {summary['time_s']} s sim at {summary['achieved_rtf']}x real time, load average {load:.1f} "
        f"({os.cpu_count()} cores); RMS {summary['rms_error_m']} m, INS RMS {summary['ins_rms_m']} m"
    )
    for name in sorted(per):
        threads = ", ".join(f"{t} {c:.1f}" for t, c in sorted(per[name].items()) if c > 0.05)
        print(
            f"  {name:18s} {sum(per[name].values()):6.1f} ms CPU, {wakeups.get(name, 0.0):5.0f} wake-ups per sim s"
            f"  ({threads})"
        )
    print(
        f"  {'total':18s} {sum(sum(v.values()) for v in per.values()):6.1f} ms CPU, "
        f"{sum(wakeups.values()):5.0f} wake-ups per sim s"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--state", choices=("ins", "mocap"), default="ins")
    ap.add_argument("--controller", choices=("pid", "rpt", "lqr", "hinf"), default="rpt")
    ap.add_argument("--runs", type=int, default=1)
    ap.add_argument("--repo", type=Path, default=REPO, help="checkout whose mjnav runs (default this one)")
    ap.add_argument("--baseline", type=Path, help="another checkout flown in turn with --repo and compared")
    args = ap.parse_args()
    if not Path("/proc/self/task").is_dir():
        print("needs Linux /proc")
        return
    repos = {"this": args.repo.resolve()}
    if args.baseline is not None:
        repos["baseline"] = args.baseline.resolve()
    rtf: dict[str, list[float]] = collections.defaultdict(list)
    cpu: dict[str, dict[str, list[float]]] = {label: collections.defaultdict(list) for label in repos}
    woken: dict[str, dict[str, list[float]]] = {label: collections.defaultdict(list) for label in repos}
    for run in range(args.runs):
        order = list(repos) if run % 2 == 0 else list(reversed(repos))
        for label in order:
            load = os.getloadavg()[0]
            summary, start, end = fly(repos[label], args.state, args.controller)
            per, wakeups = per_service(start, end, float(summary["time_s"]))  # type: ignore[arg-type]
            report(f"run {run} {label}", summary, per, wakeups, load)
            rtf[label].append(float(summary["achieved_rtf"]))  # type: ignore[arg-type]
            for name, threads in per.items():
                cpu[label][name].append(sum(threads.values()))
                woken[label][name].append(wakeups.get(name, 0.0))
            cpu[label]["total"].append(sum(sum(v.values()) for v in per.values()))
            woken[label]["total"].append(sum(wakeups.values()))
    if "baseline" not in repos:
        return
    print(f"\nmedians over {args.runs} interleaved run(s) ({args.controller}, state {args.state}):")
    print(f"  {'':18s} {'baseline':>10s} {'this':>10s} {'this/baseline':>14s}")
    for figures, unit in ((cpu, "ms CPU per sim s"), (woken, "wake-ups per sim s")):
        rows = [(name, statistics.median(v)) for name, v in figures["baseline"].items()]
        for name, base in sorted(rows, key=lambda r: (r[0] == "total", r[0])):
            this = statistics.median(figures["this"].get(name, [math.nan]))
            print(f"  {name:18s} {base:10.1f} {this:10.1f} {this / base:14.2f}   {unit}")
    b, t = statistics.median(rtf["baseline"]), statistics.median(rtf["this"])
    print(f"  {'achieved_rtf':18s} {b:10.2f} {t:10.2f} {t / b:14.2f}")
    pairs = [f"{x:.1f}/{y:.1f}" for x, y in zip(rtf["baseline"], rtf["this"], strict=True)]
    print(f"  rtf per run (baseline/this): {', '.join(pairs)}")


if __name__ == "__main__":
    main()
