"""The checkpoint helper (mjnav.runtime.checkpoint): atomic saves that keep the previous good file, reads that verify
everything and refuse bad files with a typed error, loads that log, set aside and fall back instead of raising, and
the checksummed record log."""

from __future__ import annotations

import logging
import pickle
import struct
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from mjnav.runtime.checkpoint import (
    FORMAT_VERSION,
    Checkpoint,
    CorruptCheckpoint,
    IncompatibleCheckpoint,
    RecordLog,
    read_checkpoint,
)
from tests.conftest import REPO

LOG = logging.getLogger("test.checkpoint")


def _saved(tmp_path: Path, *payloads: bytes) -> Checkpoint:
    store = Checkpoint(tmp_path / "state.ckpt", 1, LOG)
    for payload in payloads:
        store.save(payload)
    return store


def test_a_save_keeps_the_one_it_replaces_as_prev_and_load_returns_the_newest(tmp_path: Path) -> None:
    store = _saved(tmp_path, b"first", b"second")
    assert read_checkpoint(store.path, 1) == b"second" and read_checkpoint(store.prev_path, 1) == b"first"
    assert Checkpoint(store.path, 1, LOG).load(bytes) == b"second"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["state.ckpt", "state.ckpt.prev"]  # no temp file left
    assert Checkpoint(tmp_path / "none.ckpt", 1, LOG).load(bytes) is None


_CRASH = """
import os, sys
from pathlib import Path
from mjnav.runtime.checkpoint import Checkpoint
import logging
real, calls = os.replace, []
def dying(src, dst):
    calls.append(dst)
    if len(calls) == int(sys.argv[2]):
        os._exit(9)  # the process dies here: no cleanup, no flush, nothing after
    real(src, dst)
os.replace = dying
Checkpoint(Path(sys.argv[1]), 1, logging.getLogger()).save(b"new")
"""


def _crash_at_rename(path: Path, rename: int) -> None:
    """A process saving b"new" as ``path`` that dies at its ``rename``-th rename (1: NAME → NAME.prev,
    2: NAME.tmp → NAME)."""
    proc = subprocess.run([sys.executable, "-c", _CRASH, str(path), str(rename)], cwd=REPO, timeout=60)
    assert proc.returncode == 9


def test_a_crash_between_the_temp_write_and_the_rename_leaves_the_old_checkpoint(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    store = _saved(tmp_path, b"old")
    _crash_at_rename(store.path, 1)
    assert read_checkpoint(store.tmp_path, 1) == b"new"  # written and synced, never renamed
    with caplog.at_level(logging.WARNING):
        assert Checkpoint(store.path, 1, LOG).load(bytes) == b"old"
    assert not caplog.records  # nothing was bad
    store.save(b"newer")  # the next save writes over the leftover temp file
    assert Checkpoint(store.path, 1, LOG).load(bytes) == b"newer" and not store.tmp_path.exists()


def test_a_crash_between_the_two_renames_resumes_the_previous_checkpoint(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    store = _saved(tmp_path, b"old")
    _crash_at_rename(store.path, 2)
    assert not store.path.exists() and read_checkpoint(store.prev_path, 1) == b"old"
    with caplog.at_level(logging.WARNING):
        assert Checkpoint(store.path, 1, LOG).load(bytes) == b"old"
    assert f"resumed from the previous checkpoint {store.prev_path}" in caplog.text
    store.save(b"newer")
    assert Checkpoint(store.path, 1, LOG).load(bytes) == b"newer"
    assert read_checkpoint(store.prev_path, 1) == b"old"  # the good one stays until a newer one is complete


def _damaged(path: Path, offset: int, value: int) -> None:
    data = bytearray(path.read_bytes())
    data[offset] = value
    path.write_bytes(bytes(data))


def test_a_bad_checkpoint_is_logged_set_aside_and_the_previous_one_resumed(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    store = _saved(tmp_path, b"first", b"second")
    _damaged(store.path, 27, ord("X"))  # a payload byte: "second" -> "secXnd"
    bad = store.path.read_bytes()
    with caplog.at_level(logging.WARNING):
        assert store.load(bytes) == b"first"
    assert f"checkpoint {store.path} is bad (checksum mismatch" in caplog.text
    assert (tmp_path / "state.ckpt.bad-1").read_bytes() == bad and not store.path.exists()
    assert store.refused == [tmp_path / "state.ckpt.bad-1"]
    # Restarted again: the same state, nothing more set aside (no crash loop); the next save makes a new NAME and
    # keeps the good .prev.
    assert store.load(bytes) == b"first" and store.refused == []
    store.save(b"third")
    assert read_checkpoint(store.prev_path, 1) == b"first" and store.load(bytes) == b"third"


def test_with_both_bad_the_service_starts_afresh_and_nothing_is_deleted(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    store = _saved(tmp_path, b"first", b"second")
    store.path.write_bytes(b"")
    store.prev_path.write_bytes(bytes(40))
    with caplog.at_level(logging.WARNING):
        assert store.load(bytes) is None
    assert f"checkpoint {store.path} is bad (empty)" in caplog.text
    assert f"checkpoint {store.prev_path} is bad (not a checkpoint" in caplog.text
    assert f"no good checkpoint left of {store.path}: starting afresh" in caplog.text
    assert sorted(p.name for p in tmp_path.iterdir()) == ["state.ckpt.bad-1", "state.ckpt.prev.bad-1"]
    store.save(b"again")
    store.path.write_bytes(b"junk")
    store.load(bytes)
    assert (tmp_path / "state.ckpt.bad-2").read_bytes() == b"junk"  # an earlier one set aside is never overwritten
    assert (tmp_path / "state.ckpt.bad-1").read_bytes() == b""


def test_another_format_or_schema_version_is_refused_as_incompatible(tmp_path: Path) -> None:
    newer = Checkpoint(tmp_path / "state.ckpt", 2, LOG)
    newer.save(b"payload of schema 2")
    with pytest.raises(IncompatibleCheckpoint, match="schema version 2, this service reads 1"):
        read_checkpoint(newer.path, 1)
    data = bytearray(newer.path.read_bytes())
    struct.pack_into("<H", data, 8, FORMAT_VERSION + 1)  # the header's format version
    newer.path.write_bytes(bytes(data))
    with pytest.raises(IncompatibleCheckpoint, match=f"format version {FORMAT_VERSION + 1}"):
        read_checkpoint(newer.path, 2)
    assert Checkpoint(newer.path, 1, LOG).load(bytes) is None and (tmp_path / "state.ckpt.bad-1").exists()


@pytest.mark.parametrize(
    ("damage", "reason"),
    [
        (lambda d: b"", "empty"),
        (lambda d: d[:10], "truncated: 10 bytes, shorter than its header"),
        (lambda d: b"PK\x03\x04" + d[4:], "not a checkpoint: magic"),
        (lambda d: d[:-1], "its header says 7 payload bytes, the file holds 6"),
        (lambda d: d + b"!", "its header says 7 payload bytes, the file holds 8"),
        (lambda d: d[:12] + struct.pack("<Q", 2**62) + d[20:], "its header says 4611686018427387904 payload bytes"),
        (lambda d: d[:-1] + bytes([d[-1] ^ 1]), "checksum mismatch"),
        (lambda d: d[:20] + bytes(4) + d[24:], "checksum mismatch"),
    ],
    ids=["empty", "short header", "magic", "truncated", "extra byte", "huge length", "flipped bit", "zeroed crc"],
)
def test_every_damage_is_a_typed_error_naming_the_file(tmp_path: Path, damage: object, reason: str) -> None:
    store = _saved(tmp_path, b"payload")
    store.path.write_bytes(damage(store.path.read_bytes()))  # type: ignore[operator]
    with pytest.raises(CorruptCheckpoint, match=reason) as info:
        read_checkpoint(store.path, 1)
    assert info.value.path == store.path and str(store.path) in str(info.value)


def _utf8(payload: bytes) -> str:
    return payload.decode("utf-8")


def _sized(payload: bytes) -> np.ndarray:
    return np.empty(int.from_bytes(payload[:8], "little"), dtype=np.uint8)  # a length field of the payload's own


@pytest.mark.parametrize(
    ("payload", "decode", "error"),
    [
        (b"\xff\xfe", _utf8, "UnicodeDecodeError"),
        (b"\x80\x05not a pickle", pickle.loads, "UnpicklingError"),
        (b"cbuiltins\nno_such_name\n.", pickle.loads, "AttributeError"),
        ((2**62).to_bytes(8, "little"), _sized, "MemoryError"),
    ],
    ids=["unicode", "pickle", "forged pickle", "huge allocation"],
)
def test_a_payload_that_fails_to_decode_in_any_way_is_refused_not_raised(
    tmp_path: Path, caplog: pytest.LogCaptureFixture, payload: bytes, decode: object, error: str
) -> None:
    store = _saved(tmp_path, payload)
    with caplog.at_level(logging.WARNING):
        assert store.load(decode) is None  # type: ignore[arg-type]
    assert f"checkpoint {store.path} is bad (payload does not decode: " in caplog.text and error in caplog.text
    assert (tmp_path / "state.ckpt.bad-1").read_bytes()[24:] == payload


def test_the_record_log_finds_a_damaged_record_at_that_record(tmp_path: Path) -> None:
    log = RecordLog(tmp_path / "x.log", 1)
    log_id = log.start()
    records = [bytes([k]) * (10 + k) for k in range(6)]
    end = log.append(records[:3], RecordLog.HEADER_BYTES)
    end = log.append(records[3:], end)
    scan = log.scan()
    assert scan.log_id == log_id and scan.payloads == records and scan.error is None
    assert scan.good_end == end == log.path.stat().st_size and scan.ends[-1] == end
    start_of_4th = scan.ends[2]
    data = bytearray(log.path.read_bytes())
    data[start_of_4th + 9] ^= 0x10  # a payload byte of the 4th record
    log.path.write_bytes(bytes(data))
    scan = log.scan()
    assert scan.payloads == records[:3] and scan.good_end == start_of_4th
    assert scan.error == f"record at byte {start_of_4th}: checksum mismatch"
    struct.pack_into("<I", data, start_of_4th, 2**32 - 1)  # its length field, huge: never allocated
    log.path.write_bytes(bytes(data))
    assert "run past the end of the file" in str(log.scan().error)
    log.path.write_bytes(bytes(data[: start_of_4th + 5]))
    assert log.scan().error == f"record at byte {start_of_4th}: truncated in its frame"
    # A new start: another id, no records; a save cut short after it is dropped by the next append.
    assert log.start() != log_id and log.scan().payloads == []
    with log.path.open("ab") as f:
        f.write(b"torn")
    log.append([b"a"], RecordLog.HEADER_BYTES)
    assert log.scan().payloads == [b"a"] and log.scan().error is None


@pytest.mark.parametrize(
    ("offset", "reason"),
    [(0, "not a checkpoint: magic"), (9, "format version"), (11, "schema version"), (14, "header checksum mismatch")],
)
def test_a_record_log_with_a_bad_header_is_refused(tmp_path: Path, offset: int, reason: str) -> None:
    log = RecordLog(tmp_path / "x.log", 1)
    log.start()
    log.append([b"record"], RecordLog.HEADER_BYTES)
    _damaged(log.path, offset, log.path.read_bytes()[offset] ^ 0x40)
    with pytest.raises((CorruptCheckpoint, IncompatibleCheckpoint), match=reason):
        log.scan()
    log.path.write_bytes(b"")
    with pytest.raises(CorruptCheckpoint, match="empty"):
        log.scan()
    log.path.unlink()
    with pytest.raises(CorruptCheckpoint, match="missing"):
        log.scan()
