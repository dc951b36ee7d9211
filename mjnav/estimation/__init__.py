"""mjnav.estimation: state estimation, SLAM and scan matching (numpy/scipy/numba only).

Scan matching (:mod:`mjnav.estimation.scan_matching`): :func:`scan_match` (ICP, PL-ICP, CSM) and
:class:`CorrelativeGridMatcher` (branch-and-bound matching against an occupancy grid); line extraction
(:mod:`mjnav.estimation.split_merge`). File readers live at the edge (:mod:`mjnav.estimation.carmen`).
"""

from mjnav.estimation.carmen import CarmenFormatError, CarmenLog, parse_carmen, read_carmen
from mjnav.estimation.scan_matching import (
    CorrelativeGridMatcher,
    InsufficientPointsError,
    NoMatchError,
    ScanMatchError,
    ScanMatchResult,
    scan_match,
    scan_to_points,
)
from mjnav.estimation.split_merge import Corner, LineSegment, SplitMergeError, fit_line, line_corners, split_and_merge

__all__ = [
    "CarmenFormatError",
    "CarmenLog",
    "Corner",
    "CorrelativeGridMatcher",
    "InsufficientPointsError",
    "LineSegment",
    "NoMatchError",
    "ScanMatchError",
    "ScanMatchResult",
    "SplitMergeError",
    "fit_line",
    "line_corners",
    "parse_carmen",
    "read_carmen",
    "scan_match",
    "scan_to_points",
    "split_and_merge",
]
