"""``mjnav certs``: a private CA and one certificate per identity, made with openssl."""

from __future__ import annotations

import shutil
import stat
import subprocess
from pathlib import Path

import pytest

from mjnav.bus.certs import CertificateError, certificate_files, make_certificates
from mjnav.cli import main

pytestmark = pytest.mark.skipif(shutil.which("openssl") is None, reason="needs the openssl tool")


def _openssl(*args: str) -> str:
    return subprocess.run(["openssl", *args], capture_output=True, text=True, check=True).stdout


def test_certificates_chain_to_the_ca_and_name_their_identity(tmp_path: Path) -> None:
    files = make_certificates(tmp_path, ["planner", "operator"], hosts=["localhost", "127.0.0.1", "router"])
    assert sorted(f.name for f in files) == sorted(
        f"{stem}{ext}" for stem in ("ca", "router", "planner", "operator") for ext in (".crt", ".key")
    )
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(f.name for f in files)  # no leftovers
    for f in files:
        mode = stat.S_IMODE(f.stat().st_mode)
        assert mode == (0o600 if f.suffix == ".key" else 0o644), (f.name, oct(mode))
    for name in ("router", "planner", "operator"):
        crt = str(tmp_path / f"{name}.crt")
        assert f"{crt}: OK" in _openssl("verify", "-CAfile", str(tmp_path / "ca.crt"), crt)
        subject = _openssl("x509", "-in", crt, "-noout", "-subject", "-nameopt", "RFC2253")
        assert subject.strip() == f"subject=CN={name}"
    router = _openssl("x509", "-in", str(tmp_path / "router.crt"), "-noout", "-ext", "subjectAltName,extendedKeyUsage")
    assert "DNS:localhost" in router and "IP Address:127.0.0.1" in router and "DNS:router" in router
    assert "TLS Web Server Authentication" in router
    client = _openssl("x509", "-in", str(tmp_path / "planner.crt"), "-noout", "-ext", "extendedKeyUsage")
    assert "TLS Web Client Authentication" in client and "Server" not in client


def test_existing_files_are_kept_unless_forced(tmp_path: Path) -> None:
    make_certificates(tmp_path, ["sim"])
    before = (tmp_path / "ca.crt").read_bytes()
    with pytest.raises(CertificateError, match="--force"):
        make_certificates(tmp_path, ["sim"])
    assert (tmp_path / "ca.crt").read_bytes() == before
    make_certificates(tmp_path, ["sim"], force=True)
    assert (tmp_path / "ca.crt").read_bytes() != before


@pytest.mark.parametrize(
    ("names", "hosts", "days", "match"),
    [
        (["bad name"], ["localhost"], 10, "invalid identity"),
        (["router"], ["localhost"], 10, "invalid identity"),
        (["sim", "sim"], ["localhost"], 10, "duplicate"),
        (["sim"], [], 10, "at least one host"),
        (["sim"], ["bad/host"], 10, "invalid host"),
        (["sim"], ["localhost"], 0, "days"),
    ],
)
def test_bad_input_is_a_typed_error_and_writes_nothing(
    tmp_path: Path, names: list[str], hosts: list[str], days: int, match: str
) -> None:
    with pytest.raises(CertificateError, match=match):
        make_certificates(tmp_path / "out", names, hosts=hosts, days=days)
    assert not any(f.exists() for f in certificate_files(tmp_path / "out", names))


@pytest.mark.e2e
def test_cli_writes_one_certificate_per_stack_service_and_the_operator(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "certs"
    assert main(["certs", "--out", str(out), "--client", "dashboard"]) == 0
    for name in ("sim", "mapper", "planner", "smoother", "controller", "viz", "operator", "dashboard"):
        assert (out / f"{name}.crt").is_file() and (out / f"{name}.key").is_file()
    assert main(["certs", "--out", str(out)]) == 2
    assert "--force" in capsys.readouterr().err
