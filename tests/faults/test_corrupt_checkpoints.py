"""200 corrupted checkpoints (issue 31), seeded, over the three services' checkpoint kinds — the mapper's grid, the
planner's goal, SLAM's state and its record log — restored through each service's own restore code.

Each case saves two good checkpoints through the service's own save code (the older one becomes ``.prev``), damages
the newest (truncated at a random length, bits flipped at random offsets, a range zeroed, another format version,
another magic, emptied, replaced by random bytes; for SLAM the state file or its log) and, in some cases, the
previous one too or removes it. Then, as a restarted service: the restore raises nothing, every damaged file it read
is logged by name and set aside byte for byte, the state is the newest checkpoint whose bytes are all intact (for
SLAM's previous state: its file and the log up to where it was saved), or none; and a second restart gives the same
state and sets nothing more aside (no crash loop).
"""

from __future__ import annotations

import logging
import shutil
import struct
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from mjnav.bus import Bus
from mjnav.geometry import Pose2D
from mjnav.mapping import OccupancyGrid
from mjnav.msgs import ros
from mjnav.runtime import Service
from mjnav.runtime.checkpoint import FORMAT_VERSION
from mjnav.services.mapper import MapperService
from mjnav.services.planner import PlannerService, _Goal
from mjnav.services.slam import SlamService
from tests.services.harness import Harness
from tests.services.test_slam_checkpoint import _Ring

Peer = Callable[..., Bus]

#: Cases per checkpoint kind: 200 in all.
CASES = {"mapper": 67, "planner": 67, "slam": 66}
DAMAGES = ("truncated", "bit-flipped", "zeroed", "wrong version", "wrong magic", "empty", "random bytes")


def damaged(data: bytes, how: str, rng: np.random.Generator) -> bytes:
    """``data`` (a checkpoint or log file) damaged as ``how`` says; never equal to ``data``."""
    while True:
        out = bytearray(data)
        if how == "truncated":
            out = out[: int(rng.integers(0, len(data)))]
        elif how == "bit-flipped":
            for _ in range(int(rng.integers(1, 9))):
                out[int(rng.integers(len(out)))] ^= 1 << int(rng.integers(8))
        elif how == "zeroed":
            start = int(rng.integers(len(out)))
            end = min(len(out), start + int(rng.integers(1, 4097)))
            out[start:end] = bytes(end - start)
        elif how == "wrong version":  # the header's format (bytes 8-9) or schema (10-11) version, u16
            struct.pack_into("<H", out, int(rng.choice([8, 10])), FORMAT_VERSION + int(rng.integers(1, 1000)))
        elif how == "wrong magic":
            out[:8] = rng.bytes(8)
        elif how == "empty":
            out = bytearray()
        else:
            out = bytearray(rng.bytes(int(rng.integers(1, 2 * len(data)))))
        if bytes(out) != data:
            return bytes(out)


@dataclass
class Kind:
    """One checkpoint kind: how to save its two good checkpoints with the service and read back its state.

    Attributes:
        service: the service, made once (its restore is called per case, on each case's directory).
        newest: the file names the newest state depends on, with the byte count each must be intact for (None:
            the whole file); ``previous`` the same for the state saved before it.
        targets: the files a case damages in place of the newest state file.
    """

    service: Service[Any]
    save: Callable[[Path], tuple[Any, Any]]  # writes both checkpoints in a directory: (older, newest) fingerprints
    reset: Callable[[], None]  # the service as if it had just started without a state directory
    restore: Callable[[], None]
    fingerprint: Callable[[], Any]  # the service's restored state, comparable
    newest: dict[str, int | None]
    previous: dict[str, int | None]
    targets: tuple[str, ...]


def _mapper(peer: Peer) -> Kind:
    svc: Any = Harness(MapperService, peer, (), robot=None, map_source="scan", pose_source="ground_truth").service
    rng = np.random.default_rng(7)
    res = svc.config.resolution_m

    def save(directory: Path) -> tuple[Any, Any]:
        svc.state_dir, prints = directory, []
        for shape, origin in (((30, 40), (-1.0, -0.5)), ((50, 64), (-2.0, -1.5))):
            grid = OccupancyGrid(shape[1], shape[0], res, origin)
            grid.log_odds[...] = rng.normal(0.0, 2.0, shape)
            svc.grid = grid
            svc._checkpoint()
            prints.append(fingerprint())
        return prints[0], prints[1]

    def reset() -> None:
        svc.grid, svc.seeded = None, False

    def fingerprint() -> Any:
        g = svc.grid
        return None if g is None else (g.log_odds.shape, g.log_odds.tobytes(), g.resolution_m, g.origin_m)

    return Kind(
        svc, save, reset, svc._restore_checkpoint, fingerprint,
        newest={"mapper-map.npz": None}, previous={"mapper-map.npz.prev": None}, targets=("mapper-map.npz",),
    )  # fmt: skip


def _planner(peer: Peer) -> Kind:
    svc: Any = Harness(PlannerService, peer, (), robot=None, pose_source="ground_truth").service

    def save(directory: Path) -> tuple[Any, Any]:
        svc.state_dir, prints = directory, []
        for goal_id, (x, y) in ((1, (3.45, 2.05)), (2, (-1.25, 7.5))):
            msg = ros.pose_stamped(0.5 * goal_id, "map", Pose2D(x, y, 0.3))
            svc.goal, svc.next_id = _Goal(goal_id, msg, Pose2D(x, y, 0.3)), goal_id + 1
            svc._save()
            prints.append(fingerprint())
        return prints[0], prints[1]

    def reset() -> None:
        svc.goal, svc.next_id = None, 1

    def fingerprint() -> Any:
        g = svc.goal
        return (svc.next_id, None) if g is None else (svc.next_id, g.goal_id, g.pose.x, g.pose.y, g.pose.theta)

    return Kind(
        svc, save, reset, svc._restore, fingerprint,
        newest={"planner-goal.json": None}, previous={"planner-goal.json.prev": None}, targets=("planner-goal.json",),
    )  # fmt: skip


def _slam(peer: Peer) -> Kind:
    svc: Any = Harness(SlamService, peer, (), robot=None).service
    previous: dict[str, int | None] = {"slam.pickle.prev": None}

    def save(directory: Path) -> tuple[Any, Any]:
        svc.state_dir, prints = directory, []
        ring = _Ring()
        svc.slam = ring.new()
        for k in range(40):
            ring.update(svc.slam, k)
            if k % 20 == 19:
                svc.map_to_odom, svc.scans = np.array([0.01 * k, -0.02 * k, 0.001 * k]), k + 1
                svc._checkpoint()
                prints.append(fingerprint())
                previous.setdefault("slam.log", (directory / "slam.log").stat().st_size)  # the older state's log
        svc.checkpoint = None
        return prints[0], prints[1]

    def reset() -> None:
        svc.slam = svc.checkpoint = svc.map_to_odom = None
        svc.scans = 0

    def fingerprint() -> Any:
        s = svc.slam
        if s is None:
            return None
        trajectory = s.trajectory()[1].tobytes()
        return s.num_keyframes, tuple(s.pose), trajectory, tuple(svc.map_to_odom), svc.scans

    return Kind(
        svc, save, reset, svc._restore, fingerprint,
        newest={"slam.pickle": None, "slam.log": None}, previous=previous, targets=("slam.pickle", "slam.log"),
    )  # fmt: skip


def _intact(directory: Path, template: Path, needs: dict[str, int | None]) -> bool:
    """Whether every file of ``needs`` holds in ``directory`` what it held in ``template`` (up to the byte
    count given)."""
    for name, count in needs.items():
        path = directory / name
        if not path.exists() or path.read_bytes()[:count] != (template / name).read_bytes()[:count]:
            return False
    return True


KINDS = {"mapper": _mapper, "planner": _planner, "slam": _slam}


def _restarted(kind: Kind, directory: Path, caplog: pytest.LogCaptureFixture) -> tuple[Any, str]:
    """The state the service resumes when it restarts on the state directory ``directory``, and what it logged
    (warnings and errors)."""
    kind.reset()
    kind.service.state_dir = directory
    caplog.clear()
    with caplog.at_level(logging.WARNING):
        kind.restore()
    return kind.fingerprint(), caplog.text


@pytest.mark.parametrize("name", list(CASES))
def test_corrupted_checkpoints_never_crash_the_restore_and_resume_the_last_good_state(
    name: str, peer: Peer, tmp_path: Path, caplog: pytest.LogCaptureFixture, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.delenv("MJNAV_STATE_DIR", raising=False)  # the service starts without one; each case sets its own
    kind = KINDS[name](peer)
    template = tmp_path / "template"
    template.mkdir()
    older, newest = kind.save(template)
    kind.reset()
    states = {"newest": newest, "older": older, "afresh": kind.fingerprint()}
    assert len({repr(state) for state in states.values()}) == 3
    rng = np.random.default_rng(31 + list(CASES).index(name))
    failures: list[str] = []
    outcomes: Counter[str] = Counter()
    for case in range(CASES[name]):
        directory = tmp_path / f"case{case}"
        shutil.copytree(template, directory)
        how = DAMAGES[case % len(DAMAGES)]
        target = kind.targets[int(rng.integers(len(kind.targets)))]
        bad = {target: damaged((directory / target).read_bytes(), how, rng)}
        prev, prev_file = str(rng.choice(["intact", "absent", "damaged"], p=[0.6, 0.2, 0.2])), next(iter(kind.previous))
        if prev == "absent":
            (directory / prev_file).unlink()
        elif prev == "damaged":
            bad[prev_file] = damaged((directory / prev_file).read_bytes(), str(rng.choice(DAMAGES)), rng)
        for file, data in bad.items():
            (directory / file).write_bytes(data)
        what = f"case {case}: {target} {how}, previous {prev}"
        outcome = (
            "newest"
            if _intact(directory, template, kind.newest)
            else "older"
            if _intact(directory, template, kind.previous)
            else "afresh"
        )
        outcomes[outcome] += 1
        try:
            state, logged = _restarted(kind, directory, caplog)
            aside = sorted(p.name for p in directory.glob("*.bad-*"))
            again, _ = _restarted(kind, directory, caplog)  # restarted once more: no crash loop, no other state
        except Exception as exc:
            failures.append(f"{what}: the restore raised {type(exc).__name__}: {exc}")
            continue
        if state != states[outcome]:
            got = next((k for k, v in states.items() if v == state), "another state")
            failures.append(f"{what}: restored {got}, expected {outcome}")
        if again != state or sorted(p.name for p in directory.glob("*.bad-*")) != aside:
            failures.append(f"{what}: a second restart restored another state or set more files aside")
        for file, data in bad.items():
            if str(directory / file) not in logged:
                failures.append(f"{what}: {file} not named in the log:\n{logged}")
            if not any((directory / a).read_bytes() == data for a in aside if a.startswith(f"{file}.bad-")):
                failures.append(f"{what}: the damaged {file} was not set aside ({aside})")
        if target != "slam.log" and (directory / target).exists():  # (a log the older state uses is copied)
            failures.append(f"{what}: the damaged {target} is still in place")
    assert not failures, "\n".join(failures)
    # The seeded cases cover both outcomes: the older state resumed, and nothing left to resume.
    assert outcomes["older"] >= 10 and outcomes["afresh"] >= 5, outcomes
