"""What a secured fleet's router lets the ROS 2 side do (cdus.wire.access, docs/security.md):
nothing of it without [ros2]; with it, the bridge publishes exactly its topics and a ROS 2
machine reads them and publishes nothing (a real router on loopback enforces the list)."""

from __future__ import annotations

import json
import time

import pytest
import zenoh

from cdus.app.credentials import make_credentials
from cdus.ros2.fleet import grant, key, topics
from cdus.scenario.ros2 import Ros2Spec
from cdus.wire import access, keys
from cdus.wire.transport import Transport, free_tcp_port, open_session
from tests.app.test_credentials import Heard

LISTENERS = {"usv1": ("usv2",), "usv2": ("usv1",)}
SPEC = Ros2Spec(enabled=True, domain_id=4, namespace="/lake")


def test_a_fleet_without_ros2_has_no_ros2_role_or_rule(tmp_path):
    acl = access.fleet_acl("f", LISTENERS)
    text = json.dumps(acl)
    assert "ros2" not in text and "@ros2_lv" not in text and "@adv" not in text
    cred = make_credentials(tmp_path, "f", LISTENERS, ("tcp/127.0.0.1:7447",))
    assert not cred.file(access.ROS2_ROLE).exists() and not cred.file(access.ROS2_CLIENT_ROLE).exists()


def test_the_bridge_may_put_exactly_its_topics():
    g = grant(SPEC, list(LISTENERS))
    rules = {r["id"]: r for r in access.fleet_acl("f", LISTENERS, ros2=g)["rules"]}
    assert rules["ros2-put"]["key_exprs"] == [key(SPEC, t) for t in topics(SPEC, list(LISTENERS))]
    assert rules["ros2-tokens"]["key_exprs"] == ["@ros2_lv/4/**", "cdus/f/alive/ros2/*"]
    assert all(k.startswith("4/") for k in rules["ros2-put"]["key_exprs"])


def test_a_router_enforces_it(tmp_path):
    fleet, port = "r2acl", free_tcp_port()
    g = grant(SPEC, list(LISTENERS))
    cred = make_credentials(tmp_path, fleet, LISTENERS, (f"tcp/127.0.0.1:{port}",), ros2=g)
    router = open_session(Transport(mode="router", listen=cred.listen, extra=cred.router_extra()))
    sessions = []
    try:
        heard = Heard(router, fleet)
        tokens = []
        router.liveliness().declare_subscriber("@ros2_lv/**", lambda s: tokens.append(str(s.key_expr)))

        def member(role: str):
            s = zenoh.open(zenoh.Config.from_file(str(cred.file(role))))
            sessions.append(s)
            return s

        bridge, client = member(access.ROS2_ROLE), member(access.ROS2_CLIENT_ROLE)
        pose = key(SPEC, next(t for t in topics(SPEC, ["usv1"]) if t.field == "pose"))
        client.put(pose, b"forged")  # a ROS 2 machine publishes nothing
        client.put(keys.world_cmd(fleet, keys.GROUND), b"stop")  # nor into the fleet
        bridge.put(keys.state(fleet, "usv1"), b"x")  # the bridge speaks for no vehicle
        bridge.put(keys.world_events(fleet), b"x")
        bridge.put("4/cdus/other/topic", b"x")  # nor on a topic of its domain it does not publish
        bridge.put("5/lake/usv1/pose", b"x")  # nor in another domain
        bridge.liveliness().declare_token("@ros2_lv/5/x/0/0/NN/%/%/n")
        client.liveliness().declare_token("@ros2_lv/4/c/0/0/NN/%/%/rviz")  # a ROS node's own presence: allowed
        mine = keys.alive(fleet, access.ROS2_ROLE, str(bridge.zid()))
        bridge.liveliness().declare_token(mine)
        bridge.put(pose, b"ok")
        heard.wait_for(pose)
        heard.wait_for(mine)
        assert heard.puts == [pose]
        assert heard.tokens == {mine}
        # the client's token comes by its own session: the bridge's being heard says nothing of it
        deadline = time.monotonic() + 10
        while not tokens and time.monotonic() < deadline:
            time.sleep(0.02)
        assert set(tokens) == {"@ros2_lv/4/c/0/0/NN/%/%/rviz"}
        # the client hears the bridge's topic; the bridge hears the fleet; the client does not
        got, by_bridge, by_client = [], [], []
        client.declare_subscriber(pose, lambda s: got.append(s.payload.to_bytes()))
        bridge.declare_subscriber(keys.any_state(fleet), lambda s: by_bridge.append(1))
        client.declare_subscriber(keys.any_state(fleet), lambda s: by_client.append(1))
        usv1 = member("vehicle-usv1")
        deadline = time.monotonic() + 10
        while not (got and by_bridge):  # a subscription reaches the router some time after it is declared
            assert time.monotonic() < deadline, f"heard: client {len(got)}, bridge {len(by_bridge)}"
            bridge.put(pose, b"ok")
            usv1.put(keys.state(fleet, "usv1"), b"x")
            time.sleep(0.05)
        assert set(got) == {b"ok"} and by_client == []
    finally:
        for s in sessions:
            s.close()
        router.close()
