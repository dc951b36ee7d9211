"""docker/: compose names exactly the services of services/stack.toml (the default profile), services/uav_stack.toml
(profile ``uav``) and the optional relays (their own profiles), each wired the same way; the Dockerfile keeps its
promises (pinned packages, warm kernels); Debian's docker-compose validates the file. (test_deployments.py runs
the commands.)"""

from __future__ import annotations

import re
import shutil
import subprocess
import tomllib
from typing import Any

import pytest
import yaml
from packaging.requirements import Requirement

from mjnav.runtime.stack import OPTIONAL_SERVICES, load_stack, services_dir
from tests.conftest import REPO

COMPOSE = REPO / "docker" / "compose.yaml"
DOCKERFILE = REPO / "docker" / "Dockerfile"
PINNED = REPO / "docker" / "requirements.txt"
ROUTER_ENDPOINT = "tcp/router:7447"
#: Compose profile of each optional service.
OPTIONAL_PROFILES = {"foxglove": "foxglove", "ros_bridge": "ros"}


def _compose() -> dict[str, Any]:
    data = yaml.safe_load(COMPOSE.read_text(encoding="utf-8"))
    assert isinstance(data, dict) and isinstance(data.get("services"), dict)
    return data["services"]


def _expected() -> dict[str, tuple[str | None, str, str]]:
    """service -> (profile or None, namespace, stack file relative to the repository)."""
    out: dict[str, tuple[str | None, str, str]] = {}
    for stack_file, profile in (("stack.toml", None), ("uav_stack.toml", "uav")):
        stack = load_stack(services_dir() / stack_file)
        out |= {name: (profile, stack.namespace, f"services/{stack_file}") for name in stack.names()}
    ground = load_stack()
    out |= {name: (OPTIONAL_PROFILES[name], ground.namespace, "services/stack.toml") for name in OPTIONAL_SERVICES}
    return out


def _snippet(name: str, profile: str | None, namespace: str, stack_file: str) -> str:
    stack = [] if stack_file == "services/stack.toml" else ["--stack", stack_file]
    ns = [] if namespace == "robot0" else ["--ns", namespace]
    command = ", ".join(f'"{a}"' for a in ["mjnav", "run", name, *stack])
    health = ", ".join(f'"{a}"' for a in ["CMD", "mjnav", "health", name, *ns, "--status", "--timeout", "5"])
    prof = f'    profiles: ["{profile}"]\n' if profile else ""
    return (
        f"  {name}:\n    <<: *service\n{prof}    command: [{command}]\n"
        f"    healthcheck:\n      <<: *health\n      test: [{health}]\n"
    )


def test_compose_names_every_service_and_only_those_with_their_profiles() -> None:
    services = _compose()
    expected = _expected()
    missing = sorted(set(expected) - set(services))
    extra = sorted(set(services) - set(expected) - {"router"})
    assert "router" in services
    assert not missing, "docker/compose.yaml lacks service(s); add:\n" + "".join(
        _snippet(n, *expected[n]) for n in missing
    )
    assert not extra, f"docker/compose.yaml runs {extra}, which no stack file or optional service defines"
    for name, (profile, _, _) in expected.items():
        assert services[name].get("profiles") == ([profile] if profile else None), name
    assert "profiles" not in services["router"]


def test_every_service_container_is_wired_alike() -> None:
    services = _compose()
    router = services["router"]
    image = router["image"]
    for name, (_, namespace, stack_file) in _expected().items():
        svc = services[name]
        command = svc["command"]
        assert command[:3] == ["mjnav", "run", name], name
        if stack_file != "services/stack.toml":
            assert command[3:5] == ["--stack", stack_file], name
        assert svc["image"] == image, f"{name} must use the shared image"
        assert svc["environment"]["MJNAV_ZENOH_CONNECT"] == ROUTER_ENDPOINT, name
        assert any(v.endswith(":/opt/mjnav/services:ro") and v.startswith("../services") for v in svc["volumes"]), name
        assert svc["depends_on"]["router"]["condition"] == "service_healthy", name
        test = svc["healthcheck"]["test"]
        assert test[:4] == ["CMD", "mjnav", "health", name] and "--status" in test, name
        if namespace != "robot0":
            assert test[test.index("--ns") + 1] == namespace, name
        assert "ports" not in svc or name == "foxglove", f"{name} publishes a port; only the router and foxglove may"
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
    assert "pip install --no-deps -r /tmp/requirements.txt" in text and "COPY docker/requirements.txt" in text, (
        "the image installs the pinned packages, nothing resolved at build time"
    )
    assert "pip install --no-deps -e ." in text, "the package is installed (editable: it finds mjcf/ and services/)"
    user_at = text.rindex(f"USER {users[-1]}")
    assert text.find("RUN mjnav warmup", user_at) > user_at, "the kernels are compiled at build, as the runtime user"


def test_the_image_pins_every_dependency_within_its_bounds() -> None:
    pinned: dict[str, str] = {}
    for line in PINNED.read_text(encoding="utf-8").splitlines():
        if line.strip() and not line.startswith("#"):
            req = Requirement(line)
            (spec,) = req.specifier
            assert spec.operator == "==", f"{line}: pin an exact version"
            pinned[req.name.lower().replace("_", "-")] = spec.version
    project = tomllib.loads((REPO / "pyproject.toml").read_text(encoding="utf-8"))["project"]
    for text in [*project["dependencies"], *project["optional-dependencies"]["foxglove"]]:
        req = Requirement(text)
        name = req.name.lower().replace("_", "-")
        assert name in pinned, f"{req.name} is not pinned in docker/requirements.txt (make lock)"
        assert req.specifier.contains(pinned[name], prereleases=True), f"{req.name}=={pinned[name]} is outside {req}"


def resolved_compose() -> dict[str, Any]:
    """The services as Debian's docker-compose resolves the file (`docker-compose config`); the test skips, saying
    why, without it."""
    exe = shutil.which("docker-compose")
    if exe is None:
        pytest.skip("docker-compose not installed (Debian: apt-get install docker-compose; make test installs it)")
    proc = subprocess.run(
        [exe, "-f", str(COMPOSE), "config"], cwd=REPO, capture_output=True, text=True, timeout=120, check=False
    )
    assert proc.returncode == 0, proc.stderr
    services: dict[str, Any] = yaml.safe_load(proc.stdout)["services"]
    return services


@pytest.mark.e2e
def test_docker_compose_validates_the_file() -> None:
    resolved = resolved_compose()
    assert set(resolved) == {"router", *_expected()}
    assert resolved["router"]["ports"], "the router port is published"
