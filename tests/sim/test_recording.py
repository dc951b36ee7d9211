"""Offscreen recording: ``mjnav record`` writes an H.264 MP4 whose frames read back and change over time."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from mjnav.cli import main
from mjnav.sim import RecordingError, RenderBackendUnavailableError, Simulator, select_gl_backend


@pytest.fixture(scope="module")
def backend() -> str:
    try:
        return select_gl_backend()
    except RenderBackendUnavailableError as exc:
        pytest.skip(f"no offscreen OpenGL here: {exc}")


@pytest.mark.e2e
def test_record_cli_writes_90_frames_that_change(backend: str, tmp_path: Path) -> None:
    import imageio.v3 as iio
    import imageio_ffmpeg

    out = tmp_path / "video.mp4"
    code = main(["record", "--world", "rooms", "--duration", "3", "--fps", "30", "--out", str(out), "--quiet"])
    assert code == 0
    frames = iio.imread(out, plugin="FFMPEG")
    assert frames.shape == (90, 480, 640, 3)
    assert frames.dtype == np.uint8
    first, last = frames[0].astype(int), frames[-1].astype(int)
    assert np.abs(first - last).mean() > 0.05  # the robot has driven 0.6 m (the default command)
    changed = [np.abs(frames[i].astype(int) - frames[i + 1].astype(int)).max() > 0 for i in range(0, 89, 10)]
    assert all(changed)
    meta = next(imageio_ffmpeg.read_frames(str(out)))
    assert meta["codec"] == "h264"
    assert meta["fps"] == pytest.approx(30.0)


@pytest.mark.e2e
def test_sim_can_record_while_it_runs_with_the_follow_camera(backend: str, tmp_path: Path) -> None:
    import imageio.v3 as iio

    out = tmp_path / "sim.mp4"
    args = ["sim", "--world", "warehouse", "--duration", "1", "--rtf", "max", "--no-bus"]
    args += ["--record", str(out), "--record-fps", "10", "--camera", "follow", "--cmd", "0.5", "0"]
    assert main(args) == 0
    frames = iio.imread(out, plugin="FFMPEG")
    assert frames.shape == (10, 480, 640, 3)
    assert np.abs(frames[0].astype(int) - frames[-1].astype(int)).mean() > 0.5  # chase view moves


def test_recorder_rejects_bad_settings(backend: str, tmp_path: Path) -> None:
    from mjnav.sim import Recorder

    sim = Simulator("empty", seed=0, lidar=None)
    with pytest.raises(RecordingError, match="even"):
        Recorder(sim.model, sim.data, tmp_path / "a.mp4", width=641)
    with pytest.raises(RecordingError, match="unknown camera"):
        Recorder(sim.model, sim.data, tmp_path / "b.mp4", camera="nope")
    with Recorder(sim.model, sim.data, None, width=320, height=240) as render_only:
        frame = render_only.render()
        assert frame.shape == (240, 320, 3) and frame.std() > 1.0  # floor checker pattern, robot
        with pytest.raises(RecordingError, match="renders only"):
            render_only.capture()


def test_explicit_unusable_backend_is_a_typed_error(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("MUJOCO_GL", "wgl")
    with pytest.raises(RenderBackendUnavailableError, match="MUJOCO_GL"):
        select_gl_backend()


def test_a_backend_whose_library_is_missing_names_its_debian_package(monkeypatch: pytest.MonkeyPatch) -> None:
    from mjnav.sim.glbackend import missing_packages

    if "libosmesa6" not in missing_packages():
        pytest.skip("OSMesa is installed here")
    monkeypatch.setenv("MUJOCO_GL", "osmesa")
    with pytest.raises(RenderBackendUnavailableError, match="apt-get install libosmesa6"):
        select_gl_backend()


def test_the_video_shows_the_map_plan_path_goal_and_trail(backend: str) -> None:
    from mjnav.sim import Recorder

    sim = Simulator("rooms", seed=0, lidar=None)  # start (-3.5, -3.5), facing +x
    robot = sim.robot.root_body

    def colour_share(frame: np.ndarray, kind: str) -> float:
        """Share of pixels with the hue of ``kind``'s colour (lighting shades the overlay, so no exact match)."""
        r, g, b = (frame[..., i].astype(int) for i in range(3))
        hue = {
            "plan": (r > 170) & (r - b > 110) & (g > 80) & (g < r - 30),  # orange
            "path": (g > r + 50) & (g > b + 50),  # green
            "goal": (r > 140) & (g < 90) & (b < 90),  # red
            "trail": (b > r + 70) & (b > g + 20),  # blue
        }[kind]
        return float(hue.mean())

    with Recorder(sim.model, sim.data, None, width=320, height=240, camera="top", track_body=robot) as rec:
        bare = rec.render().copy()  # render() returns its own buffer
        ov = rec.overlay
        ov.track_trail = True
        ov.plan = np.array([[-3.5, -3.5], [-3.0, 0.0], [0.0, 2.0], [3.8, 2.2]])
        ov.path = ov.plan + np.array([0.0, 0.3])
        ov.goal = (3.8, 2.2)
        occupancy = np.zeros((40, 40), dtype=np.int8)
        occupancy[10:30, 10:30] = 100  # a 1 x 1 m mapped block: x in [1.5, 2.5], y in [-1.5, -0.5]
        ov.set_map(occupancy, (1.0, -2.0), 0.05)
        sim.set_command(0.5, 0.0)
        frames = []
        for _ in range(4):
            sim.set_command(0.5, 0.0)  # the watchdog stops a command older than 0.5 s
            sim.step_until(sim.time_s + 1.0)
            frames.append(rec.render().copy())
    last = frames[-1]
    for kind in ("plan", "path", "goal", "trail"):
        # Drawn: far more pixels of the item's colour than the world alone has (furniture, the heading marker).
        assert colour_share(last, kind) > colour_share(bare, kind) + 5e-4, kind
    assert len(ov.trail) == 4 and ov.trail[-1][0] > ov.trail[0][0] + 0.6  # a point per frame, following the robot
    # The mapped block is drawn dark where it is (top camera: image right = +x, up = +y; world centre mid-image).
    assert last[..., :3].astype(int).sum(axis=-1).min() < 200
    assert colour_share(frames[-1], "trail") > colour_share(frames[0], "trail")  # the trail grows
