"""The fleet's router settings: what every router cdus opens gets, and that Zenoh takes them."""

from __future__ import annotations

import json

from cdus.wire.transport import DEFAULT_LEASE_MS, ROUTER_EXTRA, Transport, router, zenoh_config


def test_a_router_closes_a_blocked_link_after_one_lease_not_zenohs_five_seconds(tmp_path):
    conf = zenoh_config(router(("tcp/127.0.0.1:7447",)))
    block = json.loads(conf.get_json("transport/link/tx/queue/congestion_control/block"))
    assert block["wait_before_close"] == DEFAULT_LEASE_MS * 1000  # µs
    assert json.loads(conf.get_json("scouting/multicast/enabled")) is False
    assert json.loads(conf.get_json("listen/endpoints")) == ["tcp/127.0.0.1:7447"]


def test_a_router_listens_on_loopback_unless_told_otherwise(tmp_path):
    r = router()
    assert r.mode == "router" and len(r.listen) == 1 and r.listen[0].startswith("tcp/127.0.0.1:")
    assert r.extra == ROUTER_EXTRA
    f = tmp_path / "z.json5"
    f.write_text('{listen: {endpoints: ["tcp/127.0.0.1:9"]}}')
    from_file = router(config_file=str(f))
    assert from_file.listen == () and json.loads(zenoh_config(from_file).get_json("listen/endpoints")) == [
        "tcp/127.0.0.1:9"]
    assert isinstance(from_file, Transport)
