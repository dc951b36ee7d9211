"""``mjnav warmup``: compile every numba kernel into its on-disk cache (``make setup`` runs it once)."""

from __future__ import annotations

import argparse
from typing import Any


def register(sub: Any) -> None:
    """Add the ``warmup`` command."""
    p = sub.add_parser(
        "warmup",
        help="compile mjnav's numba kernels into their caches (make setup does it once)",
        description=(
            "Call every numba kernel of mjnav on tiny inputs with the argument types the services pass, so each is "
            "compiled once and cached beside its module (__pycache__); services then load them instead of "
            "compiling at start-up. Seconds with warm caches, a few minutes on a fresh install."
        ),
    )
    p.add_argument("--quiet", action="store_true", help="print nothing but errors")
    p.add_argument("--list-missing", action="store_true", help="name the kernels no exercise compiled")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """``mjnav warmup``."""
    from mjnav.warmup import main

    return main((["--quiet"] if args.quiet else []) + (["--list-missing"] if args.list_missing else []))
