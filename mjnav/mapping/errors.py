"""Typed failures of the mapping library.

Every function in :mod:`mjnav.mapping` raises one of these for bad input instead of returning ``None`` or
crashing inside a compiled kernel. They share the base :class:`MappingError`, which derives from
:class:`ValueError`, so ``except ValueError`` and ``except MappingError`` both catch them. Operating-system
failures while reading or writing files (missing file, permission) propagate unchanged as :class:`OSError`.
"""

from __future__ import annotations


class MappingError(ValueError):
    """Base class of every mapping failure (all are caused by bad arguments or bad data)."""


class InvalidGridError(MappingError):
    """A grid or array argument is malformed: empty, wrong shape, wrong dtype, out-of-range values."""


class InvalidParameterError(MappingError):
    """A scalar parameter is malformed: NaN/inf, non-positive resolution, inconsistent thresholds."""


class InvalidPoseError(MappingError):
    """A pose or point has a NaN or infinite coordinate, or the wrong number of components."""


class OutsideMapError(MappingError):
    """A world point or a cell lies outside the grid.

    Attributes:
        cell: the offending (row, col) cell (possibly negative or past the end).
        shape: the grid shape (rows, cols).
    """

    def __init__(self, cell: tuple[int, int], shape: tuple[int, int]) -> None:
        super().__init__(f"cell (row, col) = {cell} lies outside the {shape[0]}×{shape[1]} grid")
        self.cell = cell
        self.shape = shape


class MapFileError(MappingError):
    """A map file (YAML or its image) cannot be parsed or is inconsistent."""
