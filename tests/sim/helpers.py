"""Shared helpers for the sim tests: small MJCF worlds written on the fly."""

from __future__ import annotations

from pathlib import Path

import mjnav

DIFFBOT = (mjnav.REPO_ROOT / "mjcf" / "diffbot.xml").resolve()
COMMON = (mjnav.REPO_ROOT / "mjcf" / "assets" / "common.xml").resolve()


def box_room_xml(
    half_x: float,
    half_y: float,
    start: tuple[float, float, float] = (0.0, 0.0, 0.0),
    thickness: float = 0.1,
    extra: str = "",
) -> str:
    """A closed rectangular room whose inner wall faces are at x = ±half_x, y = ±half_y (metres)."""
    t = thickness / 2
    hx, hy = half_x + t, half_y + t
    return f"""<mujoco model="box_room">
  <include file="{COMMON}"/>
  <worldbody>
    <geom name="floor" class="floor" size="10 10 0.1"/>
    <geom name="wall_n" class="wall" pos="0 {hy} 0.5" size="{hx + t} {t} 0.5"/>
    <geom name="wall_s" class="wall" pos="0 {-hy} 0.5" size="{hx + t} {t} 0.5"/>
    <geom name="wall_e" class="wall" pos="{hx} 0 0.5" size="{t} {hy - t} 0.5"/>
    <geom name="wall_w" class="wall" pos="{-hx} 0 0.5" size="{t} {hy - t} 0.5"/>
    {extra}
    <frame name="start" pos="{start[0]} {start[1]} 0" euler="0 0 {start[2]}">
      <attach model="diffbot" body="base_link" prefix="robot/"/>
    </frame>
  </worldbody>
</mujoco>
"""


def write(tmp_path: Path, name: str, text: str) -> Path:
    """Write ``text`` to ``tmp_path / name`` and return the path."""
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path
