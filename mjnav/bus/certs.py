"""Certificates for a stack on mutual TLS (``mjnav certs``): a private CA, the router's certificate and one client
certificate per identity, made with the ``openssl`` command-line tool.

Files written to the output folder (keys 0600, certificates 0644), all ECDSA P-256:

- ``ca.crt``, ``ca.key``: the certificate authority every link is checked against (keep ``ca.key`` private; it is
  needed only to issue more certificates);
- ``router.crt``, ``router.key``: the router's server certificate, with the host names and addresses clients
  connect to as subject alternative names (``localhost`` and ``127.0.0.1`` by default);
- ``<identity>.crt``, ``<identity>.key`` for each client identity (a service name, ``operator``, …): the
  certificate's common name is the identity the router's access control knows the client by.
"""

from __future__ import annotations

import ipaddress
import os
import re
import secrets
import shutil
import subprocess
import tempfile
from collections.abc import Sequence
from pathlib import Path

#: Common name of the router's certificate (and its file stem).
ROUTER = "router"
#: File stem of the CA.
CA = "ca"
#: Default subject alternative names of the router's certificate: what a client on this machine connects to.
DEFAULT_HOSTS = ("localhost", "127.0.0.1")

_NAME_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,63}$")
_HOST_RE = re.compile(r"^[A-Za-z0-9*]([A-Za-z0-9.-]{0,252})$")


class CertificateError(RuntimeError):
    """Certificates that cannot be made (bad names, files in the way, no ``openssl``, ``openssl`` failed)."""


def certificate_files(out: Path, identities: Sequence[str]) -> list[Path]:
    """Every file :func:`make_certificates` writes to ``out`` for ``identities``."""
    stems = [CA, ROUTER, *identities]
    return [out / f"{stem}{ext}" for stem in stems for ext in (".crt", ".key")]


def make_certificates(
    out: str | Path,
    identities: Sequence[str],
    *,
    hosts: Sequence[str] = DEFAULT_HOSTS,
    days: int = 825,
    force: bool = False,
) -> list[Path]:
    """Write a CA, the router's certificate and one client certificate per identity to ``out``.

    Args:
        out: output folder (created if needed).
        identities: client common names, e.g. the stack's services and ``operator``.
        hosts: DNS names and IP addresses clients use to reach the router (its subject alternative names).
        days: validity of every certificate, days.
        force: replace existing files (else an error names them and nothing is written).

    Returns:
        The files written.

    Raises:
        CertificateError: invalid or duplicate names, files in the way, ``openssl`` missing or failing.
    """
    out = Path(out)
    names = list(identities)
    for name in names:
        if not _NAME_RE.match(name) or name in (CA, ROUTER):
            raise CertificateError(
                f"invalid identity {name!r}: use letters, digits, '_', '.', '-' (at most 64), not {CA!r} or {ROUTER!r}"
            )
    if len(set(names)) != len(names):
        raise CertificateError(f"duplicate identities in {names}")
    if not hosts:
        raise CertificateError("the router's certificate needs at least one host name or address")
    if days <= 0:
        raise CertificateError(f"days must be positive, got {days}")
    san = ",".join(_san(h) for h in hosts)
    openssl = shutil.which("openssl")
    if openssl is None:
        raise CertificateError("the 'openssl' command was not found on PATH: install OpenSSL")
    files = certificate_files(out, names)
    existing = [str(f) for f in files if f.exists()]
    if existing and not force:
        raise CertificateError(f"{len(existing)} file(s) exist, e.g. {existing[0]}: use --force to replace them")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise CertificateError(f"cannot create {out}: {exc.strerror}") from exc
    # Everything is made in a private folder beside the output, then moved in: no key is ever readable by others.
    with tempfile.TemporaryDirectory(prefix=".mjnav-certs-", dir=out) as tmp:
        work = Path(tmp)
        _run(
            openssl,
            "req",
            "-x509",
            *_new_key(work / f"{CA}.key"),
            "-out",
            str(work / f"{CA}.crt"),
            "-days",
            str(days),
            "-subj",
            "/CN=mjnav CA",
            "-addext",
            "basicConstraints=critical,CA:TRUE",
            "-addext",
            "keyUsage=critical,keyCertSign,cRLSign",
        )
        _issue(openssl, work, ROUTER, days, "serverAuth,clientAuth", san)
        for name in names:
            _issue(openssl, work, name, days, "clientAuth", None)
        for f in files:
            made = work / f.name
            made.chmod(0o600 if f.suffix == ".key" else 0o644)
            os.replace(made, f)
    return files


def _san(host: str) -> str:
    try:
        return f"IP:{ipaddress.ip_address(host)}"
    except ValueError:
        if not _HOST_RE.match(host):
            raise CertificateError(f"invalid host name {host!r}") from None
        return f"DNS:{host}"


def _new_key(key: Path) -> list[str]:
    return ["-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:P-256", "-nodes", "-keyout", str(key)]


def _issue(openssl: str, work: Path, name: str, days: int, usage: str, san: str | None) -> None:
    """Make ``name``'s key and a certificate for it signed by the CA in ``work``."""
    ext = work / f"{name}.ext"
    lines = [
        "basicConstraints=critical,CA:FALSE",
        "keyUsage=critical,digitalSignature",
        f"extendedKeyUsage={usage}",
    ]
    if san:
        lines.append(f"subjectAltName={san}")
    ext.write_text("\n".join(lines) + "\n", encoding="utf-8")
    csr = work / f"{name}.csr"
    _run(openssl, "req", "-new", *_new_key(work / f"{name}.key"), "-out", str(csr), "-subj", f"/CN={name}")
    _run(
        openssl,
        "x509",
        "-req",
        "-in",
        str(csr),
        "-CA",
        str(work / f"{CA}.crt"),
        "-CAkey",
        str(work / f"{CA}.key"),
        "-set_serial",
        f"0x{secrets.token_hex(16)}",
        "-days",
        str(days),
        "-extfile",
        str(ext),
        "-out",
        str(work / f"{name}.crt"),
    )


def _run(*cmd: str) -> None:
    proc = subprocess.run(cmd, capture_output=True, text=True, stdin=subprocess.DEVNULL, check=False)
    if proc.returncode != 0:
        detail = (proc.stderr or proc.stdout).strip().splitlines()
        raise CertificateError(f"openssl {cmd[1]} failed: {detail[-1] if detail else f'exit code {proc.returncode}'}")
