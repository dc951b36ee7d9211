"""``mjnav up``: an in-process Zenoh router plus the stack's services in supervised child processes.

The router listens on ``tcp/127.0.0.1:<port>`` (``tls/…`` with mutual TLS and access control when ``secure``
names a ``mjnav certs`` folder). Each process of the deployment (:meth:`mjnav.runtime.stack.Stack.processes`: the
services of a ``[[container]]`` together, every other service alone) runs as ``python -m mjnav run <names>``
connected to it, with its output prefixed ``[name]``. A process that exits on its own is restarted (bounded by its
``restarts`` in the stack file, with exponential back-off); so is a hung one — a running process one of whose
services' status heartbeat (``<ns>/status/<service>``, every wall second) stopped for ``hung_timeout_s``, or whose
liveliness token vanished — which is killed first. A container restarts as a unit: its services share a process,
so one hung service takes its siblings down with it, and all of them resume from the run's checkpoints. With
``secure`` every service runs alone (a process has one identity, and access control grants each service its own
topics). On SIGINT/SIGTERM, or after ``duration_s``, the processes are stopped in reverse start order (SIGTERM,
then SIGKILL after a grace period) and the launcher returns 0; a second signal kills everything at once.

Start-up: with ``fork_services`` (``mjnav up``, ``mjnav demo``, ``mjnav fly``) the launcher imports what every
service needs once (:data:`PRELOAD_MODULES`, the service classes, numba's compiler target) and forks each service's
first process from itself, before it opens any Zenoh session or starts a thread; the children then skip the
interpreter start, the imports and numba's set-up (most of a service's start-up). A restart always executes a fresh
``python -m mjnav run <names>``: once the router runs, the launcher holds Zenoh's threads, which a fork must not copy.
"""

from __future__ import annotations

import contextlib
import ctypes
import importlib
import json
import logging
import os
import re
import select
import shutil
import signal
import socket
import stat
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, fields
from pathlib import Path
from types import FrameType
from typing import IO, Any, Protocol

from mjnav.bus import Bus, BusConfig, BusUnavailable
from mjnav.bus.acl import secure_router_config
from mjnav.bus.config import tls_env
from mjnav.runtime.config import ConfigError, parse_override
from mjnav.runtime.service import STATE_DIR_ENV
from mjnav.runtime.stack import ProcessSpec, Stack

log = logging.getLogger("mjnav.up")

#: Seconds a service gets to stop after SIGTERM before it is killed.
STOP_GRACE_S = 5.0
#: First restart delay; doubles with every restart of the same service.
RESTART_BACKOFF_S = 0.5
#: Default wall seconds without a status heartbeat (sent every second) after which a running service counts as hung.
HUNG_TIMEOUT_S = 5.0
#: Wall seconds a service may stay silent before it reported its first step: the first calls of numba kernels compile
#: them (tens of seconds for SLAM on a fresh checkout, whose caches are cold), which is starting, not hanging.
FIRST_STEP_TIMEOUT_S = 120.0


#: Modules every forked service needs besides its own class (imported once by the launcher, see ``fork_services``):
#: what builds and runs the child's services, and the packages services import lazily in ``configure``.
PRELOAD_MODULES = ("mjnav.runtime.process", "mjnav.runtime.logs", "mjnav.sim", "mjnav.viz", "numba")


#: prctl option: the signal a process gets when its parent dies (linux/prctl.h).
_PR_SET_PDEATHSIG = 1
#: prctl option: the calling thread's name (``comm``, 15 bytes), which ps and top show (linux/prctl.h).
_PR_SET_NAME = 15


def _prime_numba() -> None:
    """Set up numba's compiler target (its registries: most of the cost of a process's first kernel call, even when
    the kernel comes from the cache) by compiling a trivial function, so forked services inherit it."""
    import numba

    numba.njit(lambda: 0)()


def _name_process(name: str) -> None:
    """Name this process ``name`` in ps/top (``comm``; Linux; elsewhere a no-op)."""
    if sys.platform.startswith("linux"):
        ctypes.CDLL(None).prctl(_PR_SET_NAME, name.encode()[:15])


def _die_with_parent(parent_pid: int) -> Callable[[], None]:
    """A ``preexec_fn`` that makes the child get SIGTERM when the launcher dies, however it dies (``kill -9``
    included), so no service outlives it (Linux ``PR_SET_PDEATHSIG``; elsewhere a no-op)."""

    def preexec() -> None:
        if not sys.platform.startswith("linux"):
            return
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(_PR_SET_PDEATHSIG, signal.SIGTERM)
        if os.getppid() != parent_pid:  # the launcher died before the request took effect
            os._exit(1)

    return preexec


#: A run's state directory in the temp folder: ``mjnav-state-<launcher pid>-<its start time>-<random>``; the owner in
#: the name lets a later launcher remove what one that died (``kill -9``) left behind (:func:`make_state_dir`).
_STATE_DIR = re.compile(r"mjnav-state-(\d+)-(\d+)-")


def _started(pid: int) -> int | None:
    """When process ``pid`` started (clock ticks since boot, from Linux's /proc), None when no process has that pid
    or it is a zombie (dead, not yet reaped)."""
    try:
        text = Path(f"/proc/{pid}/stat").read_text()
    except (FileNotFoundError, ProcessLookupError):
        return None
    fields = text[text.rindex(")") + 2 :].split()  # after the command name, which may hold spaces and brackets
    return None if fields[0] == "Z" else int(fields[19])  # stat fields 3 (state) and 22 (starttime)


def make_state_dir() -> str:
    """A new state directory for this run in the temp folder (mode 0700), named after this process's pid and start
    time; first removes the leftovers of launchers that are gone (:func:`remove_leftover_state_dirs`)."""
    remove_leftover_state_dirs()
    pid = os.getpid()
    return tempfile.mkdtemp(prefix=f"mjnav-state-{pid}-{_started(pid) or 0}-")


def remove_leftover_state_dirs() -> list[Path]:
    """Remove this user's state directories in the temp folder whose launcher is gone — no process has its pid, or
    the one that has it started at another time: a launcher killed with -9 cannot remove its own —; returns them.
    Never one of a live process, nor one whose name does not say its owner; nothing at all without /proc (not
    Linux), where a live owner cannot be told from a dead one."""
    if not Path("/proc/self/stat").exists():
        return []
    removed = []
    for path in sorted(Path(tempfile.gettempdir()).glob("mjnav-state-*")):
        match = _STATE_DIR.match(path.name)
        if match is None or _started(int(match[1])) == int(match[2]):
            continue
        try:
            info = path.lstat()
            if not stat.S_ISDIR(info.st_mode) or info.st_uid != os.getuid():
                continue
            shutil.rmtree(path)
        except FileNotFoundError:  # another launcher starting at the same time removed it
            continue
        except OSError as exc:
            log.warning("leftover state directory %s not removed: %s", path, exc)
            continue
        log.info("removed %s, the state directory of launcher %s, which is gone", path, match[1])
        removed.append(path)
    return removed


class _Process(Protocol):
    """What the launcher needs of a service process: a :class:`subprocess.Popen` or a :class:`_ForkedProcess`."""

    pid: int
    returncode: int | None
    stdout: IO[str] | None

    def poll(self) -> int | None: ...

    def wait(self, timeout: float | None = None) -> int: ...

    def send_signal(self, sig: int) -> None: ...

    def kill(self) -> None: ...


class _ForkedProcess:
    """A service process forked from the launcher, with the part of :class:`subprocess.Popen`'s interface the
    launcher uses.

    Args:
        pid: the child's process id.
        stdout: read end of the pipe the child's stdout and stderr go to.
    """

    def __init__(self, pid: int, stdout: IO[str]) -> None:
        self.pid = pid
        self.stdout: IO[str] | None = stdout
        self.returncode: int | None = None

    def poll(self) -> int | None:
        """The exit code once the child exited (it is reaped then), else None."""
        if self.returncode is None:
            try:
                pid, status = os.waitpid(self.pid, os.WNOHANG)
            except ChildProcessError:  # reaped elsewhere: its code is lost
                self.returncode = -1
                return self.returncode
            if pid == self.pid:
                self.returncode = os.waitstatus_to_exitcode(status)
        return self.returncode

    def wait(self, timeout: float | None = None) -> int:
        """Wait for the child to exit; its exit code (negative: the signal that ended it).

        Raises:
            subprocess.TimeoutExpired: still running after ``timeout`` seconds.
        """
        if self.poll() is not None:
            return self.returncode  # type: ignore[return-value]
        if timeout is None:
            _, status = os.waitpid(self.pid, 0)
            self.returncode = os.waitstatus_to_exitcode(status)
            return self.returncode
        fd = os.pidfd_open(self.pid)  # readable once the child exits: no polling loop
        try:
            if not select.select([fd], [], [], timeout)[0]:
                raise subprocess.TimeoutExpired(f"pid {self.pid}", timeout)
        finally:
            os.close(fd)
        code = self.poll()
        assert code is not None
        return code

    def send_signal(self, sig: int) -> None:
        """Send ``sig`` unless the child was reaped (its pid may belong to another process by then)."""
        if self.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                os.kill(self.pid, sig)

    def kill(self) -> None:
        """SIGKILL."""
        self.send_signal(signal.SIGKILL)


@dataclass
class _Child:
    """One supervised process and what its services last said."""

    spec: ProcessSpec
    proc: _Process | None = None
    restarts: int = 0
    restart_at: float | None = None
    gave_up: bool = False
    pumps: list[threading.Thread] = field(default_factory=list)
    last_status: dict[str, float] = field(default_factory=dict)  # service -> wall time of its newest heartbeat
    stepped: set[str] = field(default_factory=set)  # services that reported a step (else FIRST_STEP_TIMEOUT_S)
    alive: set[str] = field(default_factory=set)  # services whose liveliness token came up in this process

    @property
    def name(self) -> str:
        return self.spec.name


def _probe_port(port: int, what: str, hint: str) -> None:
    """Raise :class:`ConfigError` when ``port`` on 127.0.0.1 cannot be bound (``what`` wants it; ``hint``: the way
    out)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            probe.bind(("127.0.0.1", port))
        except OSError as exc:
            raise ConfigError(f"port {port} for {what} in use ({exc.strerror}): {hint}") from exc


class Launcher:
    """Supervises the router and the services of one stack.

    Args:
        stack: the stack definition.
        only: service names to run (None = all).
        namespace: robot namespace (default: the stack's).
        port: router port on 127.0.0.1.
        duration_s: stop after this many wall seconds (None = until a signal).
        overrides: per-service ``--set`` values, ``{"sim": ["world=maze"]}``.
        extra_env: environment variables added for every service.
        out: where prefixed child output goes (default stdout).
        lockstep: run the sim in lockstep with the services on sim time (False: free-running).
        extra_participants: lockstep participants besides the services (e.g. ``mjnav demo``'s mission client);
            sim time starts once all of them are present.
        seed: seed every service that has a ``seed`` setting (the sim's noise, the planner's randomness).
        hung_timeout_s: wall seconds without a status heartbeat from a running service (once it sent one and
            reported a step; before its first step :data:`FIRST_STEP_TIMEOUT_S`) after which it is killed and
            restarted.
        secure: folder of ``mjnav certs`` certificates: the router listens on ``tls/127.0.0.1:<port>`` with mutual
            TLS and the stack's access control (:mod:`mjnav.bus.acl`); each service connects with its own
            certificate. None: plain TCP on loopback, no access control.
        fork_services: start each process the first time by forking this one after importing what the services
            need (see the module's docs). Only for a process that has not opened a Zenoh session and runs no other
            threads when :meth:`spawn` (or :meth:`run`) forks: the launcher of ``mjnav up``, ``mjnav demo``.
        packed: run the services of each of the stack's containers in one process (False: every service in a
            process of its own). Ignored with ``secure``.
    """

    def __init__(
        self,
        stack: Stack,
        *,
        only: Sequence[str] | None = None,
        namespace: str | None = None,
        port: int = 7447,
        duration_s: float | None = None,
        overrides: dict[str, list[str]] | None = None,
        extra_env: dict[str, str] | None = None,
        out: IO[str] | None = None,
        lockstep: bool = True,
        extra_participants: Sequence[str] = (),
        seed: int | None = None,
        hung_timeout_s: float = HUNG_TIMEOUT_S,
        secure: str | Path | None = None,
        fork_services: bool = False,
        packed: bool = True,
    ) -> None:
        if not hung_timeout_s > 0:
            raise ValueError(f"hung_timeout_s must be > 0, got {hung_timeout_s}")
        self.hung_timeout_s = hung_timeout_s
        self.stack = stack
        self.specs = stack.select(list(only) if only else None)
        self.namespace = namespace or stack.namespace
        self.port = port
        self.duration_s = duration_s
        self.overrides = {name: list(items) for name, items in (overrides or {}).items()}
        self._add_run_settings(lockstep, extra_participants, seed)
        self.extra_env = extra_env or {}
        self.out = out or sys.stdout
        self.processes = stack.processes(self.specs, packed=packed and secure is None)
        self.children = [_Child(proc) for proc in self.processes]
        self.stop_event = threading.Event()
        self._out_lock = threading.Lock()
        self._signals = 0
        self._alive: set[str] = set()
        self._lock = threading.Lock()  # child heartbeat fields, written from Zenoh callbacks
        self.state_dir: str | None = None  # this run's checkpoints (see Service.state_dir), while running
        self.fork_services = fork_services
        self._spawned = False
        self._go_write: int | None = None  # the forked services start when it is closed (see spawn)
        #: Set once :meth:`run` opened the router (or failed to): a client may connect then without waiting out
        #: Zenoh's connect retry period.
        self.router_ready = threading.Event()
        self.secure = Path(secure) if secure is not None else None
        if self.secure is not None:
            for spec in self.specs:
                tls_env(self.secure, spec.name)  # every certificate is there before anything starts
        self._router_config = (
            secure_router_config(self.secure, [self.endpoint], self.namespace, stack.names(), extra_participants)
            if self.secure is not None
            else BusConfig(mode="router", connect=(), listen=(self.endpoint,))
        )

    def _add_run_settings(self, lockstep: bool, extra_participants: Sequence[str], seed: int | None) -> None:
        """The run's lockstep and seed settings, put before the caller's overrides so that an explicit ``--set``
        wins. Nothing about the robot or the world: the services learn those from the sim over the bus, as they
        do when they run alone (``mjnav run``, a container)."""
        classes = {spec.name: spec.load_class() for spec in self.specs}
        for name, cls in classes.items():
            settings = []
            declared = {f.name for f in fields(cls.config_class)}
            if seed is not None and "seed" in declared:
                settings.append(f"seed={int(seed)}")
            if "lockstep_participants" in declared:  # the stack's sim
                participants = [n for n, c in classes.items() if c.uses_sim_time] + list(extra_participants)
                settings += [f"lockstep={json.dumps(lockstep)}", f"lockstep_participants={json.dumps(participants)}"]
            self.overrides[name] = settings + self.overrides.get(name, [])

    def check(self) -> None:
        """Validate everything before anything starts: every service's config file with its overrides (unknown
        keys, wrong types, bad values such as an unknown world), and the router port.

        Raises:
            ConfigError: one line naming the service, file or setting, or the taken port.
        """
        for spec in self.specs:
            overrides = dict(parse_override(item) for item in self.overrides.get(spec.name, []))
            known = {f.name for f in fields(spec.load_class().config_class)}
            for key in overrides:
                if key not in known:
                    raise ConfigError(
                        f"--set {spec.name}.{key}: {spec.name} has no setting {key!r}; valid: {sorted(known)}"
                    )
            try:
                spec.load_config(overrides)
            except ConfigError as exc:
                raise ConfigError(f"{spec.name}: {exc}") from exc
        if not 0 < self.port < 65536:
            raise ConfigError(f"--port must be 1..65535, got {self.port}")
        _probe_port(self.port, "the router", "use --port")
        for spec in self.specs:  # the ports the services listen on, unless they may search for a free one
            cls = spec.load_class()
            cfg = spec.load_config(dict(parse_override(item) for item in self.overrides.get(spec.name, [])))
            if getattr(cfg, "port_search", 0):
                continue
            for key in cls.port_settings:
                port = int(getattr(cfg, key))
                if port:
                    _probe_port(port, f"{spec.name}.{key}", "choose another --port base or --set it")

    @property
    def endpoint(self) -> str:
        """The router endpoint services connect to."""
        return f"{'tls' if self.secure is not None else 'tcp'}/127.0.0.1:{self.port}"

    # ------------------------------------------------------------------------------------------- child process

    def _command(self, spec: ProcessSpec) -> list[str]:
        cmd = [
            sys.executable,
            "-m",
            "mjnav",
            "run",
            *spec.service_names(),
            "--stack",
            str(self.stack.path),
            "--ns",
            self.namespace,
            # Client mode: every message between processes goes through the router, one link per process, so each
            # process receives a publisher's messages in the order they were sent (what lockstep relies on).
            "--mode",
            "client",
            "--connect",
            self.endpoint,
        ]
        for item in self._set_items(spec):
            cmd += ["--set", item]
        return cmd

    def _set_items(self, spec: ProcessSpec) -> list[str]:
        """The ``--set`` items of the process ``spec``: ``SERVICE.KEY=VALUE``."""
        return [f"{s}.{item}" for s in spec.service_names() for item in self.overrides.get(s, [])]

    def _env(self) -> dict[str, str]:
        env = {k: v for k, v in os.environ.items() if not k.startswith("MJNAV_ZENOH_")}
        env["PYTHONUNBUFFERED"] = "1"
        if self.state_dir is not None:
            env[STATE_DIR_ENV] = self.state_dir
        env.update(self.extra_env)
        return env

    def _start(self, child: _Child) -> None:
        """Start ``child`` as a fresh ``python -m mjnav run`` (a restart, or every start without ``fork_services``)."""
        proc = subprocess.Popen(
            self._command(child.spec),
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            stdin=subprocess.DEVNULL,
            text=True,
            bufsize=1,
            env=self._child_env(child.spec),
            start_new_session=True,  # Ctrl-C reaches the launcher only; it stops the services in order
            preexec_fn=_die_with_parent(os.getpid()),
        )
        self._started(child, proc)

    def _child_env(self, spec: ProcessSpec) -> dict[str, str]:
        # with secure, every process hosts one service (see the module's docs) and has its identity
        secure = tls_env(self.secure, spec.services[0].name) if self.secure is not None else {}
        return {**self._env(), **secure}

    def _started(self, child: _Child, proc: _Process) -> None:
        with self._lock:
            child.proc = proc
            child.last_status = {}
            child.stepped = set()
            child.alive = set()
        pump = threading.Thread(target=self._pump, args=(child.name, proc), daemon=True)
        pump.start()
        child.pumps.append(pump)
        hosts = f": {', '.join(child.spec.service_names())}" if child.spec.container else ""
        log.info("started %s (pid %d)%s", child.name, proc.pid, hosts)

    def spawn(self) -> None:
        """Fork every process the first time (with ``fork_services``; otherwise :meth:`run` starts them).

        Imports what the services need, sets up numba's compiler target once, then forks one child per process,
        each held until :meth:`run` has the router listening (so none waits out Zenoh's connect retry period).
        Call it before this process opens a Zenoh session or starts a thread (``mjnav demo`` calls it before its
        own client connects); :meth:`run` calls it when nobody did. Idempotent.
        """
        if self._spawned or not self.fork_services:
            return
        self._spawned = True
        for name in PRELOAD_MODULES:
            importlib.import_module(name)
        for service in self.specs:
            service.load_class()
        _prime_numba()
        self.state_dir = make_state_dir()
        go_read, self._go_write = os.pipe()
        forked: list[tuple[_Child, _ForkedProcess]] = []
        for child in self.children:
            forked.append((child, self._fork(child.spec, go_read, [proc.stdout for _, proc in forked])))
        os.close(go_read)
        for child, proc in forked:  # threads only once every fork is done
            self._started(child, proc)

    def _fork(self, spec: ProcessSpec, go: int, siblings: list[IO[str] | None]) -> _ForkedProcess:
        """Fork the process of ``spec``: it runs the services as ``mjnav run`` would (:meth:`_command`) once
        ``go``'s write end is closed; ``siblings``: the output pipes of the processes forked before (their ends are
        closed in it)."""
        env = self._child_env(spec)
        out_read, out_write = os.pipe()
        parent = os.getpid()
        for stream in (sys.stdout, sys.stderr, self.out):
            stream.flush()  # nothing buffered here is written twice
        pid = os.fork()
        if pid == 0:  # the service's process: never returns
            code = 1
            try:
                os.close(out_read)
                assert self._go_write is not None
                os.close(self._go_write)  # only the launcher may hold it: its closing is the start signal
                for pipe in siblings:
                    if pipe is not None:
                        os.close(pipe.fileno())
                os.setsid()  # Ctrl-C reaches the launcher only; it stops the services in order
                _die_with_parent(parent)()
                _name_process(f"mjnav-{spec.name}")  # its command line is still the launcher's
                devnull = os.open(os.devnull, os.O_RDONLY)
                os.dup2(devnull, 0)
                os.close(devnull)
                os.dup2(out_write, 1)
                os.dup2(out_write, 2)
                os.close(out_write)
                sys.stdout = open(1, "w", buffering=1, closefd=False)  # noqa: SIM115
                sys.stderr = open(2, "w", buffering=1, closefd=False)  # noqa: SIM115
                for signum in (signal.SIGINT, signal.SIGTERM):
                    signal.signal(signum, signal.SIG_DFL)
                os.environ.clear()
                os.environ.update(env)
                while os.read(go, 1):  # EOF: the router listens (or the launcher is gone)
                    pass
                os.close(go)
                code = self._run_forked(spec)
            except SystemExit as exc:
                code = exc.code if isinstance(exc.code, int) else 1
            except BaseException:
                import traceback

                traceback.print_exc()
            finally:
                for stream in (sys.stdout, sys.stderr):
                    with contextlib.suppress(BaseException):  # nothing may keep it from exiting here
                        stream.flush()
                os._exit(code)
        os.close(out_write)
        return _ForkedProcess(pid, open(out_read, encoding="utf-8", errors="replace"))

    def _run_forked(self, spec: ProcessSpec) -> int:
        """In a forked child: run the services of ``spec`` (what ``mjnav run`` does with :meth:`_command`'s
        arguments, without the command line: the runtime does not import the commands)."""
        from mjnav.bus import BusConfigError, load_bus_config
        from mjnav.runtime.logs import setup_logging
        from mjnav.runtime.process import build_runner

        setup_logging()
        try:
            bus_config = load_bus_config(mode="client", connect=(self.endpoint,))  # TLS files from the environment
            runner = build_runner(self.stack, spec.services, self._set_items(spec), bus_config, self.namespace)
        except (ConfigError, BusConfigError, ValueError) as exc:
            print(f"mjnav run: {exc}", file=sys.stderr)
            return 2
        runner.install_signal_handlers()
        return runner.run()

    def _pump(self, name: str, proc: _Process) -> None:
        assert proc.stdout is not None
        for line in proc.stdout:
            with self._out_lock:
                self.out.write(f"[{name}] {line if line.endswith(chr(10)) else line + chr(10)}")
                self.out.flush()

    def _stop_child(self, child: _Child) -> None:
        proc = child.proc
        if proc is None or proc.poll() is not None:
            return
        proc.send_signal(signal.SIGTERM)
        try:
            proc.wait(STOP_GRACE_S)
        except subprocess.TimeoutExpired:
            log.warning("%s did not stop within %.0f s: killing it", child.name, STOP_GRACE_S)
            proc.kill()
            proc.wait()
        for pump in child.pumps:
            pump.join(1.0)
        log.info("stopped %s (exit code %s)", child.name, proc.returncode)

    # ------------------------------------------------------------------------------------------- supervision

    def _supervise(self, child: _Child) -> None:
        proc = child.proc
        now = time.monotonic()
        if child.restart_at is not None:
            if now >= child.restart_at:
                child.restart_at = None
                self._start(child)
            return
        if proc is None or child.gave_up:
            return
        if proc.poll() is None:
            self._check_hung(child, proc, now)
            return
        code = proc.returncode
        if child.restarts >= child.spec.restarts:
            log.error(
                "%s exited with code %s; %d restart(s) used up, giving up",
                child.name,
                code,
                child.restarts,
            )
            child.gave_up = True
            return
        delay = RESTART_BACKOFF_S * 2**child.restarts
        child.restarts += 1
        log.warning(
            "%s exited with code %s; restarting in %.1f s (restart %d of %d)",
            child.name,
            code,
            delay,
            child.restarts,
            child.spec.restarts,
        )
        child.restart_at = now + delay

    def _check_hung(self, child: _Child, proc: _Process, now: float) -> None:
        """Kill a running process one of whose services stopped answering (the next :meth:`_supervise` restarts
        the process): its status heartbeat is older than :attr:`hung_timeout_s`, or its liveliness token went
        away. A service that has not sent its first status yet is starting (imports, compilation) and is left
        alone."""
        reason = ""
        with self._lock:
            for service in child.spec.service_names():
                last = child.last_status.get(service)
                stepped = service in child.stepped
                timeout = self.hung_timeout_s if stepped else max(self.hung_timeout_s, FIRST_STEP_TIMEOUT_S)
                if service in child.alive and service not in self._alive:
                    reason = f"{service}'s liveliness token vanished"
                elif last is not None and now - last > timeout:
                    reason = f"no status from {service} for {now - last:.1f} s"
                if reason:
                    break
            if not reason:
                return
            child.last_status = {}
            child.alive = set()
        whole = f" with {', '.join(child.spec.service_names())}" if child.spec.container else ""
        log.warning("%s (pid %d) is hung: %s; killing it%s", child.name, proc.pid, reason, whole)
        proc.kill()

    def _on_status(self, msg: Any) -> None:
        now = time.monotonic()
        with self._lock:
            for child in self.children:
                proc = child.proc
                if msg.service in child.spec.service_names() and proc is not None and proc.pid == int(msg.pid):
                    child.last_status[msg.service] = now
                    if int(msg.steps) > 0:
                        child.stepped.add(msg.service)

    def _on_alive(self, service: str, alive: bool) -> None:
        with self._lock:
            if alive:
                self._alive.add(service)
                for child in self.children:
                    if service in child.spec.service_names():
                        child.alive.add(service)
            else:
                self._alive.discard(service)
            names = [s.name for s in self.specs]
            everyone = alive and all(name in self._alive for name in names)
        if everyone:
            log.info(
                "all %d service(s) alive on %s in %d process(es): %s",
                len(names),
                self.endpoint,
                len(self.children),
                ", ".join(names),
            )

    def _open_router(self) -> Bus:
        """The router's session.

        Raises:
            BusUnavailable: the listen port cannot be bound.
        """
        return Bus.open(self._router_config, self.namespace)

    def _release(self) -> None:
        """Let the forked services go on (they wait for the router)."""
        if self._go_write is not None:
            os.close(self._go_write)
            self._go_write = None

    def _stop_all(self) -> None:
        for child in reversed(self.children):
            self._stop_child(child)
        if self.state_dir is not None:
            shutil.rmtree(self.state_dir, ignore_errors=True)
            self.state_dir = None

    def _on_signal(self, signum: int, frame: FrameType | None) -> None:
        self._signals += 1
        if self._signals > 1:
            log.warning("second %s: killing every service now", signal.Signals(signum).name)
            for child in self.children:
                if child.proc is not None and child.proc.poll() is None:
                    child.proc.kill()
            os._exit(128 + signum)
        log.info("%s: stopping the stack", signal.Signals(signum).name)
        self.stop_event.set()

    def run(self, *, install_signals: bool = True) -> int:
        """Start the router and the services, supervise until stopped; returns the exit code.

        0 after a requested stop (signal or duration) when no service had to be given up, 1 otherwise; 2 when
        the router cannot listen on the port.
        """
        if install_signals:
            signal.signal(signal.SIGINT, self._on_signal)
            signal.signal(signal.SIGTERM, self._on_signal)
        self.spawn()
        try:
            router = self._open_router()
        except BusUnavailable as exc:
            log.error("cannot start the router: %s (port %d in use? use --port)", exc, self.port)
            self._stop_all()
            self._release()
            return 2
        finally:
            self.router_ready.set()
        log.info("zenoh router on %s; namespace %s", self.endpoint, self.namespace)
        if self.state_dir is None:
            self.state_dir = make_state_dir()
        deadline = None if self.duration_s is None else time.monotonic() + self.duration_s
        try:
            router.watch_alive(self._on_alive)
            router.subscribe("status", service="*", callback=self._on_status, immediate=True)
            self._release()
            for child in self.children:
                if child.proc is None:
                    self._start(child)
            while not self.stop_event.is_set():
                if deadline is not None and time.monotonic() >= deadline:
                    log.info("duration of %.1f s reached: stopping the stack", self.duration_s)
                    break
                for child in self.children:
                    self._supervise(child)
                self.stop_event.wait(0.1)
        finally:
            self._stop_all()
            router.close()
        failed = [c.spec.name for c in self.children if c.gave_up]
        if failed:
            log.error("service(s) given up after repeated crashes: %s", ", ".join(failed))
            return 1
        return 0
