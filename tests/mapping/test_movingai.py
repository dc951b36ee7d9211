"""Moving AI .map / .scen reader: hand-written files, malformed input, and the shared reference files."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from mjnav.mapping.errors import MapFileError
from mjnav.mapping.movingai import (
    MovingAIFormatError,
    MovingAIMap,
    MovingAIScenario,
    parse_movingai_map,
    parse_movingai_scen,
    read_movingai_map,
    read_movingai_scen,
)

SMALL_MAP = "type octile\nheight 3\nwidth 4\nmap\n.@..\nT.GS\nOW..\n"


def test_parse_small_map_marks_blocked_terrain() -> None:
    m = parse_movingai_map(SMALL_MAP, name="small.map")
    assert isinstance(m, MovingAIMap)
    assert m.name == "small.map"
    assert (m.height, m.width) == (3, 4)
    expected = np.array(
        [[False, True, False, False], [True, False, False, False], [True, True, False, False]], dtype=bool
    )
    np.testing.assert_array_equal(m.blocked, expected)
    assert m.blocked.dtype == np.bool_
    assert not m.blocked.flags.writeable


def test_map_tolerates_crlf_and_trailing_blank_lines() -> None:
    m = parse_movingai_map(SMALL_MAP.replace("\n", "\r\n") + "\r\n\r\n")
    assert m.blocked.shape == (3, 4)
    assert int(m.blocked.sum()) == 4


@pytest.mark.parametrize(
    ("text", "fragment"),
    [
        ("type octile\nheight 3\nwidth 4\n", "no 'map' line"),
        ("type octile\nheight 3\nwidth 4\n.@..\n", "unexpected header"),
        ("type octile\nwidth 4\nmap\n....\n", "lacks 'height'"),
        ("type hex\nheight 1\nwidth 4\nmap\n....\n", "unsupported map type"),
        ("type octile\nheight x\nwidth 4\nmap\n....\n", "must be integers"),
        ("type octile\nheight 0\nwidth 4\nmap\n", "empty"),
        ("type octile\nheight 2\nwidth 4\nmap\n....\n", "found 1"),
        ("type octile\nheight 1\nwidth 4\nmap\n...\n", "3 characters"),
        ("type octile\nheight 1\nwidth 4\nmap\n..x.\n", "unknown terrain character 'x'"),
        ("type octile\nheight 1\nwidth 4\ncolour red\nmap\n....\n", "unexpected header"),
    ],
)
def test_malformed_map_raises_typed_error(text: str, fragment: str) -> None:
    with pytest.raises(MovingAIFormatError, match=fragment):
        parse_movingai_map(text, name="bad.map")


def test_format_error_is_a_map_file_error_and_value_error() -> None:
    with pytest.raises(MapFileError):
        parse_movingai_map("garbage")
    with pytest.raises(ValueError):
        parse_movingai_map("garbage")


def test_parse_scen_converts_x_y_to_row_col() -> None:
    text = "version 1\n0\tm.map\t4\t3\t1\t2\t3\t0\t3.41421356\n2\tm.map\t4\t3\t0\t0\t0\t0\t0\n"
    scen = parse_movingai_scen(text)
    assert scen[0] == MovingAIScenario(
        bucket=0, map="m.map", width=4, height=3, start=(2, 1), goal=(0, 3), optimal_length=3.41421356
    )
    assert scen[1].bucket == 2
    assert scen[1].start == scen[1].goal == (0, 0)
    assert scen[1].optimal_length == 0.0


@pytest.mark.parametrize(
    ("text", "fragment"),
    [
        ("", "empty"),
        ("version 2\n", "expected 'version 1'"),
        ("0\tm.map\t4\t3\t1\t2\t3\t0\t3.4\n", "expected 'version 1'"),
        ("version 1\n0\tm.map\t4\t3\t1\t2\t3\t0\n", "9 tab-separated"),
        ("version 1\n0\tm.map\t4\t3\t1\tz\t3\t0\t1.0\n", "non-numeric"),
        ("version 1\n0\tm.map\t4\t3\t4\t2\t3\t0\t1.0\n", "outside"),
        ("version 1\n0\tm.map\t4\t3\t-1\t2\t3\t0\t1.0\n", "negative"),
        ("version 1\n0\tm.map\t4\t3\t1\t2\t3\t0\tnan\n", "bad optimal length"),
    ],
)
def test_malformed_scen_raises_typed_error(text: str, fragment: str) -> None:
    with pytest.raises(MovingAIFormatError, match=fragment):
        parse_movingai_scen(text, name="bad.scen")


def test_read_files_from_disk(tmp_path: Path) -> None:
    (tmp_path / "m.map").write_text(SMALL_MAP)
    (tmp_path / "m.map.scen").write_text("version 1\n0\tm.map\t4\t3\t0\t0\t3\t2\t3.41421356\n")
    m = read_movingai_map(tmp_path / "m.map")
    assert m.name == "m.map"
    scen = read_movingai_scen(tmp_path / "m.map.scen")
    assert scen[0].goal == (2, 3)
    (tmp_path / "bin.map").write_bytes(b"\xff\xfe\x00")
    with pytest.raises(MovingAIFormatError, match="ASCII"):
        read_movingai_map(tmp_path / "bin.map")
    with pytest.raises(OSError):
        read_movingai_map(tmp_path / "missing.map")


# Terrain counts of the shared files (from `fold -w1 | sort | uniq -c` on the map rows).
REFERENCE_MAPS = {
    "arena": ((49, 49), 347),
    "den201d": ((37, 37), 413 + 418),
    "den312d": ((81, 65), 255 + 2565),
    "Boston_0_256": ((256, 256), 17768),
    "Paris_1_256": ((256, 256), 18296),
    "maze512-1-0": ((512, 512), 131073),
    "maze512-32-9": ((512, 512), 8352),
    "random512-40-5": ((512, 512), 104857 + 52937),
}


@pytest.mark.parametrize("name", sorted(REFERENCE_MAPS))
def test_reference_maps_and_scenarios(refdata: Path, name: str) -> None:
    shape, n_blocked = REFERENCE_MAPS[name]
    m = read_movingai_map(refdata / "movingai" / f"{name}.map")
    assert m.blocked.shape == shape
    assert int(m.blocked.sum()) == n_blocked
    scen = read_movingai_scen(refdata / "movingai" / f"{name}.map.scen")
    lines = (refdata / "movingai" / f"{name}.map.scen").read_text().splitlines()
    assert len(scen) == len([ln for ln in lines[1:] if ln.strip()])
    for s in scen:
        assert s.map == f"{name}.map"
        assert (s.height, s.width) == shape
        assert not m.blocked[s.start] and not m.blocked[s.goal]
        assert math.isfinite(s.optimal_length) and s.optimal_length >= 0
