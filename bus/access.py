"""Zenoh access control for a swarm, enforced by the router: a whitelist per login.

Nothing is allowed unless listed (``default_permission: deny``; an explicit deny wins over an allow):

- every login may subscribe to and receive everything under the prefix, except truth: only the
  world publishes it and only the ground station (and routers) may receive it;
- the world publishes sensor feeds, truth, the clock and the end of the run;
- the ground station publishes the fault plan and its lockstep ack, and answers fault requests and
  id claims;
- vehicle ``i`` (login ``vehicle-i``) publishes only its own MAVLink, V2V and status keys and its own
  ack, and declares only its own liveliness token: it cannot speak for another vehicle;
- ``enroll`` (a vehicle that does not know its id yet) may only claim one; ``cli`` may ask for fault
  changes; ``supervisor`` only listens; other routers (``router``) carry everything.
"""

from __future__ import annotations

from bus.secrets import ROLE_USERS, VEHICLE_USER

LISTEN = ["declare_subscriber", "declare_liveliness_subscriber", "liveliness_query"]
EVERYTHING = ["put", "delete", "declare_subscriber", "query", "reply", "declare_queryable", "liveliness_token",
              "declare_liveliness_subscriber", "liveliness_query"]


def _rule(rule_id: str, permission: str, flows: list[str], messages: list[str], key_exprs: list[str]) -> dict:
    return {"id": rule_id, "permission": permission, "flows": flows, "messages": messages, "key_exprs": key_exprs}


def _role_rules(p: str) -> dict[str, list[dict]]:
    """Ingress rules that say what each role may send, besides listening."""
    return {
        "world": [_rule("world-out", "allow", ["ingress"], ["put"],
                        [f"{p}/v/*/feed", f"{p}/truth", f"{p}/ctl/clock", f"{p}/ctl/end"]),
                  _rule("world-alive", "allow", ["ingress"], ["liveliness_token"], [f"{p}/alive/world/*"])],
        "groundstation": [_rule("gs-out", "allow", ["ingress"], ["put"], [f"{p}/ctl/faults/plan", f"{p}/ctl/ack/gs"]),
                          _rule("gs-answer", "allow", ["ingress"], ["declare_queryable", "reply"],
                                [f"{p}/ctl/faults/request", f"{p}/ctl/claim"]),
                          _rule("gs-alive", "allow", ["ingress"], ["liveliness_token"], [f"{p}/alive/groundstation/*"])],
        "cli": [_rule("cli-ask", "allow", ["ingress"], ["query"], [f"{p}/ctl/faults/request"])],
        "enroll": [_rule("enroll-ask", "allow", ["ingress"], ["query"], [f"{p}/ctl/claim"])],
        "supervisor": [],
        "router": [_rule("router-all", "allow", ["ingress"], EVERYTHING, [f"{p}/**"])],
    }


def _vehicle_rules(p: str, vid: int) -> list[dict]:
    return [_rule(f"vehicle-{vid}-out", "allow", ["ingress"], ["put"],
                  [f"{p}/v/{vid}/mavlink", f"{p}/v/{vid}/v2v", f"{p}/v/{vid}/status", f"{p}/ctl/ack/{vid}"]),
            _rule(f"vehicle-{vid}-alive", "allow", ["ingress"], ["liveliness_token"], [f"{p}/alive/vehicle/{vid}"])]


def acl_policy(prefix: str, users: list[str] | None = None) -> dict:
    """The ``access_control`` section of the router's zenoh config for key prefix ``prefix`` and the
    logins ``users`` (the names in its credentials file; vehicles are ``vehicle-<id>``)."""
    users = list(ROLE_USERS) if users is None else users
    p = prefix
    truth = [f"{p}/truth"]
    rules = [_rule("listen", "allow", ["ingress"], LISTEN, [f"{p}/**"]),
             _rule("receive", "allow", ["egress"], EVERYTHING, [f"{p}/**"]),
             _rule("no-truth", "deny", ["ingress", "egress"], ["declare_subscriber", "put"], truth)]
    subjects, policies = [], []
    role_rules = _role_rules(p)
    for user in users:
        match = VEHICLE_USER.fullmatch(user)
        if match:
            own = _vehicle_rules(p, int(match.group(1)))
        elif user in role_rules:
            own = role_rules[user]
        else:
            continue  # an unknown login may authenticate but do nothing at all
        rules += [r for r in own if r["id"] not in {x["id"] for x in rules}]
        sees_truth = user in ("groundstation", "router")
        subjects.append({"id": user, "usernames": [user]})
        policies.append({"rules": ["listen", "receive", *(r["id"] for r in own),
                                   *([] if sees_truth or user == "world" else ["no-truth"])], "subjects": [user]})
    return {"enabled": True, "default_permission": "deny", "rules": rules, "subjects": subjects, "policies": policies}
