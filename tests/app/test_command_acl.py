"""On a secured fleet only the ground role may ask the world's command queryable
(world/cmd/<from>): the router's access-control list denies everyone else's query, and the
asker sees no reply at once (how `cdus gs` tells a denial from silence)."""

from __future__ import annotations

import time

import zenoh

from cdus.app.credentials import make_credentials
from cdus.wire import keys
from cdus.wire.transport import Transport, free_tcp_port, open_session

LISTENERS = {"usv1": ("usv2",), "usv2": ("usv1",)}


def replies(session: zenoh.Session, key: str, timeout: float = 2.0) -> tuple[list[bytes], float]:
    t0 = time.monotonic()
    got = [r.ok.payload.to_bytes() for r in session.get(key, payload=b"cmd", timeout=timeout) if r.ok is not None]
    return got, time.monotonic() - t0


def test_only_the_ground_role_may_command_the_world_by_query(tmp_path):
    fleet = "aclq"
    cred = make_credentials(tmp_path, fleet, LISTENERS, (f"tcp/127.0.0.1:{free_tcp_port()}",))
    router = open_session(Transport(mode="router", listen=cred.listen, extra=cred.router_extra()))
    sessions = []
    try:
        def member(role: str) -> zenoh.Session:
            s = zenoh.open(zenoh.Config.from_file(str(cred.file(role))))
            sessions.append(s)
            return s

        world, ground, usv1 = member("world"), member("ground"), member("vehicle-usv1")
        asked = []
        world.declare_queryable(keys.any_world_command(fleet),
                                lambda q: (asked.append(str(q.key_expr)), q.reply(str(q.key_expr), b"ok")))
        key = keys.world_command(fleet, keys.GROUND)
        deadline = time.monotonic() + 10
        while not replies(ground, key, 1.0)[0]:  # the world's queryable reaches the router
            assert time.monotonic() < deadline, "the ground station's command never reached the world"
        assert asked and set(asked) == {key}
        n = len(asked)
        # (the world's own session would be answered locally: its queries never reach the router)
        for k in (key, keys.world_command(fleet, "usv1"), keys.world_command(fleet, keys.LAUNCHER)):
            got, waited = replies(usv1, k, timeout=20.0)
            assert got == [], k
            assert waited < 18.0, (k, waited)  # the get ends well before its timeout: refused, not silence
        assert len(asked) == n  # none of those reached the world
        # (a ground station asking as another sender reaches the world, which answers only "gs":
        # tests/world_sim/test_commands.py)
    finally:
        for s in sessions:
            s.close()
        router.close()
