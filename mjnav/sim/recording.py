"""Offscreen rendering of a running simulation into an H.264 MP4 (imageio-ffmpeg).

:class:`Recorder` renders the current ``MjData`` on demand (:meth:`Recorder.capture`); give it to
:class:`~mjnav.sim.runner.SimRunner` as a hook at its frame rate (:meth:`Recorder.add_to`) and any sim loop —
``mjnav record``, ``mjnav sim --record``, the sim service — records while it runs.

Speed: MSAA off (``offsamples = 0``), shadows and reflections off, one ``mjr_readPixels`` per frame; the
frames are piped to an ffmpeg child process (libx264, ``-preset veryfast``), which encodes on another core.

Cameras:
    ``top``: looks straight down on the whole world (the static geoms' bounds, or 10 m around the robot for a
        world without walls); image right = +x, image up = +y.
    ``follow``: a chase camera 2.8 m behind and 2.8 m above the robot, looking along its heading (high enough
        to see over 2 m shelves).
    any other name: a ``<camera>`` of the model.

Overlay (:class:`Overlay`, :attr:`Recorder.overlay`): what navigation knows, drawn into every frame as flat scene
geoms above the floor — the map's occupied cells (dark squares), the plan (orange), the smoothed path (green), the
goal (red disc) and the trail the tracked body drove (blue, extended at every frame). The sim service fills it from
``map``, ``plan``, ``path`` and ``goal``.
"""

from __future__ import annotations

import itertools
import math
import time
from collections.abc import Generator
from dataclasses import dataclass, field
from pathlib import Path
from types import TracebackType
from typing import TYPE_CHECKING, Any

import mujoco
import numpy as np
from numpy.typing import NDArray

from mjnav.sim.errors import RecordingError, RenderBackendUnavailableError
from mjnav.sim.glbackend import BACKENDS, select_gl_backend
from mjnav.sim.model import static_bounds

if TYPE_CHECKING:
    from mjnav.sim.runner import SimRunner


#: Overlay colours (RGBA, 0..1) and heights above the floor (m); tests look for the colours in the frames.
OVERLAY_RGBA = {
    "map": (0.15, 0.15, 0.15, 0.55),
    "plan": (1.0, 0.6, 0.0, 1.0),
    "path": (0.09, 0.78, 0.05, 1.0),
    "goal": (0.9, 0.1, 0.1, 0.9),
    "trail": (0.12, 0.47, 0.95, 1.0),
}
_OVERLAY_Z = {"map": 0.003, "plan": 0.012, "path": 0.016, "goal": 0.02, "trail": 0.008}
#: Scene geoms kept for the overlay beyond the model's own.
OVERLAY_GEOMS = 2000
#: The trail gets a point when the tracked body moved this far from the last one, metres.
TRAIL_SPACING_M = 0.1
#: Plan, path and trail are drawn with at most this many segments each (evenly decimated).
POLYLINE_SEGMENTS = 80


@dataclass
class Overlay:
    """Navigation state drawn into the video (map frame, metres).

    Attributes:
        boxes: (K, 4) the map's occupied cells merged into rectangles: centre x, y and half sizes, metres.
        plan: (N, 2) raw plan, or None.
        path: (M, 2) smoothed path, or None.
        goal: (x, y) of the goal, or None.
        trail: driven trail, extended by :meth:`Recorder.render` from the tracked body when ``track_trail``.
        track_trail: record and draw the tracked body's trail (off by default: a flying body's trail would lie on
            the floor).
    """

    boxes: NDArray[np.float64] = field(default_factory=lambda: np.zeros((0, 4)))
    plan: NDArray[np.float64] | None = None
    path: NDArray[np.float64] | None = None
    goal: tuple[float, float] | None = None
    trail: list[tuple[float, float]] = field(default_factory=list)
    track_trail: bool = False

    def set_map(self, occupancy: NDArray[np.int8], origin_m: tuple[float, float], resolution_m: float) -> None:
        """Take the occupied cells (value >= 65) of an (H, W) occupancy grid (row 0 = lowest y), merged into few
        rectangles (:func:`mjnav.sim.worldgen.merge_rectangles`)."""
        from mjnav.sim.worldgen import merge_rectangles

        rects = merge_rectangles(np.asarray(occupancy) >= 65).astype(np.float64)[: OVERLAY_GEOMS // 2]
        r, c, nr, nc = rects.T
        self.boxes = np.column_stack(
            (origin_m[0] + (c + 0.5 * nc) * resolution_m, origin_m[1] + (r + 0.5 * nr) * resolution_m,
             0.5 * nc * resolution_m, 0.5 * nr * resolution_m)
        )  # fmt: skip


def _decimate(xy: Any, max_segments: int) -> NDArray[np.float64]:
    """At most ``max_segments`` + 1 points of a polyline, evenly picked, first and last kept."""
    pts = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    if len(pts) <= max_segments + 1:
        return pts
    return pts[np.unique(np.linspace(0, len(pts) - 1, max_segments + 1).round().astype(int))]


def _gl_context(backend: str, width: int, height: int) -> Any:
    if backend == "egl":
        from mujoco.egl import GLContext
    elif backend == "osmesa":
        from mujoco.osmesa import GLContext
    else:
        from mujoco.glfw import GLContext
    return GLContext(width, height)


class Recorder:
    """Renders frames of a simulation offscreen and writes them to an MP4 file."""

    def __init__(
        self,
        model: mujoco.MjModel,
        data: mujoco.MjData,
        path: str | Path | None,
        *,
        fps: float = 30.0,
        width: int = 640,
        height: int = 480,
        camera: str = "top",
        track_body: int | None = None,
        crf: int = 23,
        backend: str | None = None,
    ) -> None:
        """Open the OpenGL context and the video writer.

        Args:
            model: the model (its ``vis.global_.offwidth/offheight`` are raised to the frame size if needed
                and ``vis.quality.offsamples`` is set to 0; physics is unaffected).
            data: the data to render; read at every :meth:`capture`.
            path: output ``.mp4`` path (parent folders are created); ``None`` = render only (no video,
                :meth:`capture` is an error).
            fps: frame rate written into the video, frames per second.
            width: frame width, pixels (even).
            height: frame height, pixels (even).
            camera: ``"top"``, ``"follow"`` or the name of a model camera.
            track_body: body the ``follow`` camera tracks (default: body 1, the first body after the world).
            crf: libx264 constant rate factor (0 = lossless … 51 = worst; 23 is ffmpeg's default).
            backend: ``"egl"``, ``"osmesa"`` or ``"glfw"``; default: chosen by
                :func:`~mjnav.sim.glbackend.select_gl_backend`.

        Raises:
            RecordingError: bad size, fps or camera, or ffmpeg cannot start.
            RenderBackendUnavailableError: no offscreen OpenGL backend works.
        """
        if width <= 0 or height <= 0 or width % 2 or height % 2:
            raise RecordingError(f"frame size must be positive and even (H.264 4:2:0), got {width}x{height}")
        if not (math.isfinite(fps) and fps > 0.0):
            raise RecordingError(f"fps must be positive, got {fps}")
        self.model = model
        self.data = data
        self.path = Path(path) if path is not None else None
        self.fps = float(fps)
        self.width = width
        self.height = height
        self.frames = 0
        self.render_s = 0.0
        self.write_s = 0.0
        self._closed = False
        self._follow = -1
        self._camera = self._make_camera(camera, track_body)
        self.backend = backend or select_gl_backend()
        glob = model.vis.global_
        glob.offwidth = max(int(glob.offwidth), width)
        glob.offheight = max(int(glob.offheight), height)
        model.vis.quality.offsamples = 0
        gl = None
        try:
            gl = _gl_context(self.backend, width, height)
            gl.make_current()
            self._context = mujoco.MjrContext(model, mujoco.mjtFontScale.mjFONTSCALE_100)
            self._gl = gl
        except Exception as exc:  # ImportError, GL errors, mujoco.FatalError: all mean "cannot render here"
            if gl is not None:
                gl.free()
            raise RenderBackendUnavailableError(
                f"cannot create an offscreen OpenGL context with {self.backend}: {exc}; "
                f"packages: {', '.join(f'{k}: {v}' for k, v in BACKENDS.items())}"
            ) from exc
        mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN, self._context)
        self._scene = mujoco.MjvScene(model, maxgeom=int(model.ngeom) + 256 + OVERLAY_GEOMS)
        #: What navigation knows, drawn over the world in every frame (see :class:`Overlay`).
        self.overlay = Overlay()
        self._track = track_body if track_body is not None else min(1, model.nbody - 1)
        self._scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = 0
        self._scene.flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = 0
        self._option = mujoco.MjvOption()
        self._perturb = mujoco.MjvPerturb()
        self._rect = mujoco.MjrRect(0, 0, width, height)
        self._pixels = np.empty((height, width, 3), dtype=np.uint8)
        self._writer: Generator[None, bytes | None, None] | None = None
        if self.path is not None:
            try:
                self.path.parent.mkdir(parents=True, exist_ok=True)
                self._writer = self._open_writer(crf)
            except Exception:
                self._closed = True  # nothing to flush: free the GL resources now, not never
                self._context.free()
                self._gl.free()
                raise

    # ----------------------------------------------------------------- setup
    def _make_camera(self, camera: str, track_body: int | None) -> mujoco.MjvCamera:
        m = self.model
        cam = mujoco.MjvCamera()
        if camera == "top":
            mujoco.mj_kinematics(m, self.data)
            bounds = static_bounds(m, self.data)
            if bounds is None:
                body = track_body if track_body is not None else min(1, m.nbody - 1)
                x, y = (float(v) for v in self.data.xpos[body][:2])
                bounds = (x - 5.0, y - 5.0, x + 5.0, y + 5.0)
            x0, y0, x1, y1 = bounds
            aspect = self.width / self.height
            half_h = 1.05 * max(0.5 * (y1 - y0), 0.5 * (x1 - x0) / aspect)
            fovy = math.radians(float(m.vis.global_.fovy))
            cam.type = mujoco.mjtCamera.mjCAMERA_FREE
            cam.lookat[:] = (0.5 * (x0 + x1), 0.5 * (y0 + y1), 0.0)
            cam.distance = half_h / math.tan(0.5 * fovy)
            cam.azimuth = 90.0
            cam.elevation = -90.0
        elif camera == "follow":
            cam.type = mujoco.mjtCamera.mjCAMERA_TRACKING
            cam.trackbodyid = track_body if track_body is not None else min(1, m.nbody - 1)
            cam.distance = 4.0
            cam.azimuth = 0.0
            cam.elevation = -45.0
            self._follow = int(cam.trackbodyid)
        else:
            cid = int(mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_CAMERA, camera))
            if cid < 0:
                names = [m.camera(i).name for i in range(m.ncam)]
                raise RecordingError(f"unknown camera {camera!r}: use 'top', 'follow' or one of {names}")
            cam.type = mujoco.mjtCamera.mjCAMERA_FIXED
            cam.fixedcamid = cid
        return cam

    def _open_writer(self, crf: int) -> Generator[None, bytes | None, None]:
        import imageio_ffmpeg

        assert self.path is not None
        try:
            writer: Generator[None, bytes | None, None] = imageio_ffmpeg.write_frames(
                str(self.path),
                (self.width, self.height),
                fps=self.fps,
                codec="libx264",
                pix_fmt_in="rgb24",
                pix_fmt_out="yuv420p",
                quality=None,
                macro_block_size=2,
                output_params=["-crf", str(int(crf)), "-preset", "veryfast"],
            )
            writer.send(None)
        except Exception as exc:
            raise RecordingError(f"cannot start ffmpeg for {self.path}: {exc}") from exc
        return writer

    # ----------------------------------------------------------------- frames
    def render(self) -> NDArray[np.uint8]:
        """Render the current state and return the frame, (height, width, 3) uint8 RGB, top row first."""
        if self._closed:
            raise RecordingError("the recorder is closed")
        t0 = time.perf_counter()
        self._gl.make_current()
        if self._follow >= 0:
            rot = self.data.xmat[self._follow]
            self._camera.azimuth = math.degrees(math.atan2(float(rot[3]), float(rot[0])))
        mujoco.mjv_updateScene(
            self.model,
            self.data,
            self._option,
            self._perturb,
            self._camera,
            mujoco.mjtCatBit.mjCAT_ALL,
            self._scene,
        )
        self._draw_overlay()
        mujoco.mjr_render(self._rect, self._scene, self._context)
        mujoco.mjr_readPixels(self._pixels, None, self._rect, self._context)
        frame = self._pixels[::-1]
        self.render_s += time.perf_counter() - t0
        return frame

    def _add_geom(self, kind: str) -> mujoco.MjvGeom | None:
        scn = self._scene
        if scn.ngeom >= scn.maxgeom:
            return None
        geom = scn.geoms[scn.ngeom]
        scn.ngeom += 1
        mujoco.mjv_initGeom(
            geom, mujoco.mjtGeom.mjGEOM_BOX, np.zeros(3), np.zeros(3), np.eye(3).ravel(),
            np.asarray(OVERLAY_RGBA[kind], dtype=np.float32),
        )  # fmt: skip
        geom.category = mujoco.mjtCatBit.mjCAT_DECOR
        return geom

    def _polyline(self, kind: str, xy: Any, width_px: float) -> None:
        pts = _decimate(xy, POLYLINE_SEGMENTS)
        z = _OVERLAY_Z[kind]
        for a, b in itertools.pairwise(pts):
            if not np.any(a != b):
                continue
            geom = self._add_geom(kind)
            if geom is None:
                return
            mujoco.mjv_connector(geom, mujoco.mjtGeom.mjGEOM_LINE, width_px, (a[0], a[1], z), (b[0], b[1], z))

    def _draw_overlay(self) -> None:
        """Append the overlay's geoms to the scene (after ``mjv_updateScene``); the trail grows from the tracked
        body's position."""
        ov = self.overlay
        if ov.track_trail:
            x, y = (float(v) for v in self.data.xpos[self._track][:2])
            if not ov.trail or math.dist(ov.trail[-1], (x, y)) >= TRAIL_SPACING_M:
                ov.trail.append((x, y))
        for cx, cy, hx, hy in ov.boxes:
            geom = self._add_geom("map")
            if geom is None:
                break
            geom.size[:] = (hx, hy, 0.002)
            geom.pos[:] = (cx, cy, _OVERLAY_Z["map"])
        self._polyline("trail", ov.trail, 4.0)  # lines: widths in pixels, cheap to render
        if ov.plan is not None:
            self._polyline("plan", ov.plan, 3.0)
        if ov.path is not None:
            self._polyline("path", ov.path, 3.0)
        if ov.goal is not None:
            geom = self._add_geom("goal")
            if geom is not None:
                geom.type = mujoco.mjtGeom.mjGEOM_CYLINDER
                geom.size[:] = (0.2, 0.2, 0.005)
                geom.pos[:] = (ov.goal[0], ov.goal[1], _OVERLAY_Z["goal"])

    def capture(self) -> None:
        """Render the current state and append it to the video."""
        if self._writer is None:
            raise RecordingError("this recorder renders only (path=None); there is no video to append to")
        frame = self.render()
        t0 = time.perf_counter()
        try:
            self._writer.send(np.ascontiguousarray(frame).tobytes())
        except (OSError, StopIteration, RuntimeError) as exc:
            raise RecordingError(f"ffmpeg failed while writing {self.path}: {exc}") from exc
        self.write_s += time.perf_counter() - t0
        self.frames += 1

    def hook(self, sim: object) -> None:
        """:class:`~mjnav.sim.runner.SimRunner` hook: capture one frame (the argument is ignored)."""
        self.capture()

    def add_to(self, runner: SimRunner) -> None:
        """Register :meth:`hook` on ``runner`` at this recorder's frame rate."""
        runner.add_hook(self.hook, 1.0 / self.fps)

    @property
    def render_fps(self) -> float:
        """Frames rendered per second of rendering time (excludes encoding), or 0 before the first frame."""
        return self.frames / self.render_s if self.render_s > 0.0 else 0.0

    # ------------------------------------------------------------------ close
    def close(self) -> None:
        """Finish the video (flushes ffmpeg) and free the OpenGL context; idempotent."""
        if self._closed:
            return
        self._closed = True
        try:
            if self._writer is not None:
                self._writer.close()
        except Exception as exc:
            raise RecordingError(f"ffmpeg failed to finish {self.path}: {exc}") from exc
        finally:
            try:
                self._gl.make_current()
                self._context.free()
            finally:
                self._gl.free()

    def __enter__(self) -> Recorder:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()
