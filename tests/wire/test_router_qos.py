"""The fleet's router drops a command query it cannot pass on rather than wait (rev-gs):
cdus.wire.transport.COMMANDS_DROP; docs/ground_station.md says what waiting did to a flooded fleet."""

from __future__ import annotations

import json

from cdus.wire import keys
from cdus.wire.transport import ROUTER_EXTRA, open_session, router


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


def test_zenoh_takes_the_routers_settings():
    from cdus.wire.transport import free_tcp_port
    s = open_session(router((f"tcp/127.0.0.1:{free_tcp_port()}",)))
    s.close()


def test_a_zenoh_that_does_not_know_the_setting_goes_without_it():
    """pyproject allows eclipse-zenoh>=1.0; a router whose Zenoh refuses qos/network must still start."""
    from cdus.wire.transport import Transport, free_tcp_port, zenoh_config
    t = Transport(mode="router", listen=(f"tcp/127.0.0.1:{free_tcp_port()}",),
                  extra=(("qos/network", "[{unknown_field: 1}]"),))
    zenoh_config(t)  # raised zenoh.ZError
