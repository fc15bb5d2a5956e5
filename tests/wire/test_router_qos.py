"""The fleet's router drops a command query it cannot pass on rather than wait (rev-gs):
cdus.wire.transport.COMMANDS_DROP; docs/ground_station.md says what waiting did to a flooded fleet."""

from __future__ import annotations

import json

from cdus.wire import keys
from cdus.wire.transport import ROUTER_EXTRA, free_tcp_port, router, zenoh_config


def test_the_router_overwrites_command_queries_to_drop_under_congestion():
    rules = [json.loads(v) for k, v in ROUTER_EXTRA if k == "qos/network"]
    assert len(rules) == 1
    (rule,) = rules[0]
    assert rule["messages"] == ["query"] and rule["flows"] == ["ingress"]
    assert rule["overwrite"] == {"congestion_control": "drop"}
    (expr,) = rule["key_exprs"]
    # every fleet's command key, and nothing else of the fleet's
    import zenoh
    ke = zenoh.KeyExpr(expr)
    assert ke.intersects(zenoh.KeyExpr(keys.world_command("lake", keys.GROUND)))
    assert not ke.intersects(zenoh.KeyExpr(keys.world_last("lake", "usv1")))
    assert not ke.intersects(zenoh.KeyExpr(keys.state("lake", "usv1")))


def _given(v):
    """A config value read back without the fields Zenoh filled with null."""
    if isinstance(v, dict):
        return {k: _given(x) for k, x in v.items() if x is not None}
    return [_given(x) for x in v] if isinstance(v, list) else v


def test_this_zenoh_keeps_the_routers_command_drop_rule_and_opens_with_it():
    """zenoh_config goes without qos/network where Zenoh refuses it (an older Zenoh): with the
    Zenoh installed here (1.10: it knows the setting) the router's config must hold the rule as
    ROUTER_EXTRA gives it, and a router must open with that config. (It only opened and closed a
    session before: it passed with the rule dropped.)"""
    import zenoh

    conf = zenoh_config(router((f"tcp/127.0.0.1:{free_tcp_port()}",)))
    want = json.loads(dict(ROUTER_EXTRA)["qos/network"])
    got = json.loads(conf.get_json("qos/network"))  # Zenoh fills the fields not given with null
    assert _given(got) == want
    assert got[0]["overwrite"]["congestion_control"] == "drop"
    zenoh.open(conf).close()  # the same config object: what a router of the fleet runs with


def test_a_zenoh_that_does_not_know_the_setting_goes_without_it():
    """pyproject allows eclipse-zenoh>=1.0; a router whose Zenoh refuses qos/network must still start."""
    from cdus.wire.transport import Transport
    t = Transport(mode="router", listen=(f"tcp/127.0.0.1:{free_tcp_port()}",),
                  extra=(("qos/network", "[{unknown_field: 1}]"),))
    zenoh_config(t)  # raised zenoh.ZError
