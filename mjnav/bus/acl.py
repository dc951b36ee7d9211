"""Zenoh access control for the stack: the router's ACL, generated from the rights tables of :mod:`mjnav.msgs.topics`.

With mutual TLS (certificates from ``mjnav certs``) the router knows who is at the other end of every link: the
common name of the client's certificate — a service name, or ``operator`` for a user's tools. The router's
``access_control`` section (default deny) then says, per identity:

- everyone may subscribe, watch and query liveliness tokens, read every service's ``config``, ask latched topics'
  publishers for their newest message, and receives whatever the router forwards to it;
- identity ``X`` may publish the topics :data:`~mjnav.msgs.topics.PUBLISH_RIGHTS` gives ``X`` and its own
  per-service keys (``<ns>/status/X``, ``<ns>/lockstep/X``), keep the history of the latched topics it publishes
  (Zenoh's advanced publisher: a queryable and a token under ``<key>/@adv/``, replies on ``<key>``; and since
  Zenoh's wildcards never match a verbatim ``@`` chunk, the everyone-rules name those history keys besides ``**``),
  hold its own liveliness tokens
  (``mjnav/alive/<ns>/X``, ``mjnav/lockstep/<ns>/X``), serve the endpoints
  :data:`~mjnav.msgs.topics.SERVE_RIGHTS` gives it, and call those :data:`~mjnav.msgs.topics.CALL_RIGHTS` gives it;
- the operator also holds the lockstep slots of the launcher's extra participants (``mjnav demo``'s mission client).

Anything else a client sends (a forged clock, goal status, costmap, cmd_vel, lockstep report or token) is dropped by
the router before any subscriber sees it.
"""

from __future__ import annotations

import json
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import zenoh

from mjnav.bus.certs import ROUTER
from mjnav.bus.config import BusConfig, tls_files
from mjnav.msgs.topics import (
    ANYONE,
    CALL_RIGHTS,
    ENDPOINTS,
    OPERATOR,
    OWN,
    PUBLISH_RIGHTS,
    SERVE_RIGHTS,
    TOPICS,
    alive_key,
    check_namespace,
    lockstep_key,
)

#: Every message kind a Zenoh 1.x ACL rule can name.
MESSAGES = (
    "put",
    "delete",
    "declare_subscriber",
    "query",
    "declare_queryable",
    "reply",
    "liveliness_token",
    "declare_liveliness_subscriber",
    "liveliness_query",
)
#: What an identity may do, and the Zenoh message kinds (router ingress) each action covers.
ACTIONS: dict[str, tuple[str, ...]] = {
    "put": ("put",),
    "token": ("liveliness_token",),
    "serve": ("declare_queryable", "reply"),
    "query": ("query",),
}
#: Everyone's (router ingress) message kinds on every key: reading, never writing.
_OBSERVE = ("declare_subscriber", "declare_liveliness_subscriber", "liveliness_query")


class AclError(ValueError):
    """Identities that cannot be given rules (bad or clashing names)."""


@dataclass(frozen=True, slots=True)
class Grant:
    """The keys one identity may act on (concrete keys or Zenoh key expressions), by action of :data:`ACTIONS`."""

    identity: str
    put: tuple[str, ...]
    token: tuple[str, ...]
    serve: tuple[str, ...]
    query: tuple[str, ...]

    def keys(self, action: str) -> tuple[str, ...]:
        """The key expressions of ``action`` (``put``, ``token``, ``serve`` or ``query``)."""
        if action not in ACTIONS:
            raise KeyError(f"unknown action {action!r}; actions: {', '.join(ACTIONS)}")
        keys: tuple[str, ...] = getattr(self, action)
        return keys


def _key(row: Any, namespace: str, rights: tuple[str, ...], identity: str) -> str | None:
    """The key of topic or endpoint ``row`` that ``rights`` open to ``identity`` (None: none). The
    :data:`ANYONE` identity gets the rights given to anyone; the others only what is theirs besides."""
    if identity == ANYONE:
        if ANYONE not in rights:
            return None
        return row.key(namespace, "*") if row.per_service else row.key(namespace)
    if row.per_service:
        return row.key(namespace, identity) if OWN in rights or identity in rights else None
    return row.key(namespace) if identity in rights else None


def grants(namespace: str, services: Sequence[str], extra_participants: Sequence[str] = ()) -> dict[str, Grant]:
    """Each identity's rights in ``namespace``: one per service of the stack, :data:`OPERATOR`, and
    :data:`ANYONE` (what every certificate holder may do besides what is its own).

    Args:
        namespace: robot namespace of the stack.
        services: the stack's service names (each one's certificate common name).
        extra_participants: lockstep participants besides the services (clients of the operator).

    Raises:
        AclError: a service is called like the operator role, or twice.
    """
    check_namespace(namespace)
    if OPERATOR in services:
        raise AclError(f"a service may not be called {OPERATOR!r}: that name is the operator's identity")
    if len(set(services)) != len(services):
        raise AclError(f"duplicate service names in {list(services)}")
    out = {}
    for identity in (*services, OPERATOR, ANYONE):
        participants = [identity] + (list(extra_participants) if identity == OPERATOR else [])
        put = [_key(TOPICS[name], namespace, rights, identity) for name, rights in PUBLISH_RIGHTS.items()]
        put += [TOPICS["lockstep"].key(namespace, p) for p in participants[1:]]
        serve = [_key(ENDPOINTS[name], namespace, rights, identity) for name, rights in SERVE_RIGHTS.items()]
        query = [_key(ENDPOINTS[name], namespace, rights, identity) for name, rights in CALL_RIGHTS.items()]
        tokens = [alive_key(namespace, identity)] + [lockstep_key(namespace, p) for p in participants]
        # Latched topics: their publishers answer late joiners from a cache (queryable + token under the key; the
        # replies carry the samples' own key).
        latched = [
            row
            for row in TOPICS.values()
            if row.latched and _key(row, namespace, PUBLISH_RIGHTS[row.name], identity) is not None
        ]
        history = [row.history_key(namespace) for row in latched]
        serve += history + [row.key(namespace) for row in latched]
        tokens += history
        if identity == ANYONE:
            put, tokens = [], []
            query += [row.history_key(namespace) for row in TOPICS.values() if row.latched]
        out[identity] = Grant(identity, _some(put), tuple(tokens), _some(serve), _some(query))
    return out


def _some(keys: list[str | None]) -> tuple[str, ...]:
    return tuple(k for k in keys if k is not None)


def allowed(table: dict[str, Grant], identity: str, action: str, key: str) -> bool:
    """Whether the rights ``table`` (from :func:`grants`) let ``identity`` do ``action`` on the concrete ``key``
    (Zenoh key-expression inclusion, as the router matches it). Unknown identities have the rights of anyone."""
    target = zenoh.KeyExpr(key)
    own = table[identity].keys(action) if identity in table else ()
    return any(zenoh.KeyExpr(expr).includes(target) for expr in (*own, *table[ANYONE].keys(action)))


def access_control(namespace: str, services: Sequence[str], extra_participants: Sequence[str] = ()) -> dict[str, Any]:
    """The router's ``access_control`` config section (Zenoh 1.x schema) for the stack.

    Subjects are matched by certificate common name, so the router must run mutual TLS (see
    :class:`~mjnav.bus.BusConfig`). Default deny; the allow rules are those of :func:`grants`.
    """
    table = grants(namespace, services, extra_participants)
    # Zenoh's wildcards never match a verbatim chunk (one starting with "@"): the latched topics' history keys
    # (``<key>/@adv/**``) are named besides ``**``, or no late joiner ever gets a latched message through the router
    # (the history query and its reply are not forwarded, the liveliness subscriber that detects late publishers is
    # refused) — seen as the INS waiting for ``datum`` for ever whenever it subscribed after the sim published it.
    everything = ["**", *(row.history_key(namespace) for row in TOPICS.values() if row.latched)]
    rules: list[dict[str, Any]] = [
        _rule("receive", "egress", MESSAGES, everything),
        _rule("observe", "ingress", _OBSERVE, everything),
    ]
    subjects: list[dict[str, Any]] = []
    policies: list[dict[str, Any]] = []
    for identity, grant in table.items():
        ids = ["receive", "observe"] if identity == ANYONE else []
        for action, messages in ACTIONS.items():
            keys = grant.keys(action)
            if keys:
                ids.append(f"{identity}:{action}")
                rules.append(_rule(ids[-1], "ingress", messages, list(keys)))
        # The subject without conditions matches every client (all hold a certificate: the router runs mTLS).
        subjects.append({"id": identity} if identity == ANYONE else {"id": identity, "cert_common_names": [identity]})
        policies.append({"id": identity, "rules": ids, "subjects": [identity]})
    return {
        "enabled": True,
        "default_permission": "deny",
        "rules": rules,
        "subjects": subjects,
        "policies": policies,
    }


def secure_router_config(
    directory: str | Path,
    listen: Sequence[str],
    namespace: str,
    services: Sequence[str],
    extra_participants: Sequence[str] = (),
) -> BusConfig:
    """A router on mutual TLS with the certificates of ``directory`` (``mjnav certs``) and the stack's access
    control (:func:`access_control`).

    Raises:
        BusConfigError: a certificate is missing, or an endpoint is not ``tls/``.
        AclError: the service names cannot be given rules.
    """
    return BusConfig(
        mode="router",
        connect=(),
        listen=tuple(listen),
        access_control=json.dumps(access_control(namespace, services, extra_participants)),
        **tls_files(directory, ROUTER),
    )


def _rule(rule_id: str, flow: str, messages: Iterable[str], keys: list[str]) -> dict[str, Any]:
    return {"id": rule_id, "permission": "allow", "flows": [flow], "messages": list(messages), "key_exprs": keys}


def rights_markdown() -> str:
    """The rights tables as Markdown, as they appear in README.md (generated; a test keeps them equal)."""

    def who(rights: tuple[str, ...]) -> str:
        names = {OWN: "each identity, its own key", ANYONE: "anyone with a certificate"}
        return ", ".join(names.get(r, r) for r in rights)

    groups: dict[tuple[str, ...], list[str]] = {}
    for name, rights in PUBLISH_RIGHTS.items():
        groups.setdefault(rights, []).append(f"`<ns>/{TOPICS[name].pattern}`")
    lines = ["| keys | may publish |", "|---|---|"]
    lines += [f"| {', '.join(keys)} | {who(rights)} |" for rights, keys in groups.items()]
    lines += ["", "| endpoint | may serve | may call |", "|---|---|---|"]
    for name, ep in ENDPOINTS.items():
        lines.append(f"| `<ns>/{ep.pattern}` | {who(SERVE_RIGHTS[name])} | {who(CALL_RIGHTS[name])} |")
    return "\n".join(lines)
