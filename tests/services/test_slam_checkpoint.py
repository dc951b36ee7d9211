"""The slam service's checkpoint (SlamCheckpoint): written by what is new, restored to continue exactly, robust to a
save cut short, and refused (typed error) when its files disagree."""

from __future__ import annotations

import pickle
from pathlib import Path

import numpy as np
import pytest

from mjnav.estimation.slam import GraphSlam, SlamConfig, SlamError
from mjnav.estimation.slam_metrics import corrupt_odometry
from mjnav.services.slam import SlamCheckpoint
from tests.estimation._slam_world import ring_drive, scans


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
    saver = SlamCheckpoint(tmp_path)
    for k in range(scans_fed):
        ring.update(slam, k)
    saver.save(slam, {"scans": scans_fed})
    return ring, slam, saver


@pytest.mark.e2e
def test_a_restored_checkpoint_continues_exactly_and_each_save_writes_only_what_is_new(tmp_path: Path) -> None:
    ring = _Ring()
    slam = ring.new()
    saver = SlamCheckpoint(tmp_path)
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

    restored, extra = SlamCheckpoint(tmp_path).load() or (None, {})
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
    restored, _ = SlamCheckpoint(tmp_path).load() or (None, {})
    assert restored is not None and restored.num_keyframes == slam.num_keyframes

    resumed = SlamCheckpoint(tmp_path)
    again, _ = resumed.load() or (None, {})
    assert again is not None
    for k in range(60, 120):
        ring.update(again, k)
        ring.update(slam, k)
    resumed.save(again, {"scans": 120})
    assert b"torn record" not in saver.log_path.read_bytes()[good : good + 64]
    final, _ = SlamCheckpoint(tmp_path).load() or (None, {})
    assert final is not None and np.array_equal(final.pose, slam.pose)


def test_a_new_mapping_starts_the_log_afresh(tmp_path: Path) -> None:
    ring = _Ring()
    saver = SlamCheckpoint(tmp_path)
    old = ring.new()
    for k in range(80):
        ring.update(old, k)
    saver.save(old, {})
    new = ring.new()
    for k in range(30):
        ring.update(new, k)
    saver.save(new, {})
    loaded, _ = SlamCheckpoint(tmp_path).load() or (None, {})
    assert loaded is not None and loaded.num_keyframes == new.num_keyframes < old.num_keyframes


def test_a_log_that_lacks_what_the_state_needs_is_refused(tmp_path: Path) -> None:
    _, _, saver = _saved(tmp_path, 60)
    saver.log_path.write_bytes(saver.log_path.read_bytes()[: saver.log_path.stat().st_size // 2])
    with pytest.raises((SlamError, EOFError, pickle.UnpicklingError)):
        SlamCheckpoint(tmp_path).load()
    assert SlamCheckpoint(tmp_path / "nowhere").load() is None


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
