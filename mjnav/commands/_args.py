"""Argument types shared by the sub-commands (private: not a command, so :mod:`mjnav.cli` skips it)."""

from __future__ import annotations

import argparse
import math


def positive_int(text: str) -> int:
    """An ``argparse`` type: an integer > 0."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}") from None
    if value <= 0:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}")
    return value


def non_negative_float(text: str) -> float:
    """An ``argparse`` type: a finite number >= 0."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not (math.isfinite(value) and value >= 0.0):
        raise argparse.ArgumentTypeError(f"expected a finite number >= 0, got {text!r}")
    return value


def add_port_argument(parser: argparse.ArgumentParser, default: int) -> None:
    """``--port BASE``: the router's port, and with it every port the stack opens (``args.port`` None: defaults)."""
    parser.add_argument(
        "--port",
        type=int,
        default=None,
        metavar="BASE",
        help=f"the router's port on 127.0.0.1 (default {default}); given, every other port the stack listens on "
        "follows it: BASE+1, BASE+2, ... (the viewer's web and meshcat ports, Foxglove's), each an error when "
        "taken; without it the services keep their own (the viewer 7000/6000, searching upwards when taken)",
    )


def add_packing_argument(parser: argparse.ArgumentParser) -> None:
    """``--process-per-service``: how the launcher packs the stack's services into processes."""
    parser.add_argument(
        "--process-per-service",
        action="store_true",
        help="run every service in a process of its own (as docker compose runs them), ignoring the stack file's "
        "[[container]]s; default: the services of each container share one process (one Zenoh session, one "
        "clock, in-process delivery). The mission is the same to the last bit either way.",
    )
