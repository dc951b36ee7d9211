"""CARMEN log reader (the file-format edge of :mod:`mjnav.estimation`): front-laser scans with their poses.

Only ``FLASER`` lines are read (other message types are skipped). Their layout (CARMEN's logger)::

    FLASER n r1 … rn x y theta odom_x odom_y odom_theta timestamp host logger_timestamp

n ranges in metres over a 180° field of view, the first beam at −90° (to the right) and the beams spaced
π/n apart (for n = 180: −90°, −89°, …, +89°); x y theta is the laser's pose in the log's world frame (in the
Radish/Freiburg "corrected" logs the SLAM-corrected pose), odom_* the raw odometry pose, metres and radians.
A range at or beyond the sensor's maximum (81.83 m in the Intel log, ``max_range_m`` here) means no return.
"""

from __future__ import annotations

import gzip
import math
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from mjnav.estimation.scan_matching import ScanMatchError

__all__ = ["CarmenFormatError", "CarmenLog", "parse_carmen", "read_carmen"]


class CarmenFormatError(ScanMatchError):
    """A CARMEN log line cannot be parsed (wrong field count or a non-numeric field), or holds no scan."""


@dataclass(frozen=True, eq=False)
class CarmenLog:
    """The ``FLASER`` scans of a CARMEN log.

    Attributes:
        ranges: (S, n) float64 ranges, metres, beam order.
        angles: (n,) float64 beam angles relative to the laser's heading, radians (−π/2 + k·π/n).
        poses: (S, 3) float64 laser poses (x, y, θ) as logged (corrected logs: the SLAM solution).
        odometry: (S, 3) float64 odometry poses (x, y, θ).
        timestamps: (S,) float64 seconds.
    """

    ranges: NDArray[np.float64]
    angles: NDArray[np.float64]
    poses: NDArray[np.float64]
    odometry: NDArray[np.float64]
    timestamps: NDArray[np.float64]

    def __len__(self) -> int:
        return int(self.ranges.shape[0])

    def points(self, index: int, *, max_range_m: float = 80.0) -> NDArray[np.float64]:
        """(M, 2) points of scan ``index`` in the laser frame, metres; ranges >= ``max_range_m`` or <= 0 dropped."""
        r = self.ranges[index]
        ok = np.isfinite(r) & (r > 0.0) & (r < max_range_m)
        return np.column_stack((r[ok] * np.cos(self.angles[ok]), r[ok] * np.sin(self.angles[ok])))


def parse_carmen(lines: Iterable[str]) -> CarmenLog:
    """Parse the ``FLASER`` lines of a CARMEN log given as text lines.

    Args:
        lines: the log's lines (other message types and ``#`` comments are skipped).

    Returns:
        :class:`CarmenLog` of every FLASER scan in order.

    Raises:
        CarmenFormatError: a FLASER line is malformed, scans have different beam counts, or there is none.
    """
    ranges: list[list[float]] = []
    poses: list[list[float]] = []
    odom: list[list[float]] = []
    stamps: list[float] = []
    n_beams = -1
    for lineno, line in enumerate(lines, start=1):
        if not line.startswith("FLASER"):
            continue
        f = line.split()
        try:
            n = int(f[1])
            if n < 1 or len(f) < 2 + n + 7:
                raise ValueError(f"expected {2 + n + 7} or more fields, got {len(f)}")
            vals = [float(v) for v in f[2 : 2 + n + 7]]
        except (IndexError, ValueError) as exc:
            raise CarmenFormatError(f"line {lineno}: malformed FLASER line: {exc}") from None
        if n_beams not in (-1, n):
            raise CarmenFormatError(f"line {lineno}: {n} beams, earlier scans had {n_beams}")
        n_beams = n
        ranges.append(vals[:n])
        poses.append(vals[n : n + 3])
        odom.append(vals[n + 3 : n + 6])
        stamps.append(vals[n + 6])
    if n_beams < 0:
        raise CarmenFormatError("no FLASER line found")
    angles = np.asarray(-0.5 * math.pi + np.arange(n_beams) * (math.pi / n_beams), dtype=np.float64)
    return CarmenLog(
        ranges=np.asarray(ranges, dtype=np.float64),
        angles=angles,
        poses=np.asarray(poses, dtype=np.float64),
        odometry=np.asarray(odom, dtype=np.float64),
        timestamps=np.asarray(stamps, dtype=np.float64),
    )


def read_carmen(path: str | Path) -> CarmenLog:
    """Read a CARMEN log file (plain text, or gzip when the name ends in ``.gz``); see :func:`parse_carmen`.

    Raises:
        OSError: the file cannot be read.
        CarmenFormatError: see :func:`parse_carmen` (also for undecodable bytes).
    """
    p = Path(path)
    try:
        if p.suffix == ".gz":
            with gzip.open(p, "rt", encoding="ascii") as fh:
                return parse_carmen(fh)
        with p.open("r", encoding="ascii") as fh:
            return parse_carmen(fh)
    except (UnicodeDecodeError, gzip.BadGzipFile, EOFError) as exc:
        raise CarmenFormatError(f"{p}: not a CARMEN text log: {exc}") from None
