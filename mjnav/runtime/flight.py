"""A UAV flight driven over the bus: arm, stream a trajectory, land, and score the flight.

:class:`FlightClient` is what ``mjnav fly`` and the UAV service tests use. It is a lockstep participant (like
:class:`~mjnav.runtime.mission.MissionClient`): it steps in the clock's callback every ``period_s`` of sim time, and
arms, streams the trajectory (the whole time-stamped ``nav_msgs/Path``, re-sent every ``resend_s`` as PX4-style proof
of life), lands and measures only in those steps, so a flight is repeatable to the last bit. It measures the true
position (``ground_truth``) against the reference, the INS estimate (``ins_odom``) and the GPS fixes (``gps``)
against the truth at their stamps, all in sim time.

The reference it streams is a :class:`~mjnav.aerial.trajectories.FlightPlan` (``mjnav.aerial``: the trajectories
are algorithms, not runtime).
"""

from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from mjnav.aerial.trajectories import FlightPlan
from mjnav.bus import Bus
from mjnav.jsonsafe import json_safe
from mjnav.msgs import ros
from mjnav.msgs import uav as uav_msgs
from mjnav.runtime.participant import LockstepParticipant

#: Sample spacing of the streamed trajectory, s.
TRAJECTORY_DT_S = 0.05
#: Each send covers the reference from this long before the send to ``TRAJECTORY_AHEAD_S`` after it, s.
TRAJECTORY_BEHIND_S = 0.2
TRAJECTORY_AHEAD_S = 2.0


@dataclass
class FlightSummary:
    """The figures ``mjnav fly --json`` prints (see README)."""

    rms_error_m: float
    max_error_m: float
    ins_rms_m: float
    gps_rms_m: float
    time_s: float
    achieved_rtf: float
    seed: int | None = None
    trajectory: str = ""
    controller: str = ""
    state: str = ""
    wind_mps: float = 0.0
    gust_mps: float = 0.0
    landed: bool = False
    collisions: int = 0
    final_state: str = ""
    samples: int = 0
    wall_s: float = math.nan

    def to_dict(self) -> dict[str, Any]:
        """JSON-friendly dict: floats rounded to 0.1 mm / 0.1 ms, non-finite floats as None."""
        d = asdict(self)
        for k, v in d.items():
            if isinstance(v, float) and math.isfinite(v):
                d[k] = round(v, 4)
        return json_safe(d)


@dataclass
class _Record:
    truth: dict[int, np.ndarray] = field(default_factory=dict)  # stamp (ns) -> true position (ENU)
    ins: list[tuple[int, np.ndarray]] = field(default_factory=list)
    gps: list[tuple[int, np.ndarray]] = field(default_factory=list)
    states: list[tuple[float, str]] = field(default_factory=list)


def _ns(t: float) -> int:
    return round(t * 1e9)


class FlightClient(LockstepParticipant):
    """Arms the UAV, streams a :class:`FlightPlan`, lands it and scores the flight (a lockstep participant).

    Args:
        bus: a bus in the UAV's namespace.
        origin: (lat deg, lon deg, alt m) of the local ENU frame (the sim's), to read the GPS fixes.
        name: the participant's name (the sim must list it in ``lockstep_participants``).
        period_s: the client's step, sim seconds (the UAV clock's period).
        resend_s: how often the trajectory is re-sent (proof of life for the failsafe), sim seconds.
    """

    def __init__(
        self,
        bus: Bus,
        origin: tuple[float, float, float],
        *,
        name: str = "flight",
        period_s: float = 0.02,
        resend_s: float = 0.2,
    ) -> None:
        self._init_participant(bus, name, period_s)
        self.origin = origin
        self.resend_s = resend_s
        self._rec = _Record()
        self._job: dict[str, Any] | None = None
        self.sim_status = bus.subscribe("sim_status")
        self.flight_state = bus.subscribe("flight_state", callback=self._on_state)
        bus.subscribe("ground_truth", callback=self._on_truth)
        bus.subscribe("ins_odom", callback=self._on_ins)
        bus.subscribe("gps", callback=self._on_gps)
        self.arm_pub = bus.publisher("arm")
        self.trajectory_pub = bus.publisher("trajectory")
        self._subscribe_clock()

    # ----------------------------------------------------------------------------------------- measurements

    def _on_truth(self, msg: Any) -> None:
        with self._lock:
            self._rec.truth[_ns(ros.seconds(msg.header.stamp))] = uav_msgs.position(msg.pose)

    def _on_ins(self, msg: Any) -> None:
        from mjnav.aerial.rep103 import ned_to_enu

        p = uav_msgs.position(msg.pose.pose)
        if msg.header.frame_id == "map_ned":
            p = ned_to_enu(p)
        with self._lock:
            self._rec.ins.append((_ns(ros.seconds(msg.header.stamp)), p))

    def _on_gps(self, msg: Any) -> None:
        from mjnav.aerial import geodetic_to_enu

        e, n, u = geodetic_to_enu(msg.latitude, msg.longitude, msg.altitude, *self.origin)
        with self._lock:
            self._rec.gps.append((_ns(ros.seconds(msg.header.stamp)), np.array([e, n, u], dtype=np.float64)))

    def _on_state(self, msg: Any) -> None:
        with self._lock:
            if not self._rec.states or self._rec.states[-1][1] != msg.data:
                self._rec.states.append((self._now, msg.data))

    def state(self) -> str:
        """The flight controller's newest state ("" before the first)."""
        with self._lock:
            return self._rec.states[-1][1] if self._rec.states else ""

    def states(self) -> list[tuple[float, str]]:
        """(sim time received, state) at every change of ``flight_state``."""
        with self._lock:
            return list(self._rec.states)

    def truth_track(self) -> tuple[np.ndarray, np.ndarray]:
        """(stamps (N,) s, true positions (N, 3) ENU m) received so far."""
        with self._lock:
            keys = sorted(self._rec.truth)
            pts = np.array([self._rec.truth[k] for k in keys]).reshape(-1, 3)
        return np.array(keys, dtype=np.float64) / 1e9, pts

    # ----------------------------------------------------------------------------------------------- steps

    def _step(self, t: float) -> None:
        job = self._job
        if job is None or job["done"]:
            return
        if job["t0"] is None:
            job["t0"] = t
            job["wall0"] = time.monotonic()
        rel = t - job["t0"]
        plan: FlightPlan = job["plan"]
        state = self._rec.states[-1][1] if self._rec.states else ""
        if job["phase"] == "arm":
            if state in ("armed", "offboard"):
                job["phase"] = "fly"
            elif rel >= job["next_arm"]:
                self.arm_pub.put(uav_msgs.boolean(True))
                job["next_arm"] = rel + 0.5
        if job["phase"] == "fly" and rel >= job["next_send"]:
            stream_until = job["stream_until_s"]
            if rel < plan.end_s and (stream_until is None or rel < stream_until):
                lo = max(plan.start_s, rel - TRAJECTORY_BEHIND_S)
                ts = np.arange(lo, min(plan.end_s, rel + TRAJECTORY_AHEAD_S) + 1e-9, TRAJECTORY_DT_S)
                self.trajectory_pub.put(uav_msgs.trajectory("map", job["t0"] + ts, plan.reference(ts), t_s=t))
                job["next_send"] = rel + self.resend_s
            elif rel >= plan.end_s:
                job["phase"] = "land"
                self.arm_pub.put(uav_msgs.boolean(False))
                job["land_at"] = rel
        if job["phase"] in ("fly", "land") and state == "disarmed" and rel > plan.start_s + 1.0:
            job["done"] = True
        if rel >= job["timeout_s"]:
            job["done"] = True
        if job["done"]:
            job["t_end"] = t
            job["wall_end"] = time.monotonic()

    def fly(
        self,
        plan: FlightPlan,
        *,
        timeout_s: float,
        wall_timeout_s: float = math.inf,
        stream_until_s: float | None = None,
    ) -> FlightSummary:
        """Fly ``plan`` (times relative to the client's first step): arm, stream, land; score it.

        Args:
            plan: the reference.
            timeout_s: sim seconds after which the flight ends whatever the vehicle does.
            wall_timeout_s: bound on the wall-time wait (a stalled sim must not hang the caller).
            stream_until_s: stop streaming the trajectory at this time (relative, s) and never command the landing
                (to exercise the failsafe); None: stream to the end and land.

        Raises:
            RuntimeError: nobody subscribes to the trajectory (no flight controller) within 10 s.
        """
        if not self.trajectory_pub.wait_for_subscribers(10.0):
            raise RuntimeError(f"nobody subscribes to {self.bus.key('trajectory')}: is the flight controller running?")
        job: dict[str, Any] = {
            "plan": plan,
            "phase": "arm",
            "next_arm": 0.0,
            "next_send": 0.0,
            "stream_until_s": stream_until_s,
            "timeout_s": timeout_s,
            "t0": None,
            "done": False,
        }
        with self._lock:
            self._job = job
        self._participate()
        deadline = time.monotonic() + wall_timeout_s
        with self._lock:
            while not job["done"] and time.monotonic() < deadline:
                self._lock.wait(0.5)
            if not job["done"]:
                job["done"] = True
                job["t_end"], job["wall_end"] = self._now, time.monotonic()
            self._job = None
        return self._score(job)

    def _score(self, job: dict[str, Any]) -> FlightSummary:
        plan: FlightPlan = job["plan"]
        t0 = job["t0"] if job["t0"] is not None else math.nan
        with self._lock:
            rec = self._rec
            lo, hi = _ns(t0 + plan.measure_from_s), _ns(t0 + plan.measure_to_s)
            keys = sorted(k for k in rec.truth if lo <= k <= hi)
            truth = np.array([rec.truth[k] for k in keys]).reshape(-1, 3)
            ins = [(k, p) for k, p in rec.ins if lo <= k <= hi and k in rec.truth]
            gps = [(k, p) for k, p in rec.gps if lo <= k <= hi and k in rec.truth]
            ins_err = [float(np.linalg.norm(p - rec.truth[k])) for k, p in ins]
            gps_err = [float(np.linalg.norm(p - rec.truth[k])) for k, p in gps]
            states = list(rec.states)
        ref = plan.reference(np.array(keys, dtype=np.float64) / 1e9 - t0) if keys else np.zeros((0, 3))
        err = np.linalg.norm(truth - ref, axis=1) if keys else np.zeros(0)

        def rms(e: Any) -> float:
            return math.sqrt(float(np.mean(np.square(e)))) if len(e) else math.nan

        wall = job.get("wall_end", math.nan) - job.get("wall0", math.nan)
        sim = job.get("t_end", math.nan) - t0
        status = self.sim_status.latest()
        return FlightSummary(
            rms_error_m=rms(err),
            max_error_m=float(err.max()) if err.size else math.nan,
            ins_rms_m=rms(ins_err),
            gps_rms_m=rms(gps_err),
            time_s=sim,
            achieved_rtf=sim / wall if wall > 0 else math.nan,
            trajectory=plan.name,
            landed=bool(states) and states[-1][1] == "disarmed",
            collisions=0 if status is None else int(status.collisions),
            final_state=states[-1][1] if states else "",
            samples=len(keys),
        )
