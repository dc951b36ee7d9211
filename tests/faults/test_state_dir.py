"""A launcher's state directory does not outlive a ``kill -9`` of it (issue 31): the next launcher removes the
leftovers of launchers that are gone, and never the directory of a live one."""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import subprocess
import sys
import tempfile
from collections.abc import Iterator
from pathlib import Path

import pytest

from mjnav.bus import wait_until
from mjnav.runtime.launcher import make_state_dir
from tests.conftest import REPO, free_port

#: A process that makes its state directory as a launcher does, prints it and runs until its stdin closes.
_OWNER = (
    "import sys; from mjnav.runtime.launcher import make_state_dir; print(make_state_dir(), flush=True); "
    "sys.stdin.read()"
)


def _state(pid: int) -> str:
    """The process's state letter from /proc ("" once it is gone)."""
    try:
        text = Path(f"/proc/{pid}/stat").read_text()
    except OSError:  # FileNotFoundError, or ProcessLookupError while the process is being reaped
        return ""
    return text[text.rindex(")") + 2]


@contextlib.contextmanager
def _owner(tmp: Path) -> Iterator[tuple[subprocess.Popen[str], Path]]:
    """A process owning a state directory in ``tmp``; killed and reaped at the end whatever happened."""
    proc = subprocess.Popen(
        [sys.executable, "-c", _OWNER], cwd=REPO, env={**os.environ, "TMPDIR": str(tmp)}, text=True,
        stdin=subprocess.PIPE, stdout=subprocess.PIPE,
    )  # fmt: skip
    try:
        assert proc.stdout is not None
        yield proc, Path(proc.stdout.readline().strip())
    finally:
        proc.kill()
        proc.wait(30)


def test_the_next_launcher_removes_the_state_directory_of_one_killed_with_sigkill_and_keeps_a_live_ones(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    with _owner(tmp_path) as (killed, dead_dir), _owner(tmp_path) as (_live, live_dir):
        (dead_dir / "mapper-map.npz").write_bytes(b"checkpoint")
        assert dead_dir.parent == live_dir.parent == tmp_path and dead_dir.name.startswith(f"mjnav-state-{killed.pid}-")
        assert oct(dead_dir.stat().st_mode & 0o777) == "0o700"
        killed.send_signal(signal.SIGKILL)
        assert wait_until(lambda: _state(killed.pid) == "Z", 10.0)  # dead, not yet reaped: gone all the same
        # Neither a directory whose name does not say its owner, nor one of a live process, is touched; a pid now
        # running another process (started at another time) counts as gone.
        other = tmp_path / "mjnav-state-k2j4h1"
        other.mkdir()
        first = Path(make_state_dir())
        started = int(first.name.split("-")[3])
        reused = tmp_path / f"mjnav-state-{os.getpid()}-{started + 1}-abc"
        reused.mkdir()
        mine = Path(make_state_dir())
        assert not dead_dir.exists() and not reused.exists()
        assert live_dir.is_dir() and other.is_dir() and mine.is_dir()
        assert sorted(tmp_path.glob(f"mjnav-state-{os.getpid()}-*")) == sorted([first, mine])  # this process's
    shutil.rmtree(first)
    shutil.rmtree(mine)


def _children(pid: int) -> list[int]:
    """The pids of the processes whose parent is ``pid``."""
    found = []
    for status in Path("/proc").glob("[0-9]*/status"):
        with contextlib.suppress(OSError):
            if f"\nPPid:\t{pid}\n" in status.read_text():
                found.append(int(status.parent.name))
    return found


@pytest.mark.e2e
def test_mjnav_up_killed_with_sigkill_leaves_a_state_directory_the_next_one_removes(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    env = {k: v for k, v in os.environ.items() if not k.startswith("MJNAV_ZENOH_")} | {"TMPDIR": str(tmp_path)}
    up = subprocess.Popen(
        [sys.executable, "-m", "mjnav", "up", "--only", "planner", "--port", str(free_port()), "--headless"],
        cwd=REPO, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
    )  # fmt: skip
    services: list[int] = []
    try:
        assert wait_until(lambda: any(tmp_path.glob("mjnav-state-*")) and bool(_children(up.pid)), 120.0)
        services = _children(up.pid)
        up.send_signal(signal.SIGKILL)
        up.wait(30)
    finally:
        up.kill()
        up.wait(30)
        # Its services die with it (SIGTERM from the kernel when the launcher dies); none may outlive the test.
        gone = wait_until(lambda: all(_state(pid) in ("", "Z") for pid in services), 30.0)
        for pid in services:
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, signal.SIGKILL)
    assert gone, f"services of the killed launcher still run: {services}"
    (leftover,) = tmp_path.glob("mjnav-state-*")
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    mine = Path(make_state_dir())
    assert not leftover.exists() and list(tmp_path.glob("mjnav-state-*")) == [mine]
    shutil.rmtree(mine)
