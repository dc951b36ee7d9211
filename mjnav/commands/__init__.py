"""Sub-commands of the ``mjnav`` CLI: one module each, discovered by :mod:`mjnav.cli`.

A module defines ``register(subparsers) -> None`` which adds its parser and sets ``func`` via
``parser.set_defaults(func=run)``; ``run(args) -> int`` returns the exit code.
"""
