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


def add_packing_argument(parser: argparse.ArgumentParser) -> None:
    """``--process-per-service``: how the launcher packs the stack's services into processes."""
    parser.add_argument(
        "--process-per-service",
        action="store_true",
        help="run every service in a process of its own (as docker compose runs them), ignoring the stack file's "
        "[[container]]s; default: the services of each container share one process (one Zenoh session, one "
        "clock, in-process delivery). The mission is the same to the last bit either way.",
    )
