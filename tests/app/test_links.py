"""How the launcher wires ω between neighbours: direct peer links or the router."""

from __future__ import annotations

from cdus.app.cli import build_parser, launch_options
from cdus.app.launcher import Launcher
from cdus.scenario.config import load_scenario
from cdus.wire.transport import Transport

ROUTER = Transport(mode="router", listen=("tcp/127.0.0.1:7999",))


def launcher(tmp_path, *flags):
    sc = load_scenario("configs/lake_circle.toml")
    args = build_parser().parse_args(["launch", "configs/lake_circle.toml", *flags])
    return Launcher(sc, tmp_path / "run", ROUTER, launch_options(args, sc), log=lambda s: None)


def argv_after(argv, flag):
    return [argv[i + 1] for i, a in enumerate(argv) if a == flag]


def test_direct_links_make_each_agent_a_peer_on_its_own_socket_linked_to_its_ring_neighbours(tmp_path):
    la = launcher(tmp_path, "--links", "direct", "--insecure")
    try:
        argv = la._agent("usv2").argv
        assert argv_after(argv, "--mode") == ["peer"]
        sock = lambda vid: f"unixsock-stream/{la.sockets / (vid + '.sock')}"  # noqa: E731
        assert argv_after(argv, "--listen") == [sock("usv2")]
        # the router, then exactly the ring neighbours (usv1 - usv2 - usv3): no other peer link
        assert argv_after(argv, "--connect") == ["tcp/127.0.0.1:7999", sock("usv1"), sock("usv3")]
        assert len(str(la.sockets / "usv2.sock")) < 100  # unix socket paths are limited to 108 bytes
        world = la._world().argv
        assert argv_after(world, "--mode") == ["client"] and "--listen" not in world
    finally:
        la.stop()
    assert not la.sockets.exists()  # the socket directory goes with the run


def test_a_restarted_agent_rejoins_and_does_not_wait_for_dead_listeners(tmp_path):
    la = launcher(tmp_path)
    try:
        c = la._agent("uav1")
        assert "--rejoin" not in c.argv and c.restart_args == ("--rejoin",)
    finally:
        la.stop()


def test_router_links_keep_every_agent_a_client_of_the_router(tmp_path):
    la = launcher(tmp_path)  # the default
    try:
        argv = la._agent("usv2").argv
        assert argv_after(argv, "--mode") == ["client"]
        assert argv_after(argv, "--connect") == ["tcp/127.0.0.1:7999"] and "--listen" not in argv
        assert la.sockets is None
    finally:
        la.stop()
