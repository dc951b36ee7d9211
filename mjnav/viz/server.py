"""A meshcat server run headlessly inside the viz process, and a ZMQ client that draws into it.

:class:`MeshcatServer` runs meshcat's own server (``meshcat.servers.zmqserver.ZMQWebSocketBridge``: the web viewer
over HTTP + WebSocket, drawing commands over ZMQ) on its own thread and event loop, with both sockets bound to a
host of our choosing — loopback by default, where meshcat itself would listen on every interface. Port 0 picks a
free port; a taken port is an error unless ``port_search`` allows trying the next ones (meshcat's habit).

:class:`MeshcatClient` speaks meshcat's ZMQ protocol with timeouts, so a dead server raises
:class:`~mjnav.viz.errors.MeshcatServerError` instead of hanging the caller. Any other meshcat client
(``meshcat.Visualizer(zmq_url=...)``) can draw into the same server.
"""

from __future__ import annotations

import asyncio
import logging
import socket
import threading
import time
from typing import Any

import zmq

from mjnav.viz.errors import MeshcatServerError

log = logging.getLogger("mjnav.viz")

#: Seconds a ZMQ request may take before the server is considered gone.
REQUEST_TIMEOUT_S = 5.0


def _bridge_class(sockets: list[socket.socket]) -> type[Any]:
    """A ZMQWebSocketBridge whose HTTP server serves on already-bound ``sockets`` (meshcat binds every interface)."""
    import tornado.httpserver
    from meshcat.servers.zmqserver import ZMQWebSocketBridge

    class _Bridge(ZMQWebSocketBridge):
        http_server: tornado.httpserver.HTTPServer | None = None

        def make_app(self) -> Any:
            app = super().make_app()

            def listen(port: int, **kwargs: Any) -> tornado.httpserver.HTTPServer:
                server = tornado.httpserver.HTTPServer(app, **kwargs)
                server.add_sockets(sockets)
                self.http_server = server
                return server

            app.listen = listen  # the bridge calls app.listen(port); serve our loopback sockets instead
            return app

    return _Bridge


def _family(host: str) -> socket.AddressFamily:
    return socket.AF_INET6 if ":" in host else socket.AF_INET


def _zmq_host(host: str) -> str:
    return f"[{host}]" if ":" in host else host


class MeshcatServer:
    """meshcat's web + ZMQ server on a background thread.

    Args:
        host: interface both sockets bind to (default loopback; ``0.0.0.0`` serves the network).
        web_port: HTTP/WebSocket port of the viewer (0 = any free port).
        zmq_port: ZMQ port drawing commands arrive on (0 = any free port).
        port_search: when a non-zero port is taken, try up to this many following ports (0 = fail at once).

    Raises:
        MeshcatServerError: (from :meth:`start`) a port is taken or the host cannot be bound.
    """

    def __init__(self, host: str = "127.0.0.1", web_port: int = 7000, zmq_port: int = 6000, port_search: int = 0):
        self.host = host
        self.web_port = web_port
        self.zmq_port = zmq_port
        self.port_search = port_search
        self.web_url = ""
        self.zmq_url = ""
        self._thread: threading.Thread | None = None
        self._loop: Any = None
        self._bridge: Any = None
        self._error: BaseException | None = None

    def __enter__(self) -> MeshcatServer:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    @property
    def running(self) -> bool:
        """Whether the server thread is serving."""
        return self._thread is not None and self._thread.is_alive()

    def start(self, timeout_s: float = 10.0) -> MeshcatServer:
        """Start serving; returns once both sockets are bound (``web_url`` and ``zmq_url`` are then set)."""
        if self.running:
            return self
        last: MeshcatServerError | None = None
        for attempt in range(self.port_search + 1):
            web = self.web_port + attempt if self.web_port else 0
            zmq_port = self.zmq_port + attempt if self.zmq_port else 0
            try:
                self._start_once(web, zmq_port, timeout_s)
            except MeshcatServerError as exc:
                last = exc
                if attempt < self.port_search:
                    log.warning("%s; trying web port %d, zmq port %d", exc, web + 1, zmq_port + 1)
                continue
            return self
        assert last is not None
        raise last

    def _start_once(self, web_port: int, zmq_port: int, timeout_s: float) -> None:
        ready = threading.Event()
        self._error = None
        zmq_url = f"tcp://{_zmq_host(self.host)}:{zmq_port or '*'}"

        def serve() -> None:
            loop = asyncio.new_event_loop()
            asyncio.set_event_loop(loop)
            sockets: list[socket.socket] = []
            try:
                import tornado.netutil

                sockets = tornado.netutil.bind_sockets(web_port, address=self.host, family=_family(self.host))
                bridge = _bridge_class(sockets)(zmq_url=zmq_url, host=self.host, port=web_port)
            except Exception as exc:  # taken port, bad address
                for sock in sockets:
                    sock.close()
                self._error = exc
                ready.set()
                loop.close()
                return
            bound = int(sockets[0].getsockname()[1])
            bridge.fileserver_port = bound
            bridge.zmq_url = bridge.zmq_socket.getsockopt(zmq.LAST_ENDPOINT).decode()
            bridge.web_url = f"http://{_zmq_host(self.host)}:{bound}/static/"
            self._bridge = bridge
            self._loop = bridge.ioloop
            ready.set()
            try:
                bridge.ioloop.start()
            finally:
                loop.close()

        thread = threading.Thread(target=serve, name="meshcat-server", daemon=True)
        thread.start()
        if not ready.wait(timeout_s):
            raise MeshcatServerError(f"meshcat server did not start within {timeout_s} s")
        if self._error is not None:
            thread.join(timeout_s)
            raise MeshcatServerError(
                f"cannot serve meshcat on {self.host} (web port {web_port or 'any'}, zmq port {zmq_port or 'any'}): "
                f"{self._error}"
            ) from self._error
        self._thread = thread
        self.web_url = self._bridge.web_url
        self.zmq_url = self._bridge.zmq_url

    @property
    def viewers(self) -> int:
        """Browsers (WebSocket connections) currently watching."""
        return len(self._bridge.websocket_pool) if self._bridge is not None else 0

    def stop(self, timeout_s: float = 5.0) -> None:
        """Stop serving and release both ports (idempotent)."""
        if self._thread is None:
            return
        loop, thread, bridge = self._loop, self._thread, self._bridge
        self._thread = None
        loop.add_callback(_shutdown, bridge, min(1.0, timeout_s / 2))
        thread.join(timeout_s)
        if thread.is_alive():
            log.warning("meshcat server thread did not stop within %.1f s", timeout_s)


async def _shutdown(bridge: Any, grace_s: float) -> None:
    """On the server's loop: close the viewers' connections (waiting up to ``grace_s`` for their close handshakes),
    the HTTP server and its connections, and the ZMQ socket, then stop the loop."""
    for ws in list(bridge.websocket_pool):
        try:
            ws.close()
        except Exception as exc:  # the connection may be half gone
            log.debug("closing a viewer connection failed: %s", exc)
    deadline = time.monotonic() + grace_s
    while bridge.websocket_pool and time.monotonic() < deadline:
        await asyncio.sleep(0.02)
    server = bridge.http_server
    if server is not None:
        server.stop()
        await server.close_all_connections()
    bridge.zmq_stream.close(linger=0)
    bridge.ioloop.stop()


class MeshcatClient:
    """Sends drawing commands to a meshcat server over ZMQ (request/reply, with timeouts).

    Args:
        zmq_url: the server's ZMQ endpoint, e.g. ``tcp://127.0.0.1:6000``.
        timeout_s: per-request deadline.
    """

    def __init__(self, zmq_url: str, timeout_s: float = REQUEST_TIMEOUT_S) -> None:
        self.zmq_url = zmq_url
        self.timeout_ms = int(timeout_s * 1000)
        self._context: zmq.Context[zmq.Socket[bytes]] = zmq.Context.instance()
        self._socket: zmq.Socket[bytes] | None = None
        self._lock = threading.Lock()

    def _connect(self) -> zmq.Socket[bytes]:
        if self._socket is None:
            sock: zmq.Socket[bytes] = self._context.socket(zmq.REQ)
            sock.setsockopt(zmq.RCVTIMEO, self.timeout_ms)
            sock.setsockopt(zmq.SNDTIMEO, self.timeout_ms)
            sock.setsockopt(zmq.LINGER, 0)
            sock.connect(self.zmq_url)
            self._socket = sock
        return self._socket

    def _request(self, frames: list[bytes]) -> bytes:
        with self._lock:
            sock = self._connect()
            try:
                sock.send_multipart(frames)
                return sock.recv()
            except zmq.ZMQError as exc:
                # A REQ socket that missed its reply is stuck; start over on the next request.
                sock.close(linger=0)
                self._socket = None
                raise MeshcatServerError(f"meshcat server at {self.zmq_url} did not answer: {exc}") from exc

    def send(self, kind: str, path: str, packed: bytes) -> None:
        """Send one packed command (the :data:`mjnav.viz.scene.Sink` signature)."""
        reply = self._request([kind.encode(), path.encode(), packed])
        if reply != b"ok":
            raise MeshcatServerError(f"meshcat server rejected {kind} {path}: {reply[:200]!r}")

    def web_url(self) -> str:
        """The viewer URL the server advertises."""
        return self._request([b"url"]).decode()

    def close(self) -> None:
        """Close the socket."""
        with self._lock:
            if self._socket is not None:
                self._socket.close(linger=0)
                self._socket = None
