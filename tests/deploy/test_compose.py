"""docker/: compose names exactly the services of services/stack.toml (so the two cannot drift), each wired the
same way; the Dockerfile keeps its promises; Debian's docker-compose validates the file."""

from __future__ import annotations

import re
import shutil
import subprocess
from typing import Any

import pytest
import yaml

from mjnav.runtime.stack import load_stack
from tests.conftest import REPO

COMPOSE = REPO / "docker" / "compose.yaml"
DOCKERFILE = REPO / "docker" / "Dockerfile"
ROUTER_ENDPOINT = "tcp/router:7447"


def _compose() -> dict[str, Any]:
    data = yaml.safe_load(COMPOSE.read_text(encoding="utf-8"))
    assert isinstance(data, dict) and isinstance(data.get("services"), dict)
    return data["services"]


def _snippet(name: str) -> str:
    return (
        f'  {name}:\n    <<: *service\n    command: ["mjnav", "run", "{name}"]\n    healthcheck:\n'
        f'      <<: *health\n      test: ["CMD", "mjnav", "health", "{name}", "--status", "--timeout", "5"]\n'
    )


def test_compose_names_every_stack_service_and_only_those() -> None:
    stack = load_stack()
    services = _compose()
    expected = set(stack.names())
    missing = sorted(expected - set(services))
    extra = sorted(set(services) - expected - {"router"})
    assert "router" in services
    assert not missing, "docker/compose.yaml lacks stack service(s); add:\n" + "".join(_snippet(n) for n in missing)
    assert not extra, f"docker/compose.yaml runs {extra}, which services/stack.toml does not define"


def test_every_service_container_is_wired_alike() -> None:
    services = _compose()
    router = services["router"]
    image = router["image"]
    for name in load_stack().names():
        svc = services[name]
        assert svc["command"][:3] == ["mjnav", "run", name], name
        assert svc["image"] == image, f"{name} must use the shared image"
        assert svc["environment"]["MJNAV_ZENOH_CONNECT"] == ROUTER_ENDPOINT, name
        assert any(v.endswith(":/opt/mjnav/services:ro") and v.startswith("../services") for v in svc["volumes"]), name
        assert svc["depends_on"]["router"]["condition"] == "service_healthy", name
        assert svc["healthcheck"]["test"][:5] == ["CMD", "mjnav", "health", name, "--status"], name
        assert "ports" not in svc, f"{name} publishes a port; only the router may"
    assert router["command"][:2] == ["mjnav", "router"] and "tcp/0.0.0.0:7447" in router["command"]
    assert router["healthcheck"]["test"][:3] == ["CMD", "mjnav", "health"]
    (port,) = router["ports"]
    assert re.fullmatch(r"\$\{MJNAV_PUBLISH:-127\.0\.0\.1\}:\$\{MJNAV_PORT:-7447\}:7447", port), port


def test_dockerfile_keeps_its_promises() -> None:
    text = DOCKERFILE.read_text(encoding="utf-8")
    assert re.search(r"^FROM python:3\.11-slim", text, re.M), "slim Python base"
    makefile = (REPO / "Makefile").read_text(encoding="utf-8")
    packages = re.search(r"^SYSTEM_PACKAGES := (.+)$", makefile, re.M)
    assert packages, "Makefile has no SYSTEM_PACKAGES"
    for pkg in packages.group(1).split():
        assert pkg in text, f"the image lacks the rendering package {pkg} that make installs"
    users = re.findall(r"^USER (\S+)", text, re.M)
    assert users and users[-1] not in ("root", "0"), "the image must end on a non-root user"
    cache = re.search(r"NUMBA_CACHE_DIR=(\S+)", text)
    assert cache and re.search(rf"install -d -o {users[-1]} .*{re.escape(cache.group(1))}", text), (
        "numba's cache directory must exist and belong to the runtime user"
    )
    assert "pip install --no-deps -e ." in text, "the package is installed (editable: it finds mjcf/ and services/)"


def test_docker_compose_validates_the_file() -> None:
    exe = shutil.which("docker-compose")
    if exe is None:
        pytest.skip("docker-compose not installed (Debian: apt-get install docker-compose; make test installs it)")
    proc = subprocess.run(
        [exe, "-f", str(COMPOSE), "config"], cwd=REPO, capture_output=True, text=True, timeout=120, check=False
    )
    assert proc.returncode == 0, proc.stderr
    resolved = yaml.safe_load(proc.stdout)["services"]
    assert set(resolved) == {"router", *load_stack().names()}
    assert resolved["router"]["ports"], "the router port is published"
