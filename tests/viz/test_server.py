"""The meshcat server on its thread: loopback binding, ports, forwarding to viewers, client timeouts."""

from __future__ import annotations

import socket
import urllib.request

import numpy as np
import pytest

from mjnav.bus import wait_until
from mjnav.geometry import Pose2D
from mjnav.msgs import ros
from mjnav.viz import MeshcatClient, MeshcatServer, MeshcatServerError, NavView, Scene
from mjnav.viz.view import ROOT
from tests.conftest import free_port
from tests.viz.helpers import ViewerClient


def _port(url: str) -> int:
    return int(url.rsplit(":", 1)[1].split("/", 1)[0])


def _bindable(port: int) -> bool:
    """Whether a server could bind ``port`` on loopback now (SO_REUSEADDR, as servers do)."""
    with socket.socket() as s:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            s.bind(("127.0.0.1", port))
        except OSError:
            return False
    return True


def _non_loopback_ip() -> str | None:
    """An address of this machine other than 127.x (None when it has none)."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        try:
            s.connect(("192.0.2.1", 9))  # TEST-NET address: no packet is sent for UDP connect
            ip = str(s.getsockname()[0])
        except OSError:
            return None
    return None if ip.startswith("127.") or ip == "0.0.0.0" else ip


def test_server_serves_the_viewer_on_loopback_and_forwards_commands() -> None:
    with MeshcatServer(web_port=0, zmq_port=0) as server:
        assert server.web_url.startswith("http://127.0.0.1:") and server.zmq_url.startswith("tcp://127.0.0.1:")
        with urllib.request.urlopen(server.web_url, timeout=10) as page:
            assert page.status == 200 and b"MeshCat" in page.read()
        other = _non_loopback_ip()
        if other is not None:
            with pytest.raises(OSError):
                socket.create_connection((other, _port(server.web_url)), timeout=2).close()
        client = MeshcatClient(server.zmq_url)
        scene = Scene(client.send)
        NavView(scene).draw_goal(ros.pose_stamped(0.0, "map", Pose2D(1.0, 2.0, 0.0)))  # before any browser connects
        viewer = ViewerClient(server.web_url)
        try:
            assert viewer.wait_for(lambda cs: any(c["path"] == f"{ROOT}/goal/arrow" for c in cs), 10.0)
            assert server.viewers == 1
            scene.set_transform(f"{ROOT}/goal", np.eye(4))
            assert viewer.wait_for(lambda cs: any(c["type"] == "set_transform" for c in cs), 10.0)
            assert client.web_url() == server.web_url
        finally:
            viewer.close()
            client.close()
    # Stopped: both ports are released (ZMQ unbinds on its own I/O thread, so allow it a moment).
    for port in (_port(server.web_url), _port(server.zmq_url)):
        assert wait_until(lambda p=port: _bindable(p), 5.0), f"port {port} is still in use"


def test_a_taken_port_is_an_error_unless_searching() -> None:
    with MeshcatServer(web_port=0, zmq_port=0) as first:
        taken = _port(first.web_url)
        with pytest.raises(MeshcatServerError, match=f"web port {taken}"):
            MeshcatServer(web_port=taken, zmq_port=0).start()
        second = MeshcatServer(web_port=taken, zmq_port=0, port_search=5).start()
        try:
            assert _port(second.web_url) not in (taken, 0)
        finally:
            second.stop()


def test_client_without_server_times_out_with_a_typed_error() -> None:
    client = MeshcatClient(f"tcp://127.0.0.1:{free_port()}", timeout_s=0.3)
    for _ in range(2):  # the stuck request socket is replaced, the next call fails the same way
        with pytest.raises(MeshcatServerError, match="did not answer"):
            client.send("set_object", "/meshcat/x", b"")
    client.close()
