"""Reader for the Moving AI grid path-finding benchmark files (``.map`` and ``.scen``).

Format (N. Sturtevant, "Benchmarks for Grid-Based Pathfinding", IEEE TCIAIG 4(2), 2012; movingai.com):

* ``.map``: header lines ``type octile``, ``height H``, ``width W``, ``map``, then H rows of W characters.
  Passable: ``.`` ``G`` ``S``; blocked: ``@`` ``O`` ``T`` ``W``.
* ``.scen``: a ``version 1`` line, then one tab-separated line per query:
  ``bucket map width height start_x start_y goal_x goal_y optimal_length`` with x = column, y = row, 0-based.
  ``optimal_length`` is the shortest 8-connected length with √2 diagonals and no corner cutting.

Cells here are (row, col), so a scenario's ``start`` is (start_y, start_x).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from mjnav.mapping.errors import MapFileError

PASSABLE = frozenset(".GS")
BLOCKED = frozenset("@OTW")


class MovingAIFormatError(MapFileError):
    """A ``.map`` or ``.scen`` file is malformed; the message names the file and line (a ``ValueError``)."""


@dataclass(frozen=True, slots=True)
class MovingAIMap:
    """A Moving AI map.

    Attributes:
        name: file name (e.g. ``arena.map``).
        blocked: (H, W) bool, True = blocked; indexed [row, col].
    """

    name: str
    blocked: NDArray[np.bool_]

    @property
    def height(self) -> int:
        """Number of rows H."""
        return int(self.blocked.shape[0])

    @property
    def width(self) -> int:
        """Number of columns W."""
        return int(self.blocked.shape[1])


@dataclass(frozen=True, slots=True)
class MovingAIScenario:
    """One query of a ``.scen`` file.

    Attributes:
        bucket: difficulty bucket (roughly optimal_length // 4).
        map: name of the map file the query is for.
        width: map width W the query was made for, cells.
        height: map height H, cells.
        start: (row, col) start cell.
        goal: (row, col) goal cell.
        optimal_length: published optimal length, cells (√2 diagonals, no corner cutting).
    """

    bucket: int
    map: str
    width: int
    height: int
    start: tuple[int, int]
    goal: tuple[int, int]
    optimal_length: float


def _read_text(path: Path) -> str:
    try:
        return path.read_text(encoding="ascii")
    except UnicodeDecodeError as exc:
        raise MovingAIFormatError(f"{path}: not an ASCII text file ({exc})") from None


def parse_movingai_map(text: str, name: str = "<string>") -> MovingAIMap:
    """Parse the text of a ``.map`` file.

    Args:
        text: the file contents.
        name: the map name stored in the result and used in error messages.

    Returns:
        The :class:`MovingAIMap`.

    Raises:
        MovingAIFormatError: bad header, wrong number of rows or columns, unknown terrain character.
    """
    lines = text.splitlines()
    header: dict[str, str] = {}
    i = 0
    while i < len(lines):
        line = lines[i].strip()
        i += 1
        if not line:
            continue
        if line == "map":
            break
        key, _, value = line.partition(" ")
        if key not in ("type", "height", "width"):
            raise MovingAIFormatError(f"{name}:{i}: unexpected header line {line!r}")
        header[key] = value.strip()
    else:
        raise MovingAIFormatError(f"{name}: no 'map' line ending the header")
    for key in ("type", "height", "width"):
        if key not in header:
            raise MovingAIFormatError(f"{name}: header lacks '{key}'")
    if header["type"] != "octile":
        raise MovingAIFormatError(f"{name}: unsupported map type {header['type']!r} (expected 'octile')")
    try:
        h = int(header["height"])
        w = int(header["width"])
    except ValueError:
        raise MovingAIFormatError(f"{name}: height/width must be integers; got {header}") from None
    if h <= 0 or w <= 0:
        raise MovingAIFormatError(f"{name}: map size {h}×{w} is empty")
    rows = [ln.rstrip("\r\n") for ln in lines[i:]]
    while rows and not rows[-1].strip():
        rows.pop()
    if len(rows) != h:
        raise MovingAIFormatError(f"{name}: header says {h} rows, found {len(rows)}")
    for r, row in enumerate(rows):
        if len(row) != w:
            raise MovingAIFormatError(f"{name}:{i + r + 1}: row {r} has {len(row)} characters, expected {w}")
    chars = np.frombuffer("".join(rows).encode("ascii", errors="replace"), dtype=np.uint8).reshape(h, w)
    passable = np.isin(chars, np.frombuffer("".join(sorted(PASSABLE)).encode(), np.uint8))
    blocked = np.isin(chars, np.frombuffer("".join(sorted(BLOCKED)).encode(), np.uint8))
    unknown = ~(passable | blocked)
    if unknown.any():
        r, c = (int(v) for v in np.argwhere(unknown)[0])
        raise MovingAIFormatError(
            f"{name}:{i + r + 1}: unknown terrain character {rows[r][c]!r} at (row {r}, col {c}); "
            f"passable {''.join(sorted(PASSABLE))}, blocked {''.join(sorted(BLOCKED))}"
        )
    blocked.setflags(write=False)
    return MovingAIMap(name=name, blocked=blocked)


def read_movingai_map(path: str | Path) -> MovingAIMap:
    """Read a Moving AI ``.map`` file (see :func:`parse_movingai_map`); the name is the file name.

    Raises:
        MovingAIFormatError: malformed file.
        OSError: the file cannot be read.
    """
    p = Path(path)
    return parse_movingai_map(_read_text(p), name=p.name)


def parse_movingai_scen(text: str, name: str = "<string>") -> list[MovingAIScenario]:
    """Parse the text of a version-1 ``.scen`` file.

    Args:
        text: the file contents.
        name: used in error messages.

    Returns:
        The scenarios in file order.

    Raises:
        MovingAIFormatError: missing/unsupported version line, wrong field count, non-numeric or negative
            fields, a start/goal outside the stated map size, or a non-finite/negative optimal length.
    """
    lines = text.splitlines()
    first = 0
    while first < len(lines) and not lines[first].strip():
        first += 1
    if first == len(lines):
        raise MovingAIFormatError(f"{name}: empty scenario file")
    version = lines[first].split()
    if len(version) != 2 or version[0] != "version" or version[1] not in ("1", "1.0"):
        raise MovingAIFormatError(f"{name}:{first + 1}: expected 'version 1', got {lines[first]!r}")
    out: list[MovingAIScenario] = []
    for n, line in enumerate(lines[first + 1 :], start=first + 2):
        if not line.strip():
            continue
        fields = line.rstrip("\r\n").split("\t")
        if len(fields) != 9:
            fields = line.split()
        if len(fields) != 9:
            raise MovingAIFormatError(f"{name}:{n}: expected 9 tab-separated fields, got {len(fields)}")
        try:
            bucket, width, height, sx, sy, gx, gy = (int(fields[k]) for k in (0, 2, 3, 4, 5, 6, 7))
            length = float(fields[8])
        except ValueError:
            raise MovingAIFormatError(f"{name}:{n}: non-numeric field in {line!r}") from None
        if min(bucket, sx, sy, gx, gy) < 0 or width <= 0 or height <= 0:
            raise MovingAIFormatError(f"{name}:{n}: negative index or empty size in {line!r}")
        if not (sx < width and gx < width and sy < height and gy < height):
            raise MovingAIFormatError(f"{name}:{n}: start/goal outside the {width}×{height} map")
        if not math.isfinite(length) or length < 0:
            raise MovingAIFormatError(f"{name}:{n}: bad optimal length {fields[8]!r}")
        out.append(
            MovingAIScenario(
                bucket=bucket,
                map=fields[1],
                width=width,
                height=height,
                start=(sy, sx),
                goal=(gy, gx),
                optimal_length=length,
            )
        )
    return out


def read_movingai_scen(path: str | Path) -> list[MovingAIScenario]:
    """Read a Moving AI ``.scen`` file (see :func:`parse_movingai_scen`).

    Raises:
        MovingAIFormatError: malformed file.
        OSError: the file cannot be read.
    """
    p = Path(path)
    return parse_movingai_scen(_read_text(p), name=p.name)
