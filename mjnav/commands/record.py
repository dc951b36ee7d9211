"""``mjnav record``: render a world offscreen into an H.264 MP4.

The OpenGL backend (``MUJOCO_GL`` = egl, else osmesa) is chosen before MuJoCo is imported; when neither works
the command exits with a message naming the Debian packages to install.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from typing import TYPE_CHECKING

from mjnav.commands._args import non_negative_float, positive_int
from mjnav.commands.sim import add_world_arguments, command_hook

if TYPE_CHECKING:
    from mjnav.sim import Simulator


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add the ``record`` sub-command."""
    p = subparsers.add_parser(
        "record",
        help="render a world offscreen into an MP4 video",
        description=(
            "Simulate a world as fast as possible and render it offscreen (EGL or OSMesa, chosen "
            "automatically) into an H.264 MP4 at the given frame rate; duration x fps frames."
        ),
    )
    add_world_arguments(p)
    p.add_argument("--duration", type=non_negative_float, default=10.0, help="sim seconds to record (default 10)")
    p.add_argument("--fps", type=positive_int, default=30, help="frames per sim second (default 30)")
    p.add_argument("--out", required=True, metavar="VIDEO.mp4", help="output MP4 file")
    p.add_argument("--camera", default="top", help="top (whole world from above), follow (chase) or a model camera")
    p.add_argument("--width", type=positive_int, default=640, help="frame width in pixels, even (default 640)")
    p.add_argument("--height", type=positive_int, default=480, help="frame height in pixels, even (default 480)")
    p.add_argument(
        "--cmd",
        nargs=2,
        type=float,
        metavar=("V", "OMEGA"),
        default=(0.2, 0.0),
        help="constant drive command (m/s, rad/s) during the recording (default 0.2 0: slowly ahead, clear of "
        "walls for 15 s in every bundled world); 0 0 keeps the robot still",
    )
    p.add_argument("--quiet", action="store_true", help="no progress bar on stderr")
    p.set_defaults(func=run)


class _Progress:
    """A one-line progress bar on stderr (redrawn at most ~50 times)."""

    def __init__(self, total: int, label: str, enabled: bool) -> None:
        self.total = max(1, total)
        self.label = label
        self.enabled = enabled
        self.done = 0
        self._every = max(1, self.total // 50)

    def hook(self, sim: Simulator) -> None:
        self.done += 1
        if self.enabled and (self.done % self._every == 0 or self.done == self.total):
            width = 30
            filled = width * self.done // self.total
            bar = "#" * filled + "-" * (width - filled)
            sys.stderr.write(f"\r{self.label} [{bar}] {self.done}/{self.total} frames")
            if self.done >= self.total:
                sys.stderr.write("\n")
            sys.stderr.flush()


def run(args: argparse.Namespace) -> int:
    """Record the video; exit code 0, 2 for a bad argument or world, 1 when rendering is impossible."""
    from mjnav.sim.errors import RenderBackendUnavailableError

    if args.width % 2 or args.height % 2:
        print("mjnav record: error: --width and --height must be even (H.264 4:2:0)", file=sys.stderr)
        return 2
    from mjnav.sim.glbackend import select_gl_backend  # before mujoco is imported

    try:
        backend = select_gl_backend()
    except RenderBackendUnavailableError as exc:
        print(f"mjnav record: error: {exc}", file=sys.stderr)
        return 1

    from mjnav.sim import Recorder, SimRunner, Simulator
    from mjnav.sim.errors import InvalidCommandError, ModelLoadError, SimError, UnknownWorldError

    t0 = time.perf_counter()
    try:
        sim = Simulator(args.world, seed=args.seed, lidar=None)
        runner = SimRunner(sim, rtf=None)
        v, w = (float(x) for x in args.cmd)
        if v != 0.0 or w != 0.0:
            runner.add_hook(command_hook(v, w), 0.1)
        total = round(args.duration * args.fps)
        progress = _Progress(total, f"recording {sim.world.name}", enabled=not args.quiet)
        with Recorder(
            sim.model,
            sim.data,
            args.out,
            fps=args.fps,
            width=args.width,
            height=args.height,
            camera=args.camera,
            track_body=sim.robot.root_body,
            backend=backend,
        ) as recorder:
            recorder.add_to(runner)
            runner.add_hook(progress.hook, 1.0 / args.fps)
            runner.run(args.duration)
    except (UnknownWorldError, ModelLoadError, InvalidCommandError) as exc:
        print(f"mjnav record: error: {exc}", file=sys.stderr)
        return 2
    except SimError as exc:
        print(f"mjnav record: error: {exc}", file=sys.stderr)
        return 1
    wall = time.perf_counter() - t0
    overall = recorder.frames / wall if wall > 0 else math.inf
    print(
        f"wrote {recorder.frames} frames ({args.width}x{args.height}, {args.fps} fps, camera "
        f"{args.camera}) to {recorder.path} with {backend}: {recorder.render_fps:.0f} frames/s rendered, "
        f"{overall:.0f} frames/s overall"
    )
    return 0
