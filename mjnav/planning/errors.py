"""Typed failures of the planners.

Every planner in :mod:`mjnav.planning` raises one of these instead of returning ``None``. They share the base
:class:`PlanningError`, so ``except PlanningError`` catches every planning failure; the input errors also derive
from :class:`ValueError` because they are caused by bad arguments.
"""

from __future__ import annotations


class PlanningError(Exception):
    """Base class of every planning failure."""


class InvalidInput(PlanningError, ValueError):
    """An argument is malformed: empty map, wrong dtype or shape, NaN, unknown option, bad weights."""


class OutsideMap(PlanningError, ValueError):
    """A start or goal cell lies outside the map.

    Attributes:
        cell: the offending (row, col) cell.
        shape: the map shape (rows, cols).
    """

    def __init__(self, what: str, cell: tuple[int, int], shape: tuple[int, int]) -> None:
        super().__init__(f"{what} (row, col) = {cell} lies outside the {shape[0]}×{shape[1]} map")
        self.cell = cell
        self.shape = shape


class StartOutsideMap(OutsideMap):
    """The start cell lies outside the map."""

    def __init__(self, cell: tuple[int, int], shape: tuple[int, int]) -> None:
        super().__init__("start", cell, shape)


class GoalOutsideMap(OutsideMap):
    """The goal cell lies outside the map."""

    def __init__(self, cell: tuple[int, int], shape: tuple[int, int]) -> None:
        super().__init__("goal", cell, shape)


class StartOccupied(PlanningError):
    """The start cell is occupied (or has infinite traversal cost).

    Attributes:
        cell: the (row, col) start cell.
    """

    def __init__(self, cell: tuple[int, int]) -> None:
        super().__init__(f"start (row, col) = {cell} is occupied")
        self.cell = cell


class GoalOccupied(PlanningError):
    """The goal cell is occupied (or has infinite traversal cost).

    Attributes:
        cell: the (row, col) goal cell.
    """

    def __init__(self, cell: tuple[int, int]) -> None:
        super().__init__(f"goal (row, col) = {cell} is occupied")
        self.cell = cell


class NoPathFound(PlanningError):
    """The search ended without reaching the goal (the goal is not reachable, or a planner gave up)."""


class LocalMinimum(NoPathFound):
    """A potential-field descent is stuck in a local minimum that the escape heuristic could not leave.

    Attributes:
        cell: the (row, col) cell of the last local minimum.
    """

    def __init__(self, cell: tuple[int, int], message: str) -> None:
        super().__init__(message)
        self.cell = cell


class InvalidPath(PlanningError, ValueError):
    """A path fails validation: non-adjacent steps, occupied or outside cells, or a corner cut."""
