"""``mjnav certs``: the certificates of a stack on mutual TLS with access control (``mjnav up --secure DIR``)."""

from __future__ import annotations

import argparse
import sys
from typing import Any


def register(sub: Any) -> None:
    """Add the ``certs`` command."""
    from mjnav.bus.certs import DEFAULT_HOSTS
    from mjnav.msgs.topics import OPERATOR

    p = sub.add_parser(
        "certs",
        help="make TLS certificates for 'mjnav up --secure'",
        description=(
            "Write a private CA (ca.crt, ca.key), the router's certificate (router.crt/.key) and one client "
            "certificate per service of the stack plus one for the operator (<name>.crt/.key; the common name is "
            "the identity the router's access control knows the client by), with the openssl tool. Keys are "
            "readable by their owner only. Existing files are kept unless --force."
        ),
        epilog="Example: mjnav certs --out certs && mjnav up --secure certs",
    )
    p.add_argument("--out", required=True, metavar="DIR", help="output folder (created if needed)")
    p.add_argument("--stack", metavar="FILE", help="stack file whose services get certificates (default services/)")
    p.add_argument(
        "--client",
        action="append",
        default=[],
        metavar="NAME",
        help=f"another client identity besides the services and '{OPERATOR}' (repeatable); under access control "
        "it may subscribe and read configs but publish nothing",
    )
    p.add_argument(
        "--host",
        action="append",
        metavar="NAME",
        help=f"host name or IP address clients reach the router at (repeatable; default {', '.join(DEFAULT_HOSTS)}; "
        "e.g. --host router for docker compose)",
    )
    p.add_argument("--days", type=int, default=825, help="validity of the certificates in days (default 825)")
    p.add_argument("--force", action="store_true", help="replace existing certificate and key files")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """``mjnav certs``."""
    from mjnav.bus.certs import DEFAULT_HOSTS, CertificateError, make_certificates
    from mjnav.msgs.topics import OPERATOR
    from mjnav.runtime.config import ConfigError
    from mjnav.runtime.stack import load_stack

    try:
        names = [*load_stack(args.stack).names(), OPERATOR, *args.client]
        files = make_certificates(args.out, names, hosts=args.host or DEFAULT_HOSTS, days=args.days, force=args.force)
    except (ConfigError, CertificateError) as exc:
        print(f"mjnav certs: {exc}", file=sys.stderr)
        return 2
    print(f"wrote {len(files)} files to {args.out}: CA, router, {', '.join(names)}")
    return 0
