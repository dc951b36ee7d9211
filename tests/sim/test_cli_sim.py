"""``mjnav sim``: JSON summary on the last stdout line, typed errors for bad worlds."""

from __future__ import annotations

import argparse
import json

import pytest

from mjnav.cli import main
from mjnav.commands.sim import parse_rtf


def test_sim_json_summary_is_the_last_line(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["sim", "--world", "rooms", "--duration", "1.5", "--rtf", "max", "--no-bus", "--json"]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    summary = json.loads(lines[-1])
    assert summary["sim_time_s"] == pytest.approx(1.5)
    assert summary["steps"] == 750 and summary["world"] == "rooms"


def test_sim_with_a_command_moves_the_robot(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["sim", "--world", "empty", "--duration", "2", "--rtf", "max", "--no-bus", "--cmd", "0.5", "0"]) == 0
    out = capsys.readouterr().out
    assert "robot at (0.9" in out  # ≈ 1 m in 2 s, with the 0.1 s acceleration


def test_unknown_world_exits_2_and_names_the_worlds(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["sim", "--world", "atlantis", "--duration", "1", "--no-bus"]) == 2
    err = capsys.readouterr().err
    assert "atlantis" in err and "warehouse" in err


def test_rtf_parsing() -> None:
    assert parse_rtf("max") is None
    assert parse_rtf("2.5") == 2.5
    for bad in ("0", "-1", "fast", "nan"):
        with pytest.raises(argparse.ArgumentTypeError):
            parse_rtf(bad)


def test_world_list(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["world", "list", "--json"]) == 0
    rows = [json.loads(line) for line in capsys.readouterr().out.strip().splitlines()]
    names = {r["name"] for r in rows}
    assert {"empty", "rooms", "maze", "warehouse"} <= names
    assert all(r["goal"] is not None for r in rows)
