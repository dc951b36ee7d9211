"""The viewer redraws only what changed: the same grid, path or transform again sends no drawing command."""

from __future__ import annotations

import numpy as np

from mjnav.viz import NavView, Scene
from mjnav.viz.layers import pose_matrix
from mjnav.viz.view import ROOT
from tests.viz.helpers import rooms_grid, straight_path


def _recording_view() -> tuple[NavView, list[tuple[str, str]]]:
    sent: list[tuple[str, str]] = []

    def sink(kind: str, path: str, _packed: bytes) -> None:
        sent.append((kind, path))

    return NavView(Scene(sink)), sent


def test_an_unchanged_grid_path_or_pose_is_not_sent_again_and_a_changed_one_is() -> None:
    view, sent = _recording_view()
    grid = rooms_grid("map")
    view.handle("map", grid)
    first = len(sent)
    assert ("set_object", f"{ROOT}/map") in sent
    view.handle("map", rooms_grid("map"))  # the same map re-published
    assert len(sent) == first
    changed = rooms_grid("map")
    data = np.array(changed.data, dtype=np.int8)
    data[0] = 100 if data[0] != 100 else 0
    changed.data = data
    view.handle("map", changed)
    assert len(sent) > first

    mark = len(sent)
    view.handle("plan", straight_path(0.0, 0.0, 2.0, 1.0))
    drawn = len(sent)
    assert drawn > mark
    view.handle("plan", straight_path(0.0, 0.0, 2.0, 1.0))  # the planner's heartbeat: the same plan
    assert len(sent) == drawn
    view.handle("plan", straight_path(0.0, 0.0, 2.0, 1.5))
    assert len(sent) > drawn

    mark = len(sent)
    view.set_robot_pose(pose_matrix(1.0, 2.0, 0.3))
    view.set_robot_pose(pose_matrix(1.0, 2.0, 0.3))  # standing still
    view.set_robot_pose(pose_matrix(1.0, 2.1, 0.3))
    assert [k for k, _ in sent[mark:]] == ["set_transform", "set_transform"]


def test_a_layer_deleted_in_between_is_drawn_again() -> None:
    view, sent = _recording_view()
    view.set_robot_pose(pose_matrix(1.0, 2.0, 0.3))
    view.scene.delete(f"{ROOT}/robot")
    mark = len(sent)
    view.set_robot_pose(pose_matrix(1.0, 2.0, 0.3))
    assert [k for k, _ in sent[mark:]] == ["set_transform"]
