"""Typed failures of the estimators.

Every estimator in :mod:`mjnav.estimation` raises one of these instead of returning ``None``. They share the base
:class:`EstimationError`, so ``except EstimationError`` catches every estimation failure; errors caused by bad
arguments also derive from :class:`ValueError`.
"""

from __future__ import annotations


class EstimationError(Exception):
    """Base class of every estimation failure."""


class InvalidModel(EstimationError, ValueError):
    """A model or filter argument is malformed: wrong shape, NaN/inf, a negative or non-symmetric covariance."""


class InvalidMeasurement(EstimationError, ValueError):
    """A measurement, control or observation array has the wrong shape or non-finite values."""


class NotPositiveDefinite(EstimationError):
    """A covariance the filter must factor (innovation covariance S, joint covariance) is not positive definite.

    Attributes:
        what: which matrix failed, e.g. ``"innovation covariance S"``.
    """

    def __init__(self, what: str) -> None:
        super().__init__(f"{what} is not positive definite")
        self.what = what
