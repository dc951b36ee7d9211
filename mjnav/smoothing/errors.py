"""Typed errors raised by the smoothing (and control) algorithms."""

from __future__ import annotations


class PathError(ValueError):
    """A path argument is unusable: wrong shape, too few points, or non-finite values."""


class InfeasibleProblem(ValueError):
    """The constraints of an optimisation problem cannot all be met (e.g. a negative box half-width)."""


class SolverError(RuntimeError):
    """A numerical solver finished without a solved status.

    Attributes:
        status: the solver's own status text (e.g. OSQP's ``"maximum iterations reached"``).
    """

    def __init__(self, message: str, status: str) -> None:
        super().__init__(f"{message} (solver status: {status})")
        self.status = status
