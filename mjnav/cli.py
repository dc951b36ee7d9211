"""The ``mjnav`` command.

Every sub-command lives in its own module under :mod:`mjnav.commands`; each module exposes
``register(subparsers)`` which adds its parser(s) and sets ``func`` (a callable taking the parsed
``argparse.Namespace`` and returning an exit code). Modules import heavy dependencies inside their
``func`` so that ``mjnav --help`` stays fast.
"""

from __future__ import annotations

import argparse
import importlib
import pkgutil
import sys
from collections.abc import Sequence

import mjnav
import mjnav.commands


def build_parser() -> argparse.ArgumentParser:
    """The full argument parser with every sub-command of :mod:`mjnav.commands` registered."""
    parser = argparse.ArgumentParser(
        prog="mjnav",
        description=(
            "MuJoCo mobile-robot navigation stack over Zenoh. Services exchange ROS 2 messages (CDR) on "
            "keys <namespace>/<topic>, e.g. robot0/scan; any Zenoh or ROS 2 client can join."
        ),
        epilog="Run 'mjnav COMMAND --help' for the options of one command.",
    )
    parser.add_argument("--version", action="version", version=f"mjnav {mjnav.__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for info in sorted(pkgutil.iter_modules(mjnav.commands.__path__), key=lambda m: m.name):
        if info.name.startswith("_"):
            continue  # shared helpers, not commands
        module = importlib.import_module(f"mjnav.commands.{info.name}")
        module.register(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``mjnav`` console script; returns the process exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    func = getattr(args, "func", None)
    if func is None:
        parser.print_help()
        return 2
    try:
        return int(func(args))
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    sys.exit(main())
