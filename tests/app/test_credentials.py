"""A secured run's credentials, and what Zenoh lets each role do with them (loopback only)."""

from __future__ import annotations

import json
import stat
import threading
import time

import pytest
import zenoh

from cdus.app.credentials import CredentialsError, endpoint_host, make_credentials, secure_endpoints
from cdus.wire import access, keys
from cdus.wire.messages import OmegaMsg, encode_control, encode_omega
from cdus.wire.transport import Transport, free_tcp_port, open_session
from tests.outsider import raw_client

IDS = ("usv1", "usv2", "uav1")
LISTENERS = {"usv1": ("usv2", "uav1"), "usv2": ("usv1",), "uav1": ("usv1",)}  # vehicle -> who hears its ω


def test_files_are_private_and_the_ca_key_is_never_written(tmp_path):
    cred = make_credentials(tmp_path / "secure", "f1", LISTENERS, ("tcp/127.0.0.1:7447",), "tls")
    d = tmp_path / "secure"
    assert stat.S_IMODE(d.stat().st_mode) == 0o700
    files = sorted(p.name for p in d.iterdir())
    for p in d.iterdir():
        assert stat.S_IMODE(p.stat().st_mode) == 0o600, p
    assert "ca.key" not in files and "ca.pem" in files
    for role in access.roles(IDS):
        assert f"{role}.json5" in files and f"{role}.pem" in files and f"{role}.key" in files
    users = [ln.split(":")[0] for ln in (d / "passwords").read_text().splitlines()]
    assert users == ["world", "ground", "vehicle-usv1", "vehicle-usv2", "vehicle-uav1"]
    assert cred.listen == ("tls/127.0.0.1:7447",)
    client = json.loads(cred.file("ground").read_text())
    assert client["scouting"]["multicast"]["enabled"] is False
    assert client["connect"]["endpoints"] == ["tls/127.0.0.1:7447"]
    assert client["transport"]["auth"]["usrpwd"]["user"] == "ground"
    assert "verify_name_on_connect" not in client["transport"]["link"]["tls"]  # the name is checked


def test_endpoints_in_tls_mode():
    assert secure_endpoints(("tcp/0.0.0.0:7447", "tls/10.0.0.1:1"), "tls") == ("tls/0.0.0.0:7447", "tls/10.0.0.1:1")
    assert secure_endpoints(("unixsock-stream//tmp/x",), "password") == ("unixsock-stream//tmp/x",)
    with pytest.raises(CredentialsError, match="cannot carry TLS"):
        secure_endpoints(("unixsock-stream//tmp/x",), "tls")
    with pytest.raises(CredentialsError, match="choose one of password, tls"):
        secure_endpoints(("tcp/127.0.0.1:1",), "kerberos")
    assert endpoint_host("tls/[::1]:7447#iface=lo") == "::1"
    assert endpoint_host("tcp/example.org:7447") == "example.org"


def test_a_wildcard_listener_turns_name_checks_off_for_clients(tmp_path):
    cred = make_credentials(tmp_path, "f1", LISTENERS, ("tcp/0.0.0.0:7447",), "tls")
    client = json.loads(cred.file("vehicle-usv1").read_text())
    assert client["connect"]["endpoints"] == ["tls/127.0.0.1:7447"]
    assert client["transport"]["link"]["tls"]["verify_name_on_connect"] is False


def test_the_acl_is_a_valid_zenoh_config_section():
    conf = zenoh.Config()
    conf.insert_json5("access_control", json.dumps(access.fleet_acl("f1", LISTENERS, match_certificates=True)))
    back = json.loads(conf.get_json("access_control"))
    assert back["enabled"] is True and back["default_permission"] == "deny"
    rules = {r["id"]: r for r in back["rules"]}
    assert rules["vehicle-usv1-put"]["key_exprs"] == ["cdus/f1/to/+usv2+uav1+/omega/usv1",
                                                      "cdus/f1/to/+world+/state/usv1", "cdus/f1/to/+world+/stats/usv1"]


class Heard:
    """Every put and every fleet liveliness token that reached the router."""

    def __init__(self, router, fleet: str):
        self.cond = threading.Condition()
        self.puts: list[str] = []
        self.tokens: set[str] = set()
        self.subs = [router.declare_subscriber("**", lambda s: self._on(self.puts.append, s)),
                     router.liveliness().declare_subscriber(keys.any_alive(fleet),
                                                            lambda s: self._on(self.tokens.add, s))]

    def _on(self, add, sample) -> None:
        with self.cond:
            add(str(sample.key_expr))
            self.cond.notify_all()

    def wait_for(self, key: str, timeout: float = 10.0) -> None:
        deadline = time.monotonic() + timeout
        with self.cond:
            while key not in self.puts and key not in self.tokens:
                assert time.monotonic() < deadline, f"{key} never arrived; heard {self.puts}, {self.tokens}"
                self.cond.wait(timeout=0.1)


@pytest.mark.parametrize("mode", ["password", "tls"])
def test_each_role_may_publish_only_its_own_keys(tmp_path, mode):
    fleet = "acl" + mode
    port = free_tcp_port()
    cred = make_credentials(tmp_path, fleet, LISTENERS, (f"tcp/127.0.0.1:{port}",), mode)
    ep = cred.listen[0]
    router = open_session(Transport(mode="router", listen=cred.listen, extra=cred.router_extra()))
    sessions = []
    try:
        heard = Heard(router, fleet)
        for who, conf in [("no credentials", raw_client(ep)),
                          ("plain tcp", raw_client(f"tcp/127.0.0.1:{port}"))][: 2 if mode == "tls" else 1]:
            with pytest.raises(zenoh.ZError):
                sessions.append(zenoh.open(conf))
        wrong = json.loads(cred.file("ground").read_text())
        wrong["transport"]["auth"]["usrpwd"]["password"] = "guess"
        (tmp_path / "wrong.json5").write_text(json.dumps(wrong))
        with pytest.raises(zenoh.ZError):
            sessions.append(zenoh.open(zenoh.Config.from_file(str(tmp_path / "wrong.json5"))))

        def member(role: str):
            s = zenoh.open(zenoh.Config.from_file(str(cred.file(role))))
            sessions.append(s)
            return s

        usv1, ground, world = member("vehicle-usv1"), member("ground"), member("world")
        watched = []  # by another member (a session hears its own puts whatever the router says)
        member("vehicle-uav1").declare_subscriber(keys.any_omega(fleet), lambda s: watched.append(str(s.key_expr)))
        omega = encode_omega(OmegaMsg(1, 0, 0.0, 123.0, -1.0))
        every = list(IDS)
        mine = keys.omega(fleet, "usv1", LISTENERS["usv1"])
        # a vehicle: its own ω to its own listeners, its telemetry and token; no one else's, no commands
        usv1.put(keys.omega(fleet, "usv2", LISTENERS["usv2"]), omega)  # another vehicle's ω
        usv1.put(keys.omega(fleet, "usv1", ["usv2"]), omega)  # its own, to a set it does not address
        usv1.put(keys.world_cmd(fleet, keys.GROUND), encode_control("stop"))
        usv1.put(keys.world_cmd(fleet, "usv1"), encode_control("set_gains", gains={"c": 0.1}, vehicle=""))
        usv1.put(keys.ctl(fleet, every), encode_control("stop"))
        usv1.put(keys.launcher_cmd(fleet), encode_control("kill", vehicle="usv2"))
        usv1.put(keys.state(fleet, "usv2"), b"x")
        usv1.put(keys.contacts(fleet, "usv2"), b"x")  # the world's proximity sensor
        # tokens: another vehicle's (with its own session id or usv2's name bare), a wildcard that
        # would intersect every watch of the fleet (docs/security.md, "Liveliness"); its own
        zid1 = str(usv1.zid())
        for forged in (keys.alive(fleet, "usv2", zid1), f"cdus/{fleet}/alive/usv2", f"cdus/{fleet}/alive/**",
                       keys.alive(fleet, keys.WORLD, zid1), keys.alive_of(fleet, "usv2")):
            usv1.liveliness().declare_token(forged)
        ground.liveliness().declare_token(f"cdus/{fleet}/alive/**")
        ground.liveliness().declare_token(keys.alive(fleet, "usv2", str(ground.zid())))
        usv1.liveliness().declare_token(keys.alive(fleet, "usv1", zid1))
        usv1.put(keys.state(fleet, "usv1"), b"x")
        usv1.put(mine, omega)
        # the ground station: commands to the world, not ω, not the world's own keys
        ground.put(keys.omega(fleet, "usv2", LISTENERS["usv2"]), omega)
        ground.put(keys.ctl(fleet, every), encode_control("stop"))
        ground.put(keys.world_cmd(fleet, keys.LAUNCHER), encode_control("stop"))
        ground.put(keys.world_status(fleet), b"x")
        ground.put(keys.contacts(fleet, "usv1"), b"x")
        ground.put(keys.world_cmd(fleet, keys.GROUND), encode_control("stop"))
        # the world: the clock and relayed commands, its reports; not ω or vehicle telemetry
        world.put(keys.state(fleet, "usv1"), b"x")
        world.put(keys.omega(fleet, "usv1", LISTENERS["usv1"]), omega)
        world.put(keys.world_events(fleet), b"x")
        world.put(keys.contacts(fleet, "usv1"), b"x")  # its proximity sensor (the safety filter's input)
        world.put(keys.ctl(fleet, ["usv2"]), encode_control("stop"))
        # a key outside the fleet is nobody's
        ground.put(keys.world_cmd("otherfleet", keys.GROUND), encode_control("stop"))
        ground.put("elsewhere", b"x")
        for last in (mine, keys.world_cmd(fleet, keys.GROUND), keys.ctl(fleet, ["usv2"])):
            heard.wait_for(last)  # each session's puts arrive in order: what is missing was refused
        heard.wait_for(keys.alive(fleet, "usv1", zid1))
        assert heard.tokens == {keys.alive(fleet, "usv1", zid1)}
        assert sorted(heard.puts) == sorted([keys.state(fleet, "usv1"), mine, keys.world_cmd(fleet, keys.GROUND),
                                             keys.world_events(fleet), keys.contacts(fleet, "usv1"),
                                             keys.ctl(fleet, ["usv2"])])
        # members hear each other: usv1's ω reached uav1 through the router
        # (uav1's subscription may reach the router after usv1's first put: put again until heard)
        deadline = time.monotonic() + 10
        while mine not in watched and time.monotonic() < deadline:
            usv1.put(mine, omega)
            time.sleep(0.05)
        assert set(watched) == {mine}
        # a vehicle answers its own link check, and cannot answer another's
        usv1.declare_queryable(keys.ping(fleet, "usv1"), lambda q: q.reply(keys.ping(fleet, "usv1"), b""))
        usv1.declare_queryable(keys.ping(fleet, "usv2"), lambda q: q.reply(keys.ping(fleet, "usv2"), b""))
        asker = member("vehicle-uav1")
        deadline = time.monotonic() + 10
        while not any(r.ok is not None for r in asker.get(keys.ping(fleet, "usv1"), timeout=1.0)):
            assert time.monotonic() < deadline, "usv1 never answered its own link check"
        assert not any(r.ok is not None for r in asker.get(keys.ping(fleet, "usv2"), timeout=1.0))
        # the world's status and settings answer the ground station, not a vehicle (a vehicle's
        # query flood on them slowed a lockstep run: issue 27); where vehicles were, both
        for key in (keys.world_status(fleet), keys.world_settings(fleet), keys.world_last(fleet, "usv2")):
            world.declare_queryable(key, lambda q: q.reply(str(q.key_expr), b"ok"))
        deadline = time.monotonic() + 10
        while not any(r.ok is not None for r in ground.get(keys.world_status(fleet), timeout=1.0)):
            assert time.monotonic() < deadline, "the world never answered the ground station's status query"
        assert any(r.ok is not None for r in ground.get(keys.world_settings(fleet), timeout=1.0))
        assert any(r.ok is not None for r in usv1.get(keys.world_last(fleet, "usv2"), timeout=1.0))
        for key in (keys.world_status(fleet), keys.world_settings(fleet)):
            assert not any(r.ok is not None for r in usv1.get(key, timeout=1.0)), key
    finally:
        for s in sessions:
            s.close()
        router.close()
