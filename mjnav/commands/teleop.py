"""``mjnav teleop``: drive the robot from the keyboard (teleop_twist_keyboard's keys) on ``cmd_vel_teleop``."""

from __future__ import annotations

import argparse
import math
import os
import select
import sys
import time
from dataclasses import dataclass
from typing import Any

#: Key → (linear direction, angular direction), teleop_twist_keyboard's layout for a differential drive.
MOVE_KEYS: dict[str, tuple[int, int]] = {
    "u": (1, 1),
    "i": (1, 0),
    "o": (1, -1),
    "j": (0, 1),
    "l": (0, -1),
    "m": (-1, -1),
    ",": (-1, 0),
    ".": (-1, 1),
}
#: Key → (linear speed factor, angular speed factor).
SPEED_KEYS: dict[str, tuple[float, float]] = {
    "q": (1.1, 1.1),
    "z": (0.9, 0.9),
    "w": (1.1, 1.0),
    "x": (0.9, 1.0),
    "e": (1.0, 1.1),
    "c": (1.0, 0.9),
}
_CTRL_C, _CTRL_D = "\x03", "\x04"

BANNER = """Driving {key} from the keyboard (overrides navigation while this runs):
   u    i    o
   j    k    l
   m    ,    .
i/,: forward/back   j/l: turn left/right   u/o/m/.: arcs   k or any other key: stop
q/z: all speeds +/-10%   w/x: linear only   e/c: angular only
Ctrl-C: quit (a zero command is sent; navigation resumes after the sim's teleop_timeout_s)"""


@dataclass
class TeleopState:
    """What the keys set: direction and speeds (m/s, rad/s)."""

    speed_mps: float
    turn_radps: float
    linear: int = 0
    angular: int = 0

    def press(self, key: str) -> bool:
        """Apply one key; returns True when the speeds changed (worth printing)."""
        if key in MOVE_KEYS:
            self.linear, self.angular = MOVE_KEYS[key]
            return False
        if key in SPEED_KEYS:
            fv, fw = SPEED_KEYS[key]
            self.speed_mps *= fv
            self.turn_radps *= fw
            return True
        self.linear = self.angular = 0  # "k" and anything else: stop
        return False

    def command(self) -> tuple[float, float]:
        """(v m/s, ω rad/s) to publish."""
        return self.linear * self.speed_mps, self.angular * self.turn_radps


def register(sub: Any) -> None:
    """Add ``teleop``."""
    from mjnav.bus import add_bus_arguments

    p = sub.add_parser(
        "teleop",
        help="drive the robot from the keyboard (teleop_twist_keyboard keys)",
        description=(
            "Publish geometry_msgs/Twist on <ns>/cmd_vel_teleop at --rate from the keys pressed (the layout of ROS's "
            "teleop_twist_keyboard). The sim's velocity mux lets these commands override navigation's cmd_vel while "
            "they keep coming; after Ctrl-C a zero command is sent and navigation takes over again once teleop has "
            "been silent for sim.teleop_timeout_s (0.5 s of sim time). Needs a terminal."
        ),
        epilog=BANNER.format(key="<ns>/cmd_vel_teleop"),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--speed", type=float, default=0.5, metavar="M_S", help="linear speed, m/s (default 0.5)")
    p.add_argument("--turn", type=float, default=1.0, metavar="RAD_S", help="turn rate, rad/s (default 1.0)")
    p.add_argument("--rate", type=float, default=10.0, metavar="HZ", help="publish rate (default 10 Hz)")
    p.add_argument("--ns", default="robot0", help="robot namespace (default robot0)")
    add_bus_arguments(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """``mjnav teleop``."""
    import termios
    import tty

    from mjnav.bus import BusConfigError, BusUnavailable
    from mjnav.commands.bustools import open_connected
    from mjnav.msgs import ros
    from mjnav.runtime.logs import setup_logging

    values = (args.speed, args.turn, args.rate)
    if not all(math.isfinite(v) and v > 0 for v in values):
        print("mjnav teleop: --speed, --turn and --rate must be > 0", file=sys.stderr)
        return 2
    if not sys.stdin.isatty():
        print("mjnav teleop: needs a terminal on stdin (it reads single key presses)", file=sys.stderr)
        return 2
    setup_logging("WARNING")
    try:
        bus = open_connected(args, args.ns)
    except (BusUnavailable, BusConfigError) as exc:
        print(f"mjnav teleop: {exc}", file=sys.stderr)
        return 1
    state = TeleopState(args.speed, args.turn)
    fd = sys.stdin.fileno()
    saved = termios.tcgetattr(fd)
    with bus:
        pub = bus.publisher("cmd_vel_teleop")
        out = sys.stdout
        out.write(BANNER.format(key=pub.key) + "\n")
        out.write(f"speed {state.speed_mps:.2f} m/s, turn {state.turn_radps:.2f} rad/s\n")
        out.flush()
        period = 1.0 / args.rate
        try:
            tty.setcbreak(fd)  # one key at a time, no echo
            mode = termios.tcgetattr(fd)
            mode[3] &= ~termios.ISIG  # Ctrl-C arrives as a key (as in teleop_twist_keyboard's raw mode)
            termios.tcsetattr(fd, termios.TCSADRAIN, mode)
            next_t = time.monotonic()
            while True:
                ready, _, _ = select.select([fd], [], [], max(0.0, next_t - time.monotonic()))
                if ready:
                    key = os.read(fd, 1).decode(errors="replace")
                    if key in (_CTRL_C, _CTRL_D, ""):
                        break
                    if state.press(key):
                        out.write(f"speed {state.speed_mps:.2f} m/s, turn {state.turn_radps:.2f} rad/s\n")
                        out.flush()
                    v, w = state.command()
                    pub.put(ros.twist(v, w))  # at once, not at the next period
                    next_t = time.monotonic() + period
                elif time.monotonic() >= next_t:
                    v, w = state.command()
                    pub.put(ros.twist(v, w))
                    next_t = max(next_t + period, time.monotonic() - period)  # no burst after a stall
        except KeyboardInterrupt:
            pass
        finally:
            termios.tcsetattr(fd, termios.TCSADRAIN, saved)
            pub.put(ros.twist(0.0, 0.0))
            out.write("stopped\n")
            out.flush()
    return 0
