"""Simulation speed: real-time factor of the mjnav sim core beside plain ``mj_step``, and render frames/s.

Run:  .venv/bin/python benchmarks/sim.py [--world rooms] [--seconds 20] [--repeats 5] [--render] [--json]

Rows (all on the same world, same machine, same run):

* ``plain mj_step (nstep, C loop)``: the raw scene MJCF, ``mj_step(m, d, nstep=N)`` — no sensors read, no
  Python per step: the ceiling.
* ``plain mj_step (Python loop)``: the same, one ``mj_step`` call per step from Python.
* ``Simulator, no lidar``: :class:`mjnav.sim.Simulator` (collision counting, odometry at 50 Hz, watchdog).
* ``Simulator, lidar 10 Hz x 360``: the issue's goal configuration (>= 150x real time).
* ``mjnav sim --rtf max (SimRunner + 10 Hz command hook)``: what ``mjnav sim --no-bus --cmd ...`` runs.
* ``with bus``: the same plus :class:`mjnav.services.sim.SimBridge` publishing clock (100 Hz), scan, odom, tf,
  joint_states, ground_truth (50 Hz) and imu (100 Hz) on Zenoh — what ``mjnav sim`` and the sim service run —
  through an in-process router to a subscriber of every topic in another process (goal: >= 50x).

The robot drives a 1 m circle (0.3 m/s, 0.3 rad/s) in the start room, clear of the walls, so the contact load
is the normal one of a driving robot. Each figure is the best of ``--repeats`` rounds; each round runs every
variant once, so a loaded (shared) machine slows all of them alike. The median is printed beside it.

``--render`` adds offscreen rendering at 640x480 (render only, and render + H.264 encoding) for the top and
follow cameras.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path

# A subscriber to every sim topic in its own process, as the other services are; prints how many it received.
_LISTENER = """
import sys
from mjnav.bus import Bus, BusConfig
bus = Bus.open(BusConfig(connect=(sys.argv[1],)))
subs = [bus.subscribe(t) for t in ("clock", "scan", "odom", "imu", "joint_states", "tf", "ground_truth")]
print("ready", flush=True)
sys.stdin.read()
print(sum(s.count for s in subs), flush=True)
bus.close()
"""


def _free_port() -> int:
    import socket

    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def _interleaved(fns: dict[str, Callable[[], float]], repeats: int) -> dict[str, tuple[float, float]]:
    """Run every variant once per round, ``repeats`` rounds (so machine load hits all alike); (best, median)."""
    values: dict[str, list[float]] = {name: [] for name in fns}
    for _ in range(repeats):
        for name, fn in fns.items():
            values[name].append(fn())
    return {name: (max(v), statistics.median(v)) for name, v in values.items()}


def bench_rtf(world: str, seconds: float, repeats: int) -> dict[str, tuple[float, float]]:
    """Real-time factors (best, median) of the plain and mjnav stepping loops."""
    import mujoco

    from mjnav.sim import LidarConfig, SimRunner, Simulator, resolve_world

    path = resolve_world(world)
    v, w = 0.3, 0.3

    def plain(python_loop: bool) -> Callable[[], float]:
        def run() -> float:
            model = mujoco.MjModel.from_xml_path(str(path))
            data = mujoco.MjData(model)
            data.ctrl[:2] = ((2 * v - 0.28 * w) / 0.1, (2 * v + 0.28 * w) / 0.1)
            n = round(seconds / model.opt.timestep)
            t0 = time.perf_counter()
            if python_loop:
                step = mujoco.mj_step
                for _ in range(n):
                    step(model, data)
            else:
                mujoco.mj_step(model, data, nstep=n)
            return data.time / (time.perf_counter() - t0)

        return run

    def core(lidar: LidarConfig | None) -> Callable[[], float]:
        def run() -> float:
            sim = Simulator(world, seed=0, lidar=lidar, watchdog_timeout_s=None)
            sim.set_command(v, w)
            t0 = time.perf_counter()
            sim.step_until(seconds)
            wall = time.perf_counter() - t0
            if sim.collisions:
                raise RuntimeError("benchmark route collided; the figures would not be representative")
            return sim.time_s / wall

        return run

    def runner() -> float:
        sim = Simulator(world, seed=0, lidar=LidarConfig())
        r = SimRunner(sim, rtf=None)
        r.add_hook(lambda s: s.set_command(v, w), 0.1)
        return r.run(seconds).real_time_factor

    def with_bus() -> float:
        import subprocess

        from mjnav.bus import Bus, BusConfig
        from mjnav.services.sim import SimBridge, SimConfig

        endpoint = f"tcp/127.0.0.1:{_free_port()}"
        router = Bus.open(BusConfig(mode="router", connect=(), listen=(endpoint,)))
        listener = subprocess.Popen(
            [sys.executable, "-c", _LISTENER, endpoint], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True
        )
        try:
            assert listener.stdout is not None and listener.stdout.readline().strip() == "ready"
            sim = Simulator(world, seed=0, lidar=LidarConfig())
            with Bus.open(BusConfig(connect=(endpoint,))) as bus:
                bridge = SimBridge(sim, bus, SimConfig(world=world))
                if not bus.publisher("clock").wait_for_subscribers(10.0):
                    raise RuntimeError("the listener process never subscribed")
                r = SimRunner(sim, rtf=None)
                r.add_hook(lambda s: s.set_command(v, w), 0.1)
                bridge.attach(r)
                rtf = r.run(seconds).real_time_factor
            out, _ = listener.communicate("", timeout=30)
            if int(out.strip() or 0) == 0:
                raise RuntimeError("the listener received nothing: the bus row would be meaningless")
            return rtf
        finally:
            if listener.poll() is None:
                listener.kill()
            router.close()

    fns: dict[str, Callable[[], float]] = {
        "plain mj_step (nstep, C loop)": plain(False),
        "plain mj_step (Python loop)": plain(True),
        "Simulator, no lidar": core(None),
        "Simulator, lidar 10 Hz x 360": core(LidarConfig()),
        "mjnav sim --rtf max (SimRunner + 10 Hz command hook)": runner,
        "with bus (SimBridge publishing to a subscriber)": with_bus,
    }
    return _interleaved(fns, repeats)


def bench_render(world: str, frames: int, repeats: int) -> dict[str, tuple[float, float]]:
    """Frames per second (best, median) at 640x480: render only, and render + encode (whole recording)."""
    import tempfile

    from mjnav.sim import Recorder, Simulator, select_gl_backend

    backend = select_gl_backend()

    def variant(camera: str, encode: bool) -> Callable[[], float]:
        def run() -> float:
            sim = Simulator(world, seed=0, lidar=None, watchdog_timeout_s=None)
            sim.set_command(0.3, 0.3)
            with tempfile.TemporaryDirectory() as tmp:
                path = Path(tmp) / "b.mp4" if encode else None
                rec = Recorder(sim.model, sim.data, path, camera=camera, track_body=sim.robot.root_body)
                t0 = time.perf_counter()
                for _ in range(frames):
                    sim.step(17)  # 34 ms of sim time per frame (30 fps)
                    if encode:
                        rec.capture()
                    else:
                        rec.render()
                rec.close()  # includes flushing the encoder
                wall = time.perf_counter() - t0
            return frames / wall

        return run

    fns: dict[str, Callable[[], float]] = {}
    for camera in ("top", "follow"):
        fns[f"render 640x480 {camera} ({backend})"] = variant(camera, False)
        fns[f"render + H.264 640x480 {camera} ({backend}, with sim stepping)"] = variant(camera, True)
    return _interleaved(fns, repeats)


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark and print a table (or JSON)."""
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--world", default="rooms", help="bundled world or MJCF path (default rooms)")
    parser.add_argument("--seconds", type=float, default=20.0, help="sim seconds per run (default 20)")
    parser.add_argument("--repeats", type=int, default=5, help="runs per row; best and median reported")
    parser.add_argument("--render", action="store_true", help="also measure offscreen rendering")
    parser.add_argument("--frames", type=int, default=150, help="frames per render run (default 150)")
    parser.add_argument("--json", action="store_true", help="print JSON instead of a table")
    parser.add_argument("--quick", action="store_true", help="short run: 5 sim s, 2 repeats")
    args = parser.parse_args(argv)
    if args.quick:
        args.seconds, args.repeats, args.frames = 5.0, 2, 60

    rows = bench_rtf(args.world, args.seconds, args.repeats)
    renders = bench_render(args.world, args.frames, args.repeats) if args.render else {}
    if args.json:
        print(
            json.dumps(
                {
                    "world": args.world,
                    "real_time_factor": {k: {"best": b, "median": m} for k, (b, m) in rows.items()},
                    "frames_per_s": {k: {"best": b, "median": m} for k, (b, m) in renders.items()},
                }
            )
        )
        return 0
    print(f"world {args.world}: {args.seconds:g} sim s per run, best (median) of {args.repeats} runs")
    print(f"{'loop':58s} {'real-time factor':>22s}")
    for name, (best, med) in rows.items():
        print(f"{name:58s} {best:10.0f}x ({med:6.0f}x)")
    if renders:
        print(f"\n{'rendering':58s} {'frames/s':>22s}")
        for name, (best, med) in renders.items():
            print(f"{name:58s} {best:10.0f}  ({med:6.0f} )")
    return 0


if __name__ == "__main__":
    sys.exit(main())
