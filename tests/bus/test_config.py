"""Layered bus configuration: defaults → file → flags → environment."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from mjnav.bus import DEFAULT_ROUTER, Bus, BusConfig, BusConfigError, load_bus_config


def test_defaults_stay_on_loopback_without_multicast() -> None:
    cfg = load_bus_config(env={})
    assert cfg == BusConfig()
    assert cfg.connect == (DEFAULT_ROUTER,) and cfg.listen == ("tcp/127.0.0.1:0",)
    assert cfg.multicast_scouting is False and cfg.mode == "peer"


def test_layers_override_in_order(tmp_path: Path) -> None:
    f = tmp_path / "bus.toml"
    f.write_text('mode = "client"\nconnect = ["tcp/10.0.0.1:7447"]\nmulticast_scouting = true\n')
    cfg = load_bus_config(config_file=f, env={})
    assert (cfg.mode, cfg.connect, cfg.multicast_scouting) == ("client", ("tcp/10.0.0.1:7447",), True)
    cfg = load_bus_config(config_file=f, connect=["tcp/127.0.0.1:9000"], env={})
    assert cfg.connect == ("tcp/127.0.0.1:9000",) and cfg.mode == "client"
    env = {"MJNAV_ZENOH_CONNECT": "tcp/127.0.0.1:1, tcp/127.0.0.1:2", "MJNAV_ZENOH_MODE": "peer"}
    cfg = load_bus_config(config_file=f, connect=["tcp/127.0.0.1:9000"], mode="client", env=env)
    assert cfg.connect == ("tcp/127.0.0.1:1", "tcp/127.0.0.1:2") and cfg.mode == "peer"
    cfg = load_bus_config(env={"MJNAV_ZENOH_CONFIG": str(f)})
    assert cfg.mode == "client"


def test_bad_values_are_typed_errors(tmp_path: Path) -> None:
    with pytest.raises(BusConfigError, match="mode"):
        load_bus_config(mode="satellite", env={})
    with pytest.raises(BusConfigError, match="endpoint"):
        load_bus_config(connect=["127.0.0.1:7447"], env={})
    bad = tmp_path / "bad.toml"
    bad.write_text("conect = []\n")
    with pytest.raises(BusConfigError, match="unknown key"):
        load_bus_config(config_file=bad, env={})
    with pytest.raises(BusConfigError, match="cannot read"):
        load_bus_config(config_file=tmp_path / "missing.toml", env={})


def test_tls_layers_and_defaults_leave_no_plain_tcp_endpoint(tmp_path: Path) -> None:
    f = tmp_path / "bus.toml"
    f.write_text('mode = "client"\ntls_ca = "certs/ca.crt"\ntls_cert = "certs/me.crt"\ntls_key = "certs/me.key"\n')
    cfg = load_bus_config(config_file=f, env={})
    assert cfg.tls and cfg.tls_ca == str(tmp_path / "certs" / "ca.crt")  # relative to the file
    assert cfg.connect == ("tls/127.0.0.1:7447",) and cfg.listen == ()
    env = {"MJNAV_ZENOH_TLS_CA": "/x/ca.crt", "MJNAV_ZENOH_TLS_CERT": "/x/a.crt", "MJNAV_ZENOH_TLS_KEY": "/x/a.key"}
    cfg = load_bus_config(connect=["tls/10.0.0.2:7447"], env=env)
    assert (cfg.tls_ca, cfg.tls_cert, cfg.tls_key) == ("/x/ca.crt", "/x/a.crt", "/x/a.key")
    assert cfg.connect == ("tls/10.0.0.2:7447",) and cfg.mode == "peer" and cfg.listen == ()
    tls = cfg.to_zenoh()
    assert '"/x/a.crt"' in tls.get_json("transport/link/tls/connect_certificate")
    assert tls.get_json("transport/link/tls/enable_mtls") == "true"
    with pytest.raises(BusConfigError, match="not tls"):
        load_bus_config(connect=["tcp/127.0.0.1:7447"], env=env)
    with pytest.raises(BusConfigError, match="tls_ca"):
        BusConfig(connect=(), listen=(), tls_cert="/x/a.crt", tls_key="/x/a.key")
    assert load_bus_config(env={}).tls is False


def _shared_memory_maps() -> list[str]:
    """Zenoh shared-memory segments this process has open (``/dev/shm/*.zenoh``)."""
    found = []
    for fd in os.listdir("/proc/self/fd"):
        try:
            target = os.readlink(f"/proc/self/fd/{fd}")
        except OSError:  # closed meanwhile (the listing's own descriptor)
            continue
        if target.startswith("/dev/shm/"):
            found.append(target)
    return found


@pytest.mark.skipif(not Path("/proc/self/fd").is_dir(), reason="needs /proc (Linux)")
def test_sessions_open_no_shared_memory_segments(router_endpoint: str) -> None:
    """With Zenoh's default shared-memory transport every session mapped four /dev/shm segments that closing it did
    not release: a process opening sessions one after another grew by 4 descriptors and ~39 MB per session."""
    before = _shared_memory_maps()
    for _ in range(3):
        with Bus.open(BusConfig(mode="client", connect=(router_endpoint,))) as bus:
            bus.publisher("scan").put_bytes(bytes(8192))  # above the transport's 3 KB shared-memory threshold
    assert _shared_memory_maps() == before
