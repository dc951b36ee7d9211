"""The ``mjnav`` command.

Every sub-command lives in its own module under :mod:`mjnav.commands`; each module exposes
``register(subparsers)`` which adds its parser(s) and sets ``func`` (a callable taking the parsed
``argparse.Namespace`` and returning an exit code). Modules import heavy dependencies inside their
``func`` so that ``mjnav --help`` stays fast.
"""

from __future__ import annotations

import argparse
import importlib
import os
import pkgutil
import re
import sys
from collections.abc import Sequence

import mjnav
import mjnav.commands

#: Arguments that are numbers or coordinate lists, negative ones included (``-3``, ``-3.5``, ``-3,2``, ``-1e-3,-2``):
#: values, never options. argparse alone takes ``--goal -3,2`` for an option and fails with "expected one argument".
_NUMBERS = re.compile(r"^-\.?\d[\d.eE+-]*(,\s*-?\.?\d[\d.eE+-]*)*$")


def _accept_negative_numbers(parser: argparse.ArgumentParser) -> None:
    """Let ``parser`` and all its sub-parsers take negative numbers and coordinates as values."""
    parser._negative_number_matcher = _NUMBERS
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for child in action.choices.values():
                _accept_negative_numbers(child)


def build_parser() -> argparse.ArgumentParser:
    """The full argument parser with every sub-command of :mod:`mjnav.commands` registered."""
    parser = argparse.ArgumentParser(
        prog="mjnav",
        description=(
            "MuJoCo mobile-robot navigation stack over Zenoh. Services exchange ROS 2 messages (CDR) on "
            "keys <namespace>/<topic>, e.g. robot0/scan; any Zenoh or ROS 2 client can join."
        ),
        epilog="Run 'mjnav COMMAND --help' for the options of one command. Numbers and coordinates may be "
        "negative everywhere: --goal -3,2, --yaw -90, mjnav goal -1.5 2.",
    )
    parser.add_argument("--version", action="version", version=f"mjnav {mjnav.__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for info in sorted(pkgutil.iter_modules(mjnav.commands.__path__), key=lambda m: m.name):
        if info.name.startswith("_"):
            continue  # shared helpers, not commands
        module = importlib.import_module(f"mjnav.commands.{info.name}")
        module.register(sub)
    _accept_negative_numbers(parser)
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
        code = int(func(args))
        sys.stdout.flush()
        return code
    except KeyboardInterrupt:
        return 130
    except BrokenPipeError:
        # The reader went away (`mjnav plan … | head`): stop quietly. Python would report the closed pipe again
        # when it flushes stdout at exit, so point stdout at /dev/null first.
        sys.stdout = open(os.devnull, "w")  # noqa: SIM115
        return 0


if __name__ == "__main__":
    sys.exit(main())
