"""The ground station's side of a command (GroundStation.command) and its JSON snapshot, with a
fake session: every answer maps to one outcome and exit code, an unreadable one is counted,
a query that comes back empty at once from a fleet whose world is up is a denial."""

from __future__ import annotations

import dataclasses
import json
import threading
import time

import msgpack
import zenoh
from hypothesis import given, settings, strategies as hs

from cdus.wire.messages import StateMsg, encode_states
from cdus.wire.schemas import CommandReply, FleetEvent, encode_event, encode_reply, StatusExtra, encode_status
from ground_station.console import GroundStation, _not_live, status_table

from .test_console import Sample


class Reply:
    def __init__(self, key: str, payload: bytes | None, err: bytes | None = None):
        self.ok = None if payload is None else Sample(key, payload)
        self.err = None if err is None else type("E", (), {"payload": Sample(key, err).payload})()


class Session:
    """Answers every get with the given replies, after ``delay`` s."""

    def __init__(self, replies: list[Reply], delay: float = 0.0):
        self.replies, self.delay, self.asked = replies, delay, []

    def get(self, key, payload=None, timeout=None, consolidation=None):
        self.asked.append((key, payload))
        self.consolidation = consolidation
        time.sleep(self.delay)
        return iter(self.replies)


def station(replies, delay: float = 0.0, world_up: bool = True, config_file: str | None = None) -> GroundStation:
    from cdus.wire.transport import Transport
    gs = GroundStation("f", Transport(config_file=config_file), name="alice")
    gs.session = Session(replies, delay)
    if world_up:
        gs.view.alive.add("world")
    return gs


KEY = "cdus/f/world/cmd/gs"


def test_each_answer_is_one_outcome_and_exit_code():
    applied = CommandReply("applied", "pause", "", 12, 0.24, "gs:alice")
    gs = station([Reply(KEY, encode_reply(applied))])
    a = gs.command("pause")
    assert (a.outcome, a.code, a.reply) == ("applied", 0, applied)
    assert msgpack.unpackb(gs.session.asked[0][1])["name"] == "alice"  # the event log will name it
    a = station([Reply(KEY, encode_reply(CommandReply("rejected", "pause", "the fleet is already paused")))]).command(
        "pause")
    assert (a.outcome, a.code, a.reply.reason) == ("rejected", 1, "the fleet is already paused")


def test_an_answer_that_does_not_read_is_no_answer_and_is_counted():
    gs = station([Reply(KEY, b"\xc1"), Reply(KEY, None, err=b"boom")])
    a = gs.command("stop")
    assert (a.outcome, a.code) == ("no_answer", 3) and "could not be read (malformed)" in a.detail
    assert "an error reply: boom" in a.detail
    assert gs.view.rejected_by_reason == {"reply_malformed": 1}


def test_nothing_back_at_once_from_a_fleet_whose_world_is_up_is_a_denial(tmp_path):
    cfg = tmp_path / "v.json5"
    cfg.write_text(json.dumps({"transport": {"auth": {"usrpwd": {"user": "vehicle-usv1", "password": "pw"}}}}))
    a = station([], config_file=str(cfg)).command("stop", timeout=5.0)
    assert (a.outcome, a.code) == ("denied", 4)
    assert "(these are the credentials of 'vehicle-usv1')" in a.detail  # was "are 'vehicle-usv1''s"
    assert "RUN/secure/ground.json5" in a.detail and "pw" not in a.detail
    a = station([], world_up=False).command("stop", timeout=5.0)  # nobody there: not a denial
    assert (a.outcome, a.code) == ("no_answer", 3) and "no world took the command" in a.detail, a
    a = station([], delay=0.2).command("stop", timeout=0.2)  # the whole timeout: silence
    assert (a.outcome, a.code) == ("no_answer", 3) and "within 0.2 s" in a.detail
    # Zenoh ends a query whose time ran out with an error reply "Timeout": that is the same silence
    # (it was shown as "an error reply: Timeout", with no word of the time given or how to give more)
    a = station([Reply(KEY, None, err=b"Timeout")], delay=0.2).command("kill", timeout=0.2, vehicle="usv2")
    assert (a.outcome, a.code) == ("no_answer", 3) and "no answer from the world within 0.2 s" in a.detail, a
    assert "--timeout" in a.detail and "error reply" not in a.detail


def row(j: int, n: int, q=(1.0, 2.0)) -> bytes:
    return encode_states([StateMsg(j, n, n * 0.02, q, 0.0, 1.0, -0.5, -1.0, 0.25)])


def test_a_paused_fleets_vehicles_come_from_the_worlds_last_telemetry_and_say_why():
    gs = station([Reply("cdus/f/world/last/usv1", row(0, 40)), Reply("cdus/f/world/last/usv2", row(1, 40)),
                  Reply("cdus/f/world/last/bad\x1bid", row(1, 40))])
    gs._on_status(Sample("cdus/f/world/status", encode_status(0.8, 10.0, "lockstep", ["usv1", "usv2"],
                                                              ["usv1", "usv2", "uav1"], 0.1, 0.01, [], True,
                                                              {"usv1": "live", "usv2": "live", "uav1": "gone"})))
    gs.view.alive |= {"usv1", "usv2"}
    assert gs.fetch_last() == 2 and gs.view.rejected == 1
    snap = gs.snapshot()
    json.dumps(snap, allow_nan=False)
    assert snap["v"] == 1 and snap["run"] == "paused" and snap["t"] == 0.8
    by = {v["id"]: v for v in snap["vehicles"]}
    assert by["usv1"]["reason"] == "paused (fleet)" and by["usv1"]["telemetry"]["q"] == [1.0, 2.0]
    assert by["uav1"]["telemetry"] is None and by["uav1"]["reason"] == "no data yet" and by["uav1"]["state"] == "gone"
    table = status_table(gs.view)
    assert table.count("[paused (fleet)]") == 2 and "(gone)" in table
    gs.view.world = dataclasses.replace(gs.view.world, paused=False)
    assert _not_live(gs.view, "usv1") is None and _not_live(gs.view, "uav1") == "gone"


def test_events_since_hands_each_event_once():
    gs = station([])
    for i in range(3):
        gs._on_event(Sample("cdus/f/world/events", encode_event(FleetEvent.of(float(i), "fleet", f"e{i}"))))
    new, seen = gs.events_since(0)
    assert [e.text for e in new] == ["e0", "e1", "e2"] and seen == 3
    gs._on_event(Sample("cdus/f/world/events", encode_event(FleetEvent.of(3.0, "fleet", "e3"))))
    new, seen = gs.events_since(seen)
    assert [e.text for e in new] == ["e3"] and gs.events_since(seen)[0] == []


@settings(max_examples=150, deadline=None)
@given(payloads=hs.lists(hs.binary(max_size=120), max_size=4), text=hs.text(max_size=12),
       t=hs.floats(allow_nan=True, allow_infinity=True))
def test_no_status_or_reply_breaks_the_snapshot_or_the_command(payloads, text, t):
    gs = station([Reply(KEY, p) for p in payloads])
    for p in payloads:
        gs._on_status(Sample("cdus/f/world/status", p))
    gs._on_status(Sample("cdus/f/world/status", encode_status(0.0, 1.0, "lockstep", [], [], None, None, [], False,
                                                              {text: "live"})))
    gs._on_state(Sample("cdus/f/to/+world+/state/usv1", encode_states(
        [StateMsg(0, 1, 0.0, (t, 0.0), t, 0.0, 0.0, 0.0, 0.0)])))
    json.dumps(gs.snapshot(), allow_nan=False)
    a = gs.command("pause", timeout=5.0)
    assert a.outcome in ("applied", "rejected", "no_answer", "denied") and a.code in (0, 1, 3, 4)


class Alive(Sample):
    """A liveliness token that comes."""
    kind = "SampleKind.PUT"


class Gone(Sample):
    """A liveliness token that goes."""
    kind = "SampleKind.DELETE"


def test_watch_writes_versioned_json_lines_and_ends_when_the_world_leaves(capsys):
    from ground_station.__main__ import _watch

    gs = station([], world_up=False)
    gs._on_alive(Alive("cdus/f/alive/world/e1", b""))
    gs._on_status(Sample("cdus/f/world/status", encode_status(1.0, 10.0, "realtime", [], ["usv1"], None, None, [],
                                                              False)))
    gs._on_event(Sample("cdus/f/world/events", encode_event(FleetEvent.of(1.0, "fleet", "fleet paused by gs:x"))))
    gs._on_alive(Gone("cdus/f/alive/world/e1", b""))  # the run is over
    assert _watch(gs, 0.1) == 0
    lines = [json.loads(ln) for ln in capsys.readouterr().out.splitlines()]
    assert [ln["kind"] for ln in lines] == ["event", "status", "end"] and all(ln["v"] == 1 for ln in lines)
    assert lines[0]["event"]["text"] == "fleet paused by gs:x" and lines[1]["run"] == "ended"
    assert lines[1]["completion"] is None and lines[2]["completion"] is None  # no last status heard


def test_watch_says_how_the_run_ended_from_the_worlds_last_status(capsys):
    from ground_station.__main__ import _watch

    gs = station([], world_up=False)
    gs._on_alive(Alive("cdus/f/alive/world/e1", b""))
    gs._on_alive(Alive("cdus/f/alive/usv1/a1", b""))
    gs._on_status(Sample("cdus/f/world/status", encode_status(10.0, 10.0, "lockstep", ["usv1"], ["usv1"], None, None,
                                                              [], False, extra=StatusExtra(completion="completed"))))
    gs._on_state(Sample("cdus/f/to/+world+/state/usv1", encode_states([StateMsg(0, 500, 10.0, (1.0, 2.0), 0.3, 10.0, -9.9,
                                                                      -1.0, 0.06)])))
    gs._on_alive(Gone("cdus/f/alive/usv1/a1", b""))  # it leaves with the run's end
    snap = gs.snapshot()
    assert (snap["run"], snap["completion"]) == ("finishing", "completed")
    assert snap["vehicles"][0]["reason"] == "the run ended"
    gs._on_alive(Gone("cdus/f/alive/world/e1", b""))
    assert _watch(gs, 0.1) == 0
    lines = [json.loads(ln) for ln in capsys.readouterr().out.splitlines()]
    assert lines[-1] == {"v": 1, "kind": "end", "fleet": "f", "reason": "the world left: the run is over",
                         "completion": "completed"}


def test_a_snapshot_to_a_path_it_cannot_write_is_a_clear_error_not_a_traceback(tmp_path, monkeypatch, capsys):
    """`gs snapshot DIR` raised IsADirectoryError, `gs snapshot /proc/version` FileNotFoundError
    (its temp file), both as tracebacks after connecting. Now: exit 2 and what is wrong; a
    directory is refused before connecting."""
    from ground_station import __main__ as cli

    opened = []
    monkeypatch.setattr(cli.GroundStation, "open", lambda self, watch=True: opened.append(1))
    monkeypatch.setattr(cli.GroundStation, "wait_for_status", lambda self, timeout: True)
    monkeypatch.setattr(cli.GroundStation, "fetch_last", lambda self, timeout=2.0: 0)
    monkeypatch.setattr(cli.GroundStation, "fetch_settings", lambda self, timeout=2.0: None)
    monkeypatch.setattr(cli.GroundStation, "close", lambda self: None)
    base = ["--fleet", "f", "-e", "tcp/127.0.0.1:1", "snapshot"]
    assert cli.main([*base, str(tmp_path)]) == cli.EXIT_USAGE and not opened
    assert f"{tmp_path} is a directory" in capsys.readouterr().err
    blocker = tmp_path / "a-file"
    blocker.write_text("x")
    assert cli.main([*base, str(blocker / "state.json")]) == cli.EXIT_USAGE and opened
    err = capsys.readouterr().err
    assert f"could not write the snapshot to {blocker / 'state.json'}" in err and "Traceback" not in err
    assert blocker.read_text() == "x"
    assert cli.main([*base, str(tmp_path / "ok.json")]) == 0
    assert json.loads((tmp_path / "ok.json").read_text())["v"] == 1


def test_a_world_that_dies_holding_the_query_is_no_answer_not_a_denial(tmp_path):
    """The world SIGKILLed while it held a ground station's vehicle fault (a restart under way):
    the query ended at once with no reply while the world's status was a second old, and the
    ground station said "denied: ... use --zenoh-config RUN/secure/ground.json5" (exit 4) to an
    operator holding ground.json5 (seen on a live lockstep fleet). The ground role may always
    ask: no reply to it is silence, and a world whose token goes away left before answering."""
    ground = tmp_path / "ground.json5"
    ground.write_text(json.dumps({"transport": {"auth": {"usrpwd": {"user": "ground", "password": "pw"}}}}))
    gs = station([], config_file=str(ground))
    gs.view.world_seen = True

    class Leaving(Session):  # the world's token goes as its session closes, a moment after the query ended
        def get(self, key, payload=None, timeout=None, consolidation=None):
            threading.Timer(0.1, lambda: gs.view.alive.discard("world")).start()
            return iter([])

    gs.session = Leaving([])
    a = gs.command("pause_vehicle", vehicle="usv1", timeout=5.0)
    assert (a.outcome, a.code) == ("no_answer", 3) and "the world left before answering" in a.detail, a
    a = station([], config_file=str(ground)).command("stop", timeout=5.0)  # up, no reply, ground: not denied
    assert (a.outcome, a.code) == ("no_answer", 3) and "denied" not in a.detail, a
    a = station([]).command("stop", timeout=5.0)  # no credentials: a fleet with no access control
    assert (a.outcome, a.code) == ("no_answer", 3), a


def test_a_second_different_answer_on_the_command_key_is_not_taken_for_the_worlds():
    """On a fleet run with --insecure anyone may answer on world/cmd/gs: a forger's "applied"
    came first and `cdus gs resume` printed "applied ... by gs:forger" and exited 0 while the
    world had rejected it (seen live). Every reply is read now: one answer (or the same one
    twice) is taken; different ones are no answer, with what each said."""
    world = CommandReply("rejected", "resume", "the fleet is not paused", None, None, "gs:alice")
    forged = CommandReply("applied", "resume", "FORGED", 1, 0.02, "gs:forger")
    import zenoh

    gs = station([Reply(KEY, encode_reply(forged)), Reply(KEY, encode_reply(world))])
    a = gs.command("resume")
    # Zenoh's default consolidation keeps one reply per key: the forger's could hide the world's
    assert gs.session.consolidation == zenoh.ConsolidationMode.NONE
    assert (a.outcome, a.code) == ("no_answer", 3) and "2 different answers" in a.detail
    assert "FORGED" in a.detail and "the fleet is not paused" in a.detail and "--insecure" in a.detail
    a = station([Reply(KEY, encode_reply(world)), Reply(KEY, encode_reply(world))]).command("resume")
    assert (a.outcome, a.code, a.reply) == ("rejected", 1, world)
    a = station([Reply(KEY, encode_reply(world)), Reply(KEY, b"\xc1")]).command("resume")  # junk beside it: counted
    assert (a.outcome, a.reply) == ("rejected", world)


def test_the_live_table_ends_when_the_world_leaves_or_goes_silent():
    """`gs status` kept redrawing a stopped fleet forever ("6/6 vehicles alive", every row "NO")."""
    import time as _time

    from ground_station.__main__ import STATUS_LOST_S, _run_ended
    from ground_station.console import GroundStation
    from cdus.wire.transport import Transport

    gs = GroundStation("f", Transport())
    assert _run_ended(gs) is None  # nothing heard yet: not ended
    with gs.view.lock:
        gs.view.world_seen, gs.view.alive = True, {"world"}
        gs.view.status_at = _time.monotonic()
    assert _run_ended(gs) is None
    with gs.view.lock:
        gs.view.status_at = _time.monotonic() - STATUS_LOST_S - 1
    assert "no status from the fleet" in _run_ended(gs)
    with gs.view.lock:
        gs.view.alive = set()
    assert "world has left" in _run_ended(gs)


def test_fleets_here_names_each_fleet_whose_world_is_up_and_nothing_forged():
    gs = station([])
    replies = [Reply("cdus/lake_demo/alive/world/e1", b""), Reply("cdus/other/alive/world/e2", b""),
               Reply("cdus/lake_demo/alive/world/e1", b""), Reply("cdus/third/alive/usv1/e3", b""),
               Reply("cdus/bad name/alive/world/e4", b""), Reply("elsewhere/x/alive/world/e5", b""),
               Reply("k", None, b"e")]
    gs.session.liveliness = lambda: type("L", (), {"get": lambda self, key, timeout=None: iter(replies)})()
    assert gs.fleets_here() == ["lake_demo", "other"]

    def refused(key, timeout=None):
        raise zenoh.ZError("denied")
    gs.session.liveliness = lambda: type("L", (), {"get": lambda self, key, timeout=None: refused(key)})()
    assert gs.fleets_here() == []


def test_a_one_shot_snapshot_carries_the_worlds_recent_events_as_the_text_status_does():
    """`cdus gs status --json` and `snapshot FILE` on a fleet that had been paused, re-gained
    and re-formed gave "events": [] (a one-shot ground station hears no event live) while
    `cdus gs status` listed them from the world's status. Now the same events in both."""
    gs = station([], world_up=True)
    recent = [FleetEvent.of(3.0, "fleet", "fleet paused by gs:x"), FleetEvent.of(5.0, "fleet", "fleet resumed by gs:x")]
    gs._on_status(Sample("cdus/f/world/status", encode_status(6.0, 10.0, "realtime", [], ["usv1"], None, None, recent,
                                                              False)))
    snap = gs.snapshot()
    assert [e["text"] for e in snap["events"]] == ["fleet paused by gs:x", "fleet resumed by gs:x"]
    assert "fleet resumed by gs:x" in status_table(gs.view)
    gs._on_event(Sample("cdus/f/world/events", encode_event(FleetEvent.of(7.0, "fleet", "fleet stopped by gs:y"))))
    assert [e["text"] for e in gs.snapshot()["events"]] == ["fleet stopped by gs:y"]  # heard live: those, as the table


def test_the_snapshot_saves_the_settings_the_world_says_and_counts_a_reply_it_cannot_read():
    from cdus.wire.messages import encode_control
    from cdus.wire.schemas import encode_settings

    good = encode_settings([(None, encode_control("link", link={"loss": 0.1}, at=4.0, seq=0))], [("usv1", 1.0)],
                           {"loss": 0.1})
    gs = station([Reply("cdus/f/world/settings", b"\xc1"), Reply("cdus/f/world/settings", good)])
    got = gs.fetch_settings()
    assert got["link"] == {"loss": 0.1} and got["changes"][0]["op"] == "link" and got["phases"] == {"usv1": 1.0}
    assert gs.view.rejected == 1 and gs.view.rejected_by_reason["malformed"] == 1
    snap = gs.snapshot(settings=True)
    assert snap["settings"] == got and "settings" not in gs.snapshot()  # only when asked (watch lines do not)
    json.dumps(snap, allow_nan=False)
    assert station([]).snapshot(settings=True)["settings"] is None  # an older world: said as null


def test_wait_for_status_asks_the_world_at_once_and_checks_the_answer():
    ok = encode_status(3.0, 10.0, "lockstep", ["usv1"], ["usv1"], None, None, [], False)
    gs = station([Reply("cdus/f/world/status", b"\xc1"), Reply("cdus/f/world/status", ok)])
    assert gs.wait_for_status(0.2) and gs.view.world.t == 3.0
    assert gs.session.asked[-1][0] == "cdus/f/world/status"
    assert gs.view.rejected_by_reason["status_malformed"] == 1  # a reply is checked as a published status is
    assert not station([]).wait_for_status(0.2)  # no answer, nothing published: still waits, then says no
