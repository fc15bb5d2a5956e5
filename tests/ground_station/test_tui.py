"""The live console's screen and keys (ground_station.tui), against a fake ground station,
with Textual's own pilot (App.run_test): no fleet, no terminal."""

from __future__ import annotations

import asyncio
import dataclasses

from textual.widgets import DataTable, RichLog

from cdus.wire.messages import StateMsg
from cdus.wire.schemas import CommandReply, FleetEvent, StatusExtra, WorldStatus, decode_status, encode_status
from ground_station.console import Answer
from ground_station.console import FleetView
from ground_station.tui import ConfirmKill, ConsoleApp, before_line, send_command, snapshot, vehicle_state

IDS = ["usv1", "usv2", "uav1"]


def world(t: float, states=("live", "live", "live"), paused=False, **over) -> WorldStatus:
    """A status as the console gets it: encoded by the world's encoder, decoded by decode_status."""
    extra = {"kinds": ["usv", "usv", "uav"], "states": list(states),
             "edges": [("usv1", "usv2", 0.3), ("usv2", "uav1", None if "gone" in states else 0.1),
                       ("usv1", "uav1", 0.05)],
             "links": [("usv1", "usv2", 120, 9, "lossy")], "rx": [(100, 1), (90, 2), None], "safety_radius": 2.0,
             "closest": ("usv1", "usv2", 7.5), "path_errors": [0.2, 0.1, 0.05], "directed": False}
    extra.update({k: v for k, v in over.items() if k in extra or k == "completion"})
    st = decode_status(encode_status(t, over.get("duration", 100.0), "lockstep", [v for v, s in zip(IDS, states)
                                                                                    if s != "gone"], IDS, 0.2, 0.3,
                                     over.get("events", [FleetEvent.of(0.5, "fleet", "an event from before")]), paused,
                                     extra=StatusExtra(**extra)))
    assert isinstance(st, WorldStatus), st
    return st


class FakeGS:
    """What the console uses of a GroundStation: its fleet, its view, and the two senders."""

    def __init__(self):
        self.fleet = "f"
        self.view = FleetView()
        self.view.world = world(3.0)
        self.view.alive = {"usv1", "usv2", "uav1", "world"}
        for j, vid in enumerate(IDS):
            self.view.states[vid] = StateMsg(j, 150, 3.0, (1.0 + j, 2.0, 20.0) if vid == "uav1" else (1.0 + j, 2.0),
                                             0.0, 1.0, -3.0 - j, -1.0, 0.1 * (j + 1))
        self.sent: list[tuple] = []

    def command(self, op: str, **fields):
        """The acknowledged call (GroundStation.command): recorded as (fleet, op) or (action,
        vehicle), answered applied from tick 150, or rejected for a vehicle named "nobody"."""
        vehicle = fields.get("vehicle")
        action = {"pause_vehicle": "pause", "resume_vehicle": "resume"}.get(op, op)
        self.sent.append(("fleet", op) if vehicle is None else (action, vehicle))
        if vehicle == "nobody":
            return Answer("rejected", CommandReply("rejected", op, "no vehicle 'nobody' in this fleet"))
        return Answer("applied", CommandReply("applied", op, "", 150, 3.0))


def text_of(app, selector: str) -> str:
    w = app.query_one(selector)
    if isinstance(w, RichLog):
        return "\n".join("".join(seg.text for seg in line) for line in w.lines)
    if isinstance(w, DataTable):
        return "\n".join(" ".join(str(c) for c in w.get_row_at(i)) for i in range(w.row_count))
    return str(w.render())


async def settle(pilot, until, what: str, tries: int = 400) -> None:
    """Pause until ``until()`` holds (commands go through a worker thread), at least 20 s on a busy machine."""
    for _ in range(tries):
        await pilot.pause(0.05)
        if until():
            return
    raise AssertionError(f"not reached: {what}")


def test_snapshot_shows_every_vehicle_with_its_state_kind_and_values():
    gs = FakeGS()
    snap = snapshot(gs.view)
    rows = {r[0]: r for r in snap["rows"]}
    assert list(rows) == IDS
    assert rows["usv1"][1:4] == ("usv", "live", "3.00") and rows["usv1"][7] == "-3.000"
    assert rows["uav1"][6] == "20.0" and rows["usv1"][6] == ""  # z only for a drone
    assert rows["usv2"][10] == "0.3000" and rows["usv2"][11:] == ("90", "2") and rows["uav1"][11:] == ("-", "-")
    assert "3/3 vehicles alive" in snap["header"] and "closest usv1 - usv2 7.50 m" in snap["header"]
    gs.view.world = world(4.0, states=("live", "gone", "live"), paused=True)
    snap = snapshot(gs.view)
    assert [r[2] for r in snap["rows"]] == ["paused", "lost", "paused"] and "FLEET PAUSED" in snap["header"]


def test_names_that_are_not_the_worlds_vehicles_are_not_rows():
    gs = FakeGS()
    gs.view.alive |= {"gs-operator2", "launcher", "ros2"}  # ros2: the ROS 2 bridge (docs/ros2.md)
    gs.view.states["forged"] = gs.view.states["usv1"]
    assert [r[0] for r in snapshot(gs.view)["rows"]] == IDS
    gs.view.world = None  # before the world's first status: whoever is heard
    assert [r[0] for r in snapshot(gs.view)["rows"]] == sorted({*IDS, "forged", "gs-operator2"})


def test_a_vehicle_without_a_liveliness_token_is_lost_whatever_the_roster_says():
    w = world(1.0)
    assert vehicle_state("usv2", w, {"usv1", "uav1"}) == "lost"
    assert vehicle_state("usv2", w, {"usv1", "usv2", "uav1"}) == "live"
    assert vehicle_state("usv2", None, {"usv2"}) == "live" and vehicle_state("usv2", None, set()) == "lost"
    old = dataclasses.replace(world(1.0), states=None)  # a world without roster states
    assert vehicle_state("usv2", old, set()) == "live"  # before our tokens come in: the world's alive
    assert vehicle_state("usv2", dataclasses.replace(old, alive=["usv1"]), set()) == "lost"
    assert vehicle_state("usv2", world(1.0, states=("live", "paused", "live")), {"usv2"}) == "paused"
    # once our tokens are in, none left means every vehicle left (the end of a run), not "use the world's"
    assert vehicle_state("usv2", old, set(), tokens_in=True) == "lost"
    assert vehicle_state("usv2", world(1.0), set(), tokens_in=True) == "lost"
    assert vehicle_state("usv2", world(1.0, states=("live", "paused", "live")), set(), tokens_in=True) == "paused"


def test_vehicles_leaving_with_the_runs_end_are_ended_and_raise_no_alarm():
    from ground_station.alarms import Alarms
    from ground_station.tui import alarm_status

    gs = FakeGS()
    gs.view.world_seen = True
    gs.view.world = world(100.0, states=("live", "gone", "live"), completion="completed")
    gs.view.alive = {"world", "usv1"}
    snap = snapshot(gs.view)
    assert [r[2] for r in snap["rows"]] == ["live", "lost", "ended"]
    assert "1/3 vehicles alive" in snap["header"] and "RUN OVER: completed" in snap["header"]
    st = alarm_status(gs.view.world, snap["alive"], tokens_in=True)
    assert st.states == ["live", "gone", "live"]
    raised = [ch.alarm.subject for ch in Alarms().update(st) if ch.raised and ch.alarm.kind == "vehicle_lost"]
    assert raised == ["usv2"]  # the one gone before the end, not uav1 that left with it


def test_the_console_says_lost_when_every_vehicle_has_left():
    gs = FakeGS()
    gs.view.world_seen = True
    gs.view.alive = {"world"}
    snap = snapshot(gs.view)
    assert [r[2] for r in snap["rows"]] == ["lost"] * 3 and "0/3 vehicles alive" in snap["header"]


def test_send_command_says_what_became_of_it():
    gs = FakeGS()
    applied = "applied from tick 150 (t = 3.00 s)"
    assert send_command(gs, "pause") == (True, f"pause fleet: {applied}") and gs.sent == [("fleet", "pause")]
    assert send_command(gs, "kill", "usv2") == (True, f"kill usv2: {applied}") and gs.sent[-1] == ("kill", "usv2")
    ok, line = send_command(gs, "kill", "nobody")
    assert not ok and line == "kill nobody: REJECTED, no vehicle 'nobody' in this fleet"

    class Silent(FakeGS):
        def command(self, op, **fields):
            return Answer("no_answer", None, "no answer within 10 s")

    assert send_command(Silent(), "pause") == (False, "pause fleet: NO ANSWER, no answer within 10 s")

    class Broken(FakeGS):
        def command(self, op, **fields):
            raise ValueError("no session\x1b[31m")

    ok, line = send_command(Broken(), "restart", "usv1")
    assert not ok and line.startswith("restart usv1: FAILED") and "\x1b" not in line


def run(coro):
    return asyncio.run(coro)


def test_keys_pause_resume_restart_the_selected_vehicle_and_the_fleet():
    async def go():
        gs = FakeGS()
        app = ConsoleApp(gs, refresh_s=0.05)
        async with app.run_test(size=(160, 50)) as pilot:
            await pilot.pause(0.1)
            assert "usv1 usv live" in text_of(app, "#vehicles")
            assert "event (before this console) t = 0.50 s: an event from before" in text_of(app, "#log")
            await pilot.press("down", "p")
            await settle(pilot, lambda: ("pause", "usv2") in gs.sent, "pause usv2")
            await pilot.press("r")
            await settle(pilot, lambda: ("resume", "usv2") in gs.sent, "resume usv2")
            await pilot.press("down", "t")
            await settle(pilot, lambda: ("restart", "uav1") in gs.sent, "restart uav1")
            await pilot.press("P")
            await settle(pilot, lambda: ("fleet", "pause") in gs.sent, "pause fleet")
            await pilot.press("R")
            await settle(pilot, lambda: ("fleet", "resume") in gs.sent, "resume fleet")
            await settle(pilot, lambda: "resume fleet: applied" in text_of(app, "#log"), "the outcome in the log")
            log = text_of(app, "#log")
            for line in ("> pause usv2", "pause usv2: applied", "resume usv2: applied", "restart uav1: applied",
                         "pause fleet: applied"):
                assert line in log
            assert not any(op == "kill" for op, _ in gs.sent)
    run(go())


def test_kill_asks_first_and_a_lost_vehicle_raises_its_alarm():
    async def go():
        gs = FakeGS()
        app = ConsoleApp(gs, refresh_s=0.05)
        async with app.run_test(size=(160, 50)) as pilot:
            await pilot.pause(0.1)
            await pilot.press("down", "k")
            await settle(pilot, lambda: isinstance(app.screen, ConfirmKill), "the confirmation")
            await pilot.press("n")
            await settle(pilot, lambda: "kill usv2: cancelled" in text_of(app, "#log"), "cancelled")
            assert gs.sent == []
            await pilot.press("k")
            await settle(pilot, lambda: isinstance(app.screen, ConfirmKill), "the confirmation")
            await pilot.press("escape")
            await settle(pilot, lambda: not isinstance(app.screen, ConfirmKill), "dismissed")
            assert gs.sent == []
            await pilot.press("k", "y")
            await settle(pilot, lambda: gs.sent == [("kill", "usv2")], "kill usv2")
            assert "alarms: none" in text_of(app, "#alarms")
            # the world says it is gone: the alarm, with a simulated time
            with gs.view.lock:
                gs.view.world = world(4.25, states=("live", "gone", "live"))
                gs.view.alive.discard("usv2")
            # stamped with when it was last heard of: its newest telemetry (3 s), before this status (4.25 s)
            await settle(pilot, lambda: "ALARM t = 3.00 s: vehicle usv2 lost" in text_of(app, "#alarms"), "alarm")
            assert "usv2 usv lost" in text_of(app, "#vehicles")
            assert "end down" in text_of(app, "#edges")
            assert "t = 3.00 s ALARM: vehicle usv2 lost" in text_of(app, "#log")
            with gs.view.lock:
                gs.view.world = world(9.0)
                gs.view.alive.add("usv2")
            await settle(pilot, lambda: "alarms: none" in text_of(app, "#alarms"), "cleared")
            assert "t = 9.00 s cleared: vehicle usv2 lost" in text_of(app, "#log")
    run(go())


def test_wire_strings_cannot_reach_the_terminal_as_markup():
    async def go():
        gs = FakeGS()
        with gs.view.lock:
            gs.view.events.append(FleetEvent.of(1.0, "fleet", "[bold red]not markup[/]"))
        app = ConsoleApp(gs, refresh_s=0.05)
        async with app.run_test(size=(160, 50)) as pilot:
            # logged after the console's hold (EventHold.HOLD_S); as markup it would never show as written
            await settle(pilot, lambda: "[bold red]not markup[/]" in text_of(app, "#log"), "the event as written")
    run(go())


def test_links_fall_back_to_what_each_vehicle_received():
    async def go():
        gs = FakeGS()
        gs.view.world = world(3.0, links=[])
        app = ConsoleApp(gs, refresh_s=0.05)
        async with app.run_test(size=(160, 50)) as pilot:
            await pilot.pause(0.2)
            links = text_of(app, "#links")
            assert "-> usv1 100 1" in links and "-> usv2 90 2" in links
    run(go())


def test_a_world_that_falls_silent_is_said_so(monkeypatch):
    import ground_station.tui as tui

    monkeypatch.setattr(tui, "STALE_S", 0.3)

    async def go():
        gs = FakeGS()
        app = ConsoleApp(gs, refresh_s=0.05)
        t = [3.0]

        def talking() -> bool:
            """A new status each time it is asked; True once the header shows no silence."""
            if not app.query("#header"):  # not mounted yet
                return False
            t[0] += 0.1
            with gs.view.lock:
                gs.view.world = world(t[0])
            return "NO STATUS" not in text_of(app, "#header") and f"t = {t[0] - 0.1:.1f}" in text_of(app, "#header")

        async with app.run_test(size=(160, 50)) as pilot:
            await settle(pilot, talking, "a world that talks")
            await settle(pilot, lambda: "NO STATUS for" in text_of(app, "#header"), "the silence")
            await settle(pilot, talking, "a status again")
    run(go())


def test_events_keep_coming_into_the_log_once_the_view_holds_hundreds():
    async def go():
        gs = FakeGS()
        with gs.view.lock:
            gs.view.events += [FleetEvent.of(0.1 * j, "fleet", f"old {j}") for j in range(300)]
        app = ConsoleApp(gs, refresh_s=0.05)
        async with app.run_test(size=(160, 50)) as pilot:
            await settle(pilot, lambda: "old 299" in text_of(app, "#log"), "the events heard before")
            for j in range(3):
                with gs.view.lock:
                    gs.view.events.append(FleetEvent.of(40.0 + j, "fleet", f"new {j}"))
                    del gs.view.events[:-1000]
                await settle(pilot, lambda: f"new {j}" in text_of(app, "#log"), f"new event {j}")
            assert text_of(app, "#log").count("new 0") == 1  # each once
    run(go())


def test_a_vehicle_whose_token_goes_is_lost_before_the_next_status():
    async def go():
        gs = FakeGS()
        gs.view.world = world(2.5)  # the world's status lags its vehicles' telemetry (t = 3 s)
        app = ConsoleApp(gs, refresh_s=0.05)
        async with app.run_test(size=(160, 50)) as pilot:
            await settle(pilot, lambda: "usv2 usv live" in text_of(app, "#vehicles"), "usv2 live")
            with gs.view.lock:
                gs.view.alive.discard("usv2")  # killed: the world's status does not know yet
            with gs.view.lock:  # the others carry on
                for vid in ("usv1", "uav1"):
                    gs.view.states[vid] = dataclasses.replace(gs.view.states[vid], t=4.0)
            # stamped with when it was last heard of (its telemetry, 3 s), not the older status's 2.5 s
            await settle(pilot, lambda: "ALARM t = 3.00 s: vehicle usv2 lost" in text_of(app, "#alarms"), "alarm")
            assert "usv2 usv lost" in text_of(app, "#vehicles")
            with gs.view.lock:
                gs.view.world = world(5.0, states=("live", "gone", "live"))
            await pilot.pause(0.3)
            assert text_of(app, "#log").count("vehicle usv2 lost") == 1  # the status saying so raises nothing again
    run(go())


def test_when_every_token_is_gone_the_vehicles_are_lost_not_the_worlds_last_alive():
    """rev-gs, seen in tmux on a realtime fleet that ended (and one whose world was SIGKILLed):
    with every liveliness token gone, the console fell back to the world's last status (meant for
    before this ground station's tokens come in) and showed '4/4 vehicles alive', each 'live',
    for as long as it stayed open; with the world's token gone too it said only 'NO STATUS'."""
    gs = FakeGS()
    gs.view.world_seen = True  # this ground station's liveliness subscription has spoken
    gs.view.alive = {"world"}  # every vehicle's token gone, the world's still there (its status lags)
    snap = snapshot(gs.view)
    assert [r[2] for r in snap["rows"]] == ["lost", "lost", "lost"] and "0/3 vehicles alive" in snap["header"]
    gs.view.alive = set()  # the world's too: the run is over
    snap = snapshot(gs.view)
    assert "0/3 vehicles alive" in snap["header"] and "RUN OVER" in snap["header"]
    gs.view.world_seen = False  # before any token is heard: the world's status says who is alive
    assert [r[2] for r in snapshot(gs.view)["rows"]] == ["live", "live", "live"]

    async def go():
        gs2 = FakeGS()
        gs2.view.world_seen = True
        app = ConsoleApp(gs2, refresh_s=0.05)
        async with app.run_test(size=(160, 50)) as pilot:
            await settle(pilot, lambda: "usv2 usv live" in text_of(app, "#vehicles"), "usv2 live")
            with gs2.view.lock:
                gs2.view.alive = {"world"}
            await settle(pilot, lambda: all(f"{v} lost" in text_of(app, "#alarms") for v in IDS), "every alarm")
    run(go())


def test_the_events_from_before_the_console_are_one_line_of_its_log():
    """Issue 27: the log started with a line per event of the world's recent ones ("event
    (before)" ten times, a link change a line per link). Now one line: how many of each kind, a
    link change counted once, the newest in full."""
    from cdus.sim.reports import link_state_event
    links = ["usv1->usv2", "usv2->usv1", "usv2->uav1", "uav1->usv2", "usv1->uav1", "uav1->usv1"]
    events = [FleetEvent.of(10.0, "link_changed", "link loss=0.1 by gs:alice"),
              *(link_state_event(10.02, ln, "lossy") for ln in links),
              FleetEvent.of(12.0, "fault", "kill of usv2 by gs:alice (t = 12 s)", vehicle="usv2")]
    assert before_line(events) == ("before this console: 3 events from t = 10.00 to 12.00 s (1 link_changed, "
                                   "1 link_state, 1 fault); the newest: t = 12.00 s: kill of usv2 by gs:alice "
                                   "(t = 12 s)")
    assert before_line([]) == ""

    async def go():
        gs = FakeGS()
        gs.view.world = world(3.0, events=events)
        app = ConsoleApp(gs, refresh_s=0.05)
        async with app.run_test(size=(160, 50)) as pilot:
            await settle(pilot, lambda: "before this console: 3 events" in text_of(app, "#log"), "the line")
            log = text_of(app, "#log")
            assert "lossy" not in log and log.count("before this console") == 1, log
    run(go())


def test_a_change_of_many_links_heard_over_a_second_is_one_log_line_in_time_order():
    """Seen in tmux on a realtime lake_circle (`cdus gs ... link loss=0`): the console logged
    twelve 'event t = 25.80 s: link X up' lines, as heard, while the launcher, `cdus sim` and
    `gs status` say such a change in one line. The console now holds each event a moment
    (cdus.sim.reports.EventHold, as the launcher) and logs them in time order, grouped."""
    from cdus.sim.reports import link_state_event

    async def go():
        gs = FakeGS()
        app = ConsoleApp(gs, refresh_s=0.05)
        links = [f"{a}->{b}" for a in ("usv1", "usv2", "uav1") for b in ("usv1", "usv2", "uav1", "uav2") if a != b][:8]
        async with app.run_test(size=(160, 50)) as pilot:
            await settle(pilot, lambda: "usv1" in text_of(app, "#vehicles"), "the table")
            with gs.view.lock:  # a kill stamped after the change, heard before the links' states
                gs.view.events.append(FleetEvent.of(26.0, "fault", "kill of usv2 by gs:x", severity="warn"))
                gs.view.events += [link_state_event(25.8, ln, "up") for ln in links[:5]]
            await pilot.pause(0.3)
            with gs.view.lock:
                gs.view.events += [link_state_event(25.8, ln, "up") for ln in links[5:]]
            await settle(pilot, lambda: "kill of usv2" in text_of(app, "#log"), "the kill")
            log = text_of(app, "#log")
            assert "8 links up (from t = 25.80 s)" in log, log
            assert not any(f"link {ln} up" in log for ln in links), log  # no line per link
            assert log.index("8 links up") < log.index("kill of usv2")  # in time order, not as heard
    run(go())
