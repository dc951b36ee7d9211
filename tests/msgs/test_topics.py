"""The topic table: keys, types, README generated from it."""

from __future__ import annotations

import re

import pytest

from mjnav.msgs import TOPICS, Kind, alive_key, resolve_key, topic
from mjnav.msgs.topics import markdown_table
from tests.conftest import REPO


def test_keys_follow_the_bridge_convention() -> None:
    assert topic("scan").key() == "robot0/scan"
    assert topic("cmd_vel").key("fleet/r2") == "fleet/r2/cmd_vel"
    assert topic("status").key("robot0", "sim") == "robot0/status/sim"
    assert alive_key("robot0", "sim") == "mjnav/alive/robot0/sim"
    with pytest.raises(ValueError):
        topic("status").key("robot0")
    with pytest.raises(ValueError):
        topic("scan").key("robot0", "sim")
    with pytest.raises(ValueError):
        topic("scan").key("bad ns")
    with pytest.raises(KeyError, match="known topics"):
        topic("nope")


def test_resolve_key_inverts_key() -> None:
    for row in TOPICS.values():
        key = row.key("fleet/r2", "planner" if row.per_service else None)
        ns, found = resolve_key(key)
        assert (ns, found) == ("fleet/r2", row)
    with pytest.raises(KeyError):
        resolve_key("robot0/unknown_topic")


def test_delivery_semantics() -> None:
    assert topic("goal").kind is Kind.EVENT and topic("cancel").kind is Kind.EVENT
    for name in ("scan", "odom", "map", "cmd_vel"):
        assert topic(name).kind is Kind.SNAPSHOT


def test_readme_topic_table_is_generated_from_the_table() -> None:
    readme = (REPO / "README.md").read_text(encoding="utf-8")
    m = re.search(r"<!-- topic-table:begin -->\n(.*?)\n<!-- topic-table:end -->", readme, re.S)
    assert m, "README.md lacks the generated topic table markers"
    assert m.group(1) == markdown_table(), "README topic table is stale: run `python -m mjnav.msgs.topics`"


def test_no_key_is_spelled_outside_the_table() -> None:
    """DESIGN: nothing outside mjnav/msgs spells a key ("robot0/…" or "mjnav/alive")."""
    offenders = []
    for path in (REPO / "mjnav").rglob("*.py"):
        if path.parent.name == "msgs":
            continue
        text = path.read_text(encoding="utf-8")
        if re.search(r"[\"'](robot0/|mjnav/alive)", text):
            offenders.append(str(path.relative_to(REPO)))
    assert not offenders
