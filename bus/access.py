"""Zenoh access control for a swarm (the router enforces it): one user per role.

- only the world publishes sensor feeds, truth and the clock;
- only the ground station publishes fault-control keys and answers fault requests and id claims;
- vehicles, the supervisor and the CLI can neither subscribe to truth nor receive it.
Everything else is allowed (default permission "allow"); vehicles' MAVLink streams are protected
by MAVLink signing instead.
"""

from __future__ import annotations

ROLE_USERS = ("world", "vehicle", "groundstation", "supervisor", "cli")


def acl_policy(prefix: str) -> dict:
    """The ``access_control`` section of the router's zenoh config, for key prefix ``prefix``."""
    truth = [f"{prefix}/v/*/truth"]
    world_output = [f"{prefix}/v/*/sensor/**", f"{prefix}/v/*/truth", f"{prefix}/ctl/clock", f"{prefix}/ctl/end"]
    rules = [
        {"id": "no-truth", "permission": "deny", "flows": ["ingress", "egress"],
         "messages": ["declare_subscriber", "put", "query", "declare_queryable"], "key_exprs": truth},
        {"id": "no-fault-control", "permission": "deny", "flows": ["ingress"],
         "messages": ["put", "delete", "declare_queryable"], "key_exprs": [f"{prefix}/ctl/faults/**", f"{prefix}/ctl/claim"]},
        {"id": "no-world-output", "permission": "deny", "flows": ["ingress"],
         "messages": ["put", "delete"], "key_exprs": world_output},
    ]
    subjects = [{"id": user, "usernames": [user]} for user in ROLE_USERS]
    policies = [
        {"rules": ["no-truth", "no-fault-control", "no-world-output"], "subjects": ["vehicle", "supervisor", "cli"]},
        {"rules": ["no-fault-control"], "subjects": ["world"]},
        {"rules": ["no-world-output"], "subjects": ["groundstation"]},
    ]
    return {"enabled": True, "default_permission": "allow", "rules": rules, "subjects": subjects, "policies": policies}
