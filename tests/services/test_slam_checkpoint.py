"""The slam service's checkpoint (SlamCheckpoint): written by what is new, restored to continue exactly, robust to a
save cut short, and refused (logged, set aside) when its files disagree."""

from __future__ import annotations

import logging
import pickle
from pathlib import Path

import numpy as np
import pytest

from mjnav.estimation.slam import GraphSlam, SlamConfig
from mjnav.estimation.slam_metrics import corrupt_odometry
from mjnav.services.slam import SlamCheckpoint
from tests.estimation._slam_world import ring_drive, scans

LOG = logging.getLogger("test.slam_checkpoint")


class _Ring:
    """A seeded drive round the synthetic ring, fed scan by scan."""

    def __init__(self) -> None:
        self.truth = ring_drive()
        rng = np.random.default_rng(0)
        self.angles, self.ranges = scans(self.truth, rng, noise_m=0.02)
        self.odom = corrupt_odometry(self.truth, rng, (0.05, 0.05, 0.05))

    def new(self) -> GraphSlam:
        return GraphSlam(SlamConfig(max_range_m=4.0, loop_candidates=2), initial_pose=self.truth[0])

    def update(self, slam: GraphSlam, k: int) -> np.ndarray:
        est = slam.update(0.1 * k, self.odom[k], self.ranges[k], self.angles, range_min_m=0.1, range_max_m=12.0)
        return est.pose


def _saved(tmp_path: Path, scans_fed: int) -> tuple[_Ring, GraphSlam, SlamCheckpoint]:
    """A SLAM fed the ring's first ``scans_fed`` scans and saved once in ``tmp_path``."""
    ring = _Ring()
    slam = ring.new()
    saver = SlamCheckpoint(tmp_path, LOG)
    for k in range(scans_fed):
        ring.update(slam, k)
    saver.save(slam, {"scans": scans_fed})
    return ring, slam, saver


@pytest.mark.e2e
def test_a_restored_checkpoint_continues_exactly_and_each_save_writes_only_what_is_new(tmp_path: Path) -> None:
    ring = _Ring()
    slam = ring.new()
    saver = SlamCheckpoint(tmp_path, LOG)
    half = ring.truth.shape[0] // 2
    sizes = []
    for k in range(half):
        ring.update(slam, k)
        if k % 50 == 49:
            saver.save(slam, {"scans": k + 1})
            sizes.append(saver.log_path.stat().st_size)
    first = saver.log_path.read_bytes()
    for k in range(half, half + 50):
        ring.update(slam, k)
    saver.save(slam, {"scans": half + 50})
    # The log only grew: what the first saves wrote is untouched, and a save wrote its new keyframes, not all.
    assert saver.log_path.read_bytes()[: len(first)] == first
    assert sizes == sorted(sizes) and sizes[0] > 0
    whole = len(pickle.dumps(slam))
    assert saver.state_path.stat().st_size < 0.3 * whole

    restored, extra = SlamCheckpoint(tmp_path, LOG).load(dict) or (None, {})
    assert restored is not None and extra == {"scans": half + 50}
    assert restored.num_keyframes == slam.num_keyframes and restored.loop_closures == slam.loop_closures
    for j in range(half + 50, ring.truth.shape[0]):
        assert np.array_equal(ring.update(restored, j), ring.update(slam, j)), j
    assert np.array_equal(restored.trajectory()[1], slam.trajectory()[1])


@pytest.mark.e2e
def test_a_save_cut_short_is_ignored_and_overwritten_by_the_next(tmp_path: Path) -> None:
    ring, slam, saver = _saved(tmp_path, 60)
    good = saver.log_path.stat().st_size
    with saver.log_path.open("ab") as f:  # a crash after appending records, before the state file was replaced
        f.write(b"\x80\x05torn record")
    restored, _ = SlamCheckpoint(tmp_path, LOG).load(dict) or (None, {})
    assert restored is not None and restored.num_keyframes == slam.num_keyframes

    resumed = SlamCheckpoint(tmp_path, LOG)
    again, _ = resumed.load(dict) or (None, {})
    assert again is not None
    for k in range(60, 120):
        ring.update(again, k)
        ring.update(slam, k)
    resumed.save(again, {"scans": 120})
    assert b"torn record" not in saver.log_path.read_bytes()[good : good + 64]
    final, _ = SlamCheckpoint(tmp_path, LOG).load(dict) or (None, {})
    assert final is not None and np.array_equal(final.pose, slam.pose)


def test_a_new_mapping_starts_the_log_afresh(tmp_path: Path) -> None:
    ring = _Ring()
    saver = SlamCheckpoint(tmp_path, LOG)
    old = ring.new()
    for k in range(80):
        ring.update(old, k)
    saver.save(old, {})
    new = ring.new()
    for k in range(30):
        ring.update(new, k)
    saver.save(new, {})
    loaded, _ = SlamCheckpoint(tmp_path, LOG).load(dict) or (None, {})
    assert loaded is not None and loaded.num_keyframes == new.num_keyframes < old.num_keyframes


def test_a_log_that_lacks_what_the_state_needs_is_refused(tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    _, _, saver = _saved(tmp_path, 60)
    saver.log_path.write_bytes(saver.log_path.read_bytes()[: saver.log_path.stat().st_size // 2])
    with caplog.at_level(logging.WARNING):
        assert SlamCheckpoint(tmp_path, LOG).load(dict) is None
    assert f"checkpoint {saver.state_path} is bad" in caplog.text and "the state needs it up to byte" in caplog.text
    assert not saver.state_path.exists() and (tmp_path / "slam.pickle.bad-1").exists()
    assert not saver.log_path.exists() and (tmp_path / "slam.log.bad-1").exists()  # set aside with it
    assert SlamCheckpoint(tmp_path / "nowhere", LOG).load(dict) is None


@pytest.mark.e2e
def test_a_save_does_not_rewrite_what_earlier_saves_wrote(tmp_path: Path) -> None:
    ring, slam, saver = _saved(tmp_path, 60)
    n = saver.log_path.stat().st_size
    saver.log_path.write_bytes(b"X" * n)  # a marker in place of the records written so far
    for k in range(60, 120):
        ring.update(slam, k)
    saver.save(slam, {})
    log = saver.log_path.read_bytes()
    assert log[:n] == b"X" * n and len(log) > n  # only the new keyframes and submaps were written


def test_past_a_damaged_record_the_previous_state_resumes_and_the_next_save_replaces_the_damage(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    ring, slam, saver = _saved(tmp_path, 20)
    older = saver.log_path.stat().st_size
    for k in range(20, 40):
        ring.update(slam, k)
    saver.save(slam, {"scans": 40})
    log = bytearray(saver.log_path.read_bytes())
    log[older + 20] ^= 0x04  # a bit of the first record the newest state added
    saver.log_path.write_bytes(bytes(log))
    resumed = SlamCheckpoint(tmp_path, LOG)
    with caplog.at_level(logging.WARNING):
        again, extra = resumed.load(dict) or (None, {})
    assert again is not None and extra == {"scans": 20}  # the state saved at 20 scans: its records are intact
    assert f"record at byte {older}: checksum mismatch" in caplog.text and str(saver.state_path) in caplog.text
    assert (tmp_path / "slam.log.bad-1").read_bytes() == bytes(log)  # a copy: the resumed state uses the log
    # The resumed SLAM goes on as the original did from 20 scans; its next save drops the damaged records.
    original = ring.new()
    for k in range(60):
        ring.update(original, k)
        if k >= 20:
            ring.update(again, k)
    resumed.save(again, {"scans": 60})
    final, extra = SlamCheckpoint(tmp_path, LOG).load(dict) or (None, {})
    assert final is not None and extra == {"scans": 60} and np.array_equal(final.pose, original.pose)


def test_a_state_of_an_earlier_mapping_is_not_resumed_on_a_later_mappings_log(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    ring = _Ring()
    saver = SlamCheckpoint(tmp_path, LOG)
    old = ring.new()
    for k in range(20):
        ring.update(old, k)
    saver.save(old, {})
    new = ring.new()  # a new mapping (a new initialpose): the log starts afresh, the old state becomes .prev
    for k in range(40):
        ring.update(new, k)
    saver.save(new, {})
    saver.state_path.write_bytes(b"")
    with caplog.at_level(logging.WARNING):
        assert SlamCheckpoint(tmp_path, LOG).load(dict) is None
    assert "another mapping's log" in caplog.text
