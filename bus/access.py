"""Zenoh access control for a swarm, enforced by every router: what each login may not do.

Explicit denies win over everything (zenoh's priority: explicit deny > explicit allow > default);
the default is allow, because a router that connects to another router cannot authenticate it and
must still forward the swarm's traffic to it. A router only admits logins listed in its credentials
file, so the default reaches authenticated processes and peer routers only.

- only the world publishes sensor feeds, truth, the clock (and its pace) and the end of the run;
- only the ground station publishes the fault plan and its lockstep ack, and answers fault requests
  and id claims;
- nobody but the ground station (and routers, which carry it) subscribes to or receives truth;
- vehicle ``i`` (login ``vehicle-i``) cannot publish on any other swarm vehicle's keys, ack for it or
  declare its liveliness token: it speaks only for itself (keys of ids outside the swarm are refused
  by the processes, which count them as ``unknown_vehicle``);
- ``enroll`` (a vehicle that does not know its id yet), ``cli`` and ``supervisor`` cannot publish on
  any vehicle's keys or ack at all; ``enroll`` may only claim an id, ``cli`` only ask for faults.
"""

from __future__ import annotations

from bus.keys import GS_ACK, KeySpace
from bus.secrets import ROLE_USERS, VEHICLE_USER

SEND = ["put", "delete"]
EVERYTHING = [
    "put",
    "delete",
    "declare_subscriber",
    "query",
    "reply",
    "declare_queryable",
    "liveliness_token",
    "declare_liveliness_subscriber",
    "liveliness_query",
]


def _deny(rule_id: str, messages: list[str], key_exprs: list[str], flows: tuple[str, ...] = ("ingress",)) -> dict:
    return {"id": rule_id, "permission": "deny", "flows": list(flows), "messages": messages, "key_exprs": key_exprs}


def _shared_rules(k: KeySpace) -> list[dict]:
    return [
        _deny("no-truth", ["declare_subscriber", "put"], [k.truth()], ("ingress", "egress")),
        _deny("no-world-output", SEND, [k.feed("*"), k.truth(), k.clock(), k.pace(), k.end()]),
        _deny("no-world-token", ["liveliness_token"], [k.alive("world", "**")]),
        _deny(
            "no-fault-control",
            [*SEND, "declare_queryable", "reply"],
            [k.every_fault_key(), k.claim(), k.ack(GS_ACK)],
        ),
        _deny("no-gs-token", ["liveliness_token"], [k.alive("groundstation", "**")]),
        _deny("no-vehicle-speech", SEND, [k.mavlink("*"), k.v2v("*"), k.v2v_to("*", "*"), k.status("*")]),
        _deny("no-vehicle-acks", SEND, [k.ack("*")]),
        _deny("no-vehicle-token", ["liveliness_token"], [k.alive("vehicle", "**")]),
        _deny("no-fault-requests", ["query"], [k.every_fault_key()]),
        _deny("no-claims", ["query"], [k.claim()]),
    ]


_ROLE_DENIES = {
    "world": ["no-fault-control", "no-gs-token", "no-vehicle-speech", "no-vehicle-acks", "no-vehicle-token"],
    "groundstation": ["no-world-output", "no-world-token", "no-vehicle-speech", "no-vehicle-token"],
    "cli": [
        "no-truth",
        "no-world-output",
        "no-world-token",
        "no-fault-control",
        "no-gs-token",
        "no-vehicle-speech",
        "no-vehicle-acks",
        "no-vehicle-token",
        "no-claims",
    ],
    "supervisor": [
        "no-truth",
        "no-world-output",
        "no-world-token",
        "no-fault-control",
        "no-gs-token",
        "no-vehicle-speech",
        "no-vehicle-acks",
        "no-vehicle-token",
        "no-fault-requests",
        "no-claims",
    ],
    "enroll": [
        "no-truth",
        "no-world-output",
        "no-world-token",
        "no-fault-control",
        "no-gs-token",
        "no-vehicle-speech",
        "no-vehicle-acks",
        "no-vehicle-token",
        "no-fault-requests",
    ],
    "router": [],
}
_VEHICLE_DENIES = [
    "no-truth",
    "no-world-output",
    "no-world-token",
    "no-fault-control",
    "no-gs-token",
    "no-fault-requests",
    "no-claims",
]


def _others(k: KeySpace, vid: int, ids: list[int]) -> list[dict]:
    """Vehicle ``vid`` may not speak on another swarm vehicle's keys nor hold its token."""
    others = [j for j in ids if j != vid]
    if not others:
        return []
    return [
        _deny(f"vehicle-{vid}-only", SEND, [k.under_vehicle(j) for j in others] + [k.ack(j) for j in others]),
        _deny(f"vehicle-{vid}-token", ["liveliness_token"], [k.alive("vehicle", j) for j in others]),
    ]


def acl_policy(prefix: str, users: list[str] | None = None) -> dict:
    """The ``access_control`` section of a router's zenoh config for key prefix ``prefix`` and the
    logins ``users`` (the names in its credentials file; vehicles are ``vehicle-<id>``)."""
    users = list(ROLE_USERS) if users is None else users
    keys = KeySpace(prefix)
    rules = _shared_rules(keys)
    ids = sorted(int(m.group(1)) for m in map(VEHICLE_USER.fullmatch, users) if m)
    subjects, policies = [], []
    for user in users:
        match = VEHICLE_USER.fullmatch(user)
        if match:
            own = _others(keys, int(match.group(1)), ids)
            rules += own
            denies = _VEHICLE_DENIES + [r["id"] for r in own]
        elif user in _ROLE_DENIES:
            denies = _ROLE_DENIES[user]
        else:
            denies = [r["id"] for r in _shared_rules(keys)]  # a login we do not know may only listen
        subjects.append({"id": user, "usernames": [user]})
        if denies:
            policies.append({"rules": denies, "subjects": [user]})
    return {"enabled": True, "default_permission": "allow", "rules": rules, "subjects": subjects, "policies": policies}
