"""The fleet's router settings: what every router cdus opens gets, and that Zenoh takes them."""

from __future__ import annotations

import json

from cdus.wire.transport import (DEFAULT_ENDPOINT, DEFAULT_LEASE_MS, ROUTER_EXTRA, Transport, client_of, router,
                                   zenoh_config)


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


def test_a_router_or_peer_waits_for_no_scouting_answers_on_open_a_client_and_a_users_file_keep_zenohs(tmp_path):
    """With multicast off nothing answers a scout: Zenoh's default scouting/delay made every router
    open take 500 ms (every `cdus launch`); ours is 0 unless the user's file says otherwise."""
    delay = lambda t: json.loads(zenoh_config(t).get_json("scouting/delay"))  # noqa: E731
    assert delay(router(("tcp/127.0.0.1:7447",))) == 0
    assert delay(Transport(mode="peer", listen=("tcp/127.0.0.1:7448",))) == 0
    assert delay(Transport(mode="client", connect=("tcp/127.0.0.1:7447",))) is None  # unset: a client's is its wait for a router
    f = tmp_path / "z.json5"
    f.write_text('{scouting: {delay: 250}, listen: {endpoints: ["tcp/127.0.0.1:9"]}}')
    assert delay(router(config_file=str(f))) == 250


def test_the_clients_of_a_router_given_only_a_config_file_connect_where_the_file_listens(tmp_path):
    """`cdus launch --zenoh-config FILE --insecure` (no --listen): the router listens where FILE
    says; its world and vehicles connected to DEFAULT_ENDPOINT instead (the world gave up after
    30 s, the metrics said world_lost). A file naming no endpoint: Zenoh's router default,
    tcp/[::]:7447, reached on loopback, as before."""
    f = tmp_path / "z.json5"
    f.write_text('{listen: {endpoints: ["tcp/127.0.0.1:9", "tcp/0.0.0.0:10"]}}')
    assert client_of(router(config_file=str(f))).connect == ("tcp/127.0.0.1:9", "tcp/127.0.0.1:10")
    (tmp_path / "none.json5").write_text("{}")
    assert client_of(router(config_file=str(tmp_path / "none.json5"))).connect == (DEFAULT_ENDPOINT,)
    assert client_of(router(("tcp/0.0.0.0:11",), config_file=str(f))).connect == ("tcp/127.0.0.1:11",)  # --listen wins
