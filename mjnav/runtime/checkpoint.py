"""Checkpoints a restarted service resumes from, written and read so that neither a crash nor a damaged file loses
the last good state or crashes the restart.

A :class:`Checkpoint` is one file: a 24-byte header — magic ``MJNAVCKP``, format version (u16), the caller's schema
version (u16), payload length in bytes (u64), CRC-32 of the payload (u32); little-endian — then the payload.
:meth:`Checkpoint.save` writes ``NAME.tmp`` in the same directory and syncs it, moves the current checkpoint to
``NAME.prev``, renames ``NAME.tmp`` to ``NAME`` and syncs the directory: a crash at any point leaves the new
checkpoint or the previous good one (as ``NAME`` or as ``NAME.prev``). :meth:`Checkpoint.load` verifies everything
(magic, versions, length, checksum, then the caller's decoder, any exception of which counts as a damaged payload);
a file that fails is logged by name with the reason, set aside (renamed ``NAME.bad-N``, never deleted) and the
previous one tried; with none left it returns None and the service starts afresh. It never raises for a bad file,
so a service cannot crash-loop on one.

A :class:`RecordLog` is an append-only file of checksummed records, for a checkpoint that grows by what is new
(SLAM's keyframes): a 24-byte header (magic ``MJNAVLOG``, format version, schema, a random id of this log, CRC-32
of the header's first 20 bytes), then records, each its payload length (u32), the CRC-32 of length and payload
(u32) and the payload. :meth:`RecordLog.scan` returns the records up to the first one that fails its checks and
says where and why, so a damaged record is found at that record.

CRC-32 catches accidental damage (every burst of up to 32 flipped bits; any other damage but for 1 in 2³²), not a
forgery: the state directory is its user's alone (``mjnav up`` makes it with mode 0700).
"""

from __future__ import annotations

import itertools
import logging
import os
import shutil
import struct
import zlib
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import TypeVar

T = TypeVar("T")

#: Version of the file layouts below; a file of another is refused (:class:`IncompatibleCheckpoint`).
FORMAT_VERSION = 1
CHECKPOINT_MAGIC = b"MJNAVCKP"
LOG_MAGIC = b"MJNAVLOG"
#: magic, format version, schema version, payload length (a log: its id), CRC-32 (of the payload; a log: of the
#: header's first 20 bytes).
_HEADER = struct.Struct("<8sHHQI")
#: A log record's frame: payload length, CRC-32 of the length's 4 bytes and the payload.
_FRAME = struct.Struct("<II")


class CheckpointError(Exception):
    """A checkpoint file that cannot be used.

    Attributes:
        path: the file.
        reason: what is wrong with it.
    """

    def __init__(self, path: Path, reason: str) -> None:
        super().__init__(f"{path}: {reason}")
        self.path = path
        self.reason = reason


class CorruptCheckpoint(CheckpointError):
    """A damaged file: empty, truncated, zeroed, wrong magic, length or checksum, or a payload that does not
    decode."""


class IncompatibleCheckpoint(CheckpointError):
    """A file in another format or schema version than this code reads."""


def read_checkpoint(path: Path, schema: int) -> bytes:
    """The payload of the checkpoint file ``path``, verified.

    Args:
        path: the file.
        schema: the schema version the caller reads.

    Raises:
        CorruptCheckpoint: unreadable, empty, truncated, not a checkpoint, or a length or checksum that does not
            match the payload.
        IncompatibleCheckpoint: another format or schema version.
    """
    try:
        with path.open("rb") as f:
            head = f.read(_HEADER.size)
            if not head:
                raise CorruptCheckpoint(path, "empty")
            if len(head) < _HEADER.size:
                raise CorruptCheckpoint(path, f"truncated: {len(head)} bytes, shorter than its header")
            magic, version, file_schema, length, crc = _HEADER.unpack(head)
            _check_kind(path, CHECKPOINT_MAGIC, magic, version, schema, file_schema)
            size = os.fstat(f.fileno()).st_size - _HEADER.size
            if length != size:  # checked before reading: a damaged length never sizes an allocation
                raise CorruptCheckpoint(path, f"its header says {length} payload bytes, the file holds {size}")
            payload = f.read(length)
    except OSError as exc:
        raise CorruptCheckpoint(path, f"unreadable: {exc}") from exc
    if len(payload) != length:
        raise CorruptCheckpoint(path, f"{len(payload)} payload bytes read, {length} expected")
    if zlib.crc32(payload) != crc:
        raise CorruptCheckpoint(path, f"checksum mismatch (CRC-32 {zlib.crc32(payload):#010x}, header {crc:#010x})")
    return payload


def _check_kind(path: Path, expected: bytes, magic: bytes, version: int, schema: int, file_schema: int) -> None:
    """Raise unless a header's magic and versions are what this code reads."""
    if magic != expected:
        raise CorruptCheckpoint(path, f"not a checkpoint: magic {magic!r}, expected {expected!r}")
    if version != FORMAT_VERSION:
        raise IncompatibleCheckpoint(path, f"format version {version}, this mjnav reads {FORMAT_VERSION}")
    if file_schema != schema:
        raise IncompatibleCheckpoint(path, f"schema version {file_schema}, this service reads {schema}")


def set_aside(path: Path, *, copy: bool = False) -> Path:
    """Move (``copy``: copy) a bad file to the first free ``NAME.bad-N`` beside it, so nothing is lost and nothing
    reads it again; returns the new path.

    Raises:
        OSError: it could not be moved or copied.
    """
    for n in itertools.count(1):
        target = path.with_name(f"{path.name}.bad-{n}")
        if not target.exists() and not target.is_symlink():
            break
    if copy:
        shutil.copyfile(path, target)
    else:
        os.rename(path, target)
    return target


def _write_synced(path: Path, *chunks: bytes) -> None:
    """Create or truncate ``path`` with ``chunks`` and sync it to disk (removed again when writing fails)."""
    try:
        with path.open("wb") as f:
            for chunk in chunks:
                f.write(chunk)
            f.flush()
            os.fsync(f.fileno())
    except BaseException:
        path.unlink(missing_ok=True)
        raise


def _sync_directory(directory: Path) -> None:
    """Sync a directory's entries (the renames in it) to disk."""
    fd = os.open(directory, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


class Checkpoint:
    """One checkpoint file of a service, with the previous good one kept beside it.

    Args:
        path: the checkpoint (``NAME``); ``NAME.prev`` holds the previous one, ``NAME.tmp`` a save in progress,
            ``NAME.bad-N`` the files :meth:`load` refused.
        schema: version of the payload's layout (the caller's); a file of another is refused as incompatible.
        log: where :meth:`load` reports what it refused and what it resumed from.
    """

    def __init__(self, path: Path, schema: int, log: logging.Logger) -> None:
        self.path = path
        self.prev_path = path.with_name(path.name + ".prev")
        self.tmp_path = path.with_name(path.name + ".tmp")
        self.schema = schema
        self.log = log
        #: The files the last :meth:`load` refused, where it set them aside.
        self.refused: list[Path] = []

    def save(self, payload: bytes) -> None:
        """Make ``payload`` the checkpoint, atomically; the one it replaces becomes ``NAME.prev``.

        Raises:
            OSError: it could not be written (the checkpoints there were are untouched).
        """
        header = _HEADER.pack(CHECKPOINT_MAGIC, FORMAT_VERSION, self.schema, len(payload), zlib.crc32(payload))
        _write_synced(self.tmp_path, header, payload)
        if self.path.exists():
            os.replace(self.path, self.prev_path)
        os.replace(self.tmp_path, self.path)
        _sync_directory(self.path.parent)

    def load(self, decode: Callable[[bytes], T]) -> T | None:
        """The newest checkpoint that verifies and that ``decode`` accepts: ``NAME``, else ``NAME.prev``; None when
        there is none (start afresh). Never raises for a bad file: each one is logged with the reason and set aside
        (:attr:`refused`).

        Args:
            decode: the caller's state from a verified payload; any exception it raises (a bad value, a pickle or
                Unicode error, a :class:`CheckpointError` about a file the payload relies on) refuses the file.
        """
        self.refused = []
        for candidate in (self.path, self.prev_path):
            if not candidate.exists():
                continue
            try:
                value = _decoded(candidate, read_checkpoint(candidate, self.schema), decode)
            except CheckpointError as exc:
                self._refuse(candidate, exc.reason)
                continue
            if candidate == self.prev_path:
                self.log.warning("resumed from the previous checkpoint %s", candidate)
            return value
        if self.refused:
            self.log.warning("no good checkpoint left of %s: starting afresh", self.path)
        return None

    def _refuse(self, path: Path, reason: str) -> None:
        try:
            moved = set_aside(path)
        except OSError as exc:
            self.log.error("checkpoint %s is bad (%s) and could not be set aside: %s", path, reason, exc)
            return
        self.refused.append(moved)
        self.log.warning("checkpoint %s is bad (%s): set aside as %s", path, reason, moved.name)


def _decoded(path: Path, payload: bytes, decode: Callable[[bytes], T]) -> T:
    """``decode(payload)``, any exception of it a :class:`CorruptCheckpoint` of ``path``."""
    try:
        return decode(payload)
    except CheckpointError as exc:
        raise CorruptCheckpoint(path, exc.reason if exc.path == path else str(exc)) from exc
    except Exception as exc:  # whatever a damaged payload makes the decoder raise (MemoryError included)
        raise CorruptCheckpoint(path, f"payload does not decode: {type(exc).__name__}: {exc}") from exc


@dataclass(frozen=True)
class LogScan:
    """What :meth:`RecordLog.scan` found.

    Attributes:
        log_id: the log's id (from its header).
        payloads: the records that passed their checks, in file order.
        ends: byte offset just past each of them.
        good_end: byte offset where the good part ends (past the last good record, or the header).
        error: why the record at ``good_end`` failed; None when the file ends there.
    """

    log_id: int
    payloads: list[bytes]
    ends: list[int]
    good_end: int
    error: str | None


class RecordLog:
    """An append-only file of checksummed records.

    Args:
        path: the file.
        schema: version of the records' layout (the caller's); a log of another is refused as incompatible.
    """

    #: Bytes before the first record.
    HEADER_BYTES = _HEADER.size

    def __init__(self, path: Path, schema: int) -> None:
        self.path = path
        self.schema = schema

    def start(self) -> int:
        """Begin the log afresh (what it held is gone) under a new random id, synced; returns the id."""
        log_id = int.from_bytes(os.urandom(8), "little")
        head = _HEADER.pack(LOG_MAGIC, FORMAT_VERSION, self.schema, log_id, 0)[:20]
        _write_synced(self.path, head, struct.pack("<I", zlib.crc32(head)))
        _sync_directory(self.path.parent)
        return log_id

    def append(self, payloads: Iterable[bytes], at: int) -> int:
        """Write records of ``payloads`` from byte ``at`` on (what followed it, a save cut short, is dropped) and
        sync them; returns the byte offset past the last."""
        with self.path.open("r+b") as f:
            f.truncate(at)
            f.seek(at)
            for payload in payloads:
                size = struct.pack("<I", len(payload))
                f.write(size + struct.pack("<I", zlib.crc32(payload, zlib.crc32(size))))
                f.write(payload)
            f.flush()
            os.fsync(f.fileno())
            return f.tell()

    def scan(self) -> LogScan:
        """The records that verify, up to the first that does not (or the end of the file).

        Raises:
            CorruptCheckpoint: no log, or a header that is empty, truncated, not a log's, or fails its checksum.
            IncompatibleCheckpoint: another format or schema version.
        """
        path = self.path
        try:
            with path.open("rb") as f:
                size = os.fstat(f.fileno()).st_size
                head = f.read(_HEADER.size)
                if not head:
                    raise CorruptCheckpoint(path, "empty")
                if len(head) < _HEADER.size:
                    raise CorruptCheckpoint(path, f"truncated: {len(head)} bytes, shorter than its header")
                magic, version, schema, log_id, crc = _HEADER.unpack(head)
                _check_kind(path, LOG_MAGIC, magic, version, self.schema, schema)
                if zlib.crc32(head[:20]) != crc:
                    raise CorruptCheckpoint(path, "header checksum mismatch")
                payloads: list[bytes] = []
                ends: list[int] = []
                pos, error = _HEADER.size, None
                while pos < size:
                    frame = f.read(_FRAME.size)
                    if len(frame) < _FRAME.size:
                        error = f"record at byte {pos}: truncated in its frame"
                        break
                    length, crc = _FRAME.unpack(frame)
                    if length > size - pos - _FRAME.size:  # before reading: a damaged length never sizes a read
                        error = f"record at byte {pos}: its {length} bytes run past the end of the file ({size} bytes)"
                        break
                    payload = f.read(length)
                    if zlib.crc32(payload, zlib.crc32(frame[:4])) != crc:
                        error = f"record at byte {pos}: checksum mismatch"
                        break
                    payloads.append(payload)
                    pos += _FRAME.size + length
                    ends.append(pos)
        except FileNotFoundError as exc:
            raise CorruptCheckpoint(path, "missing") from exc
        except OSError as exc:
            raise CorruptCheckpoint(path, f"unreadable: {exc}") from exc
        return LogScan(log_id, payloads, ends, pos, error)
