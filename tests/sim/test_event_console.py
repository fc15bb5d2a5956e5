"""The console lines of a fleet's events, the launcher's and `cdus sim`'s alike
(cdus.sim.reports.ConsoleQuota.printed): links lossy by design are one line, not one per
link; the in-process fleet reports link changes as the world does."""

from __future__ import annotations

from cdus.scenario.config import load_scenario
from cdus.sim.fleet import InProcessFleet
from hypothesis import given, settings, strategies as st

from cdus.sim.reports import ConsoleQuota, design_lines, link_state_event, newest_events, scheduled_fault
from cdus.wire.schemas import FleetEvent

OVERRIDE = """
[[link.override]]
src = "*"
dst = "uav1"
loss = 0.2
delay = { base = 0.05, jitter = 0.01 }
"""


def test_uniform_faults_are_one_group_of_every_link():
    line, lossy = design_lines(load_scenario("configs/lake_circle.toml", {"link.loss": 0.1}))
    assert line == "link faults from t = 0: loss 0.1 on 12 links (all)"
    assert len(lossy) == 12 and set(lossy.values()) == {"loss 0.1"}
    assert design_lines(load_scenario("configs/lake_circle.toml")) == ("", {})  # ideal: nothing by design


def test_an_override_makes_a_group_of_its_own_with_its_links_named(tmp_path):
    cfg = tmp_path / "o.toml"
    cfg.write_text(open("configs/lake_circle.toml").read() + OVERRIDE)
    line, lossy = design_lines(load_scenario(cfg))
    assert line == ("link faults from t = 0: loss 0.2, delay 0.05 s (uniform jitter 0.01 s) on 2 of 12 links "
                    "(usv3->uav1, uav2->uav1)")
    assert set(lossy) == {"usv3->uav1", "uav2->uav1"}


def test_links_lossy_by_design_are_one_console_line_and_later_changes_each_their_own():
    sc = load_scenario("configs/lake_circle.toml", {"link.loss": 0.1})
    console = ConsoleQuota(scenario=sc)
    lossy = [link_state_event(0.0, f"{e.k}->{e.i}", "lossy") for e in sc.edges]
    assert len(lossy) == 12
    printed = [line for e in lossy for line in console.printed(e)]
    assert printed == ["  event: t = 0.00 s: link faults from t = 0: loss 0.1 on 12 links (all)"]
    later = [link_state_event(150.0, "usv1->usv2", "down"), link_state_event(160.0, "usv1->usv2", "lossy"),
             scheduled_fault(7500, 0.02, "kill", "usv2")]
    assert [line for e in later for line in console.printed(e)] == [
        "  event: t = 150.00 s: link usv1->usv2 down (from t = 150.00 s)",
        "  event: t = 160.00 s: link usv1->usv2 lossy (from t = 160.00 s)",
        "  event: t = 150.00 s: scheduled kill of usv2 (t = 150 s)"]
    # without the scenario (or for a link not lossy by design) each is its own line
    bare = ConsoleQuota()
    assert sum(len(bare.printed(e)) for e in lossy) == 12
    assert ConsoleQuota(scenario=load_scenario("configs/lake_circle.toml")).printed(lossy[0]) == [
        f"  event: t = 0.00 s: link {lossy[0].link} lossy (from t = 0.00 s)"]


def test_the_in_process_fleet_reports_link_changes_as_events_as_the_world_does():
    sc = load_scenario("configs/lake_circle.toml", {"link.loss": 0.1, "scenario.duration": 1.0})
    events = [FleetEvent(**e.to_dict()) for e in InProcessFleet(sc).run().metrics.events]
    states = [e for e in events if e.kind == "link_state"]
    assert len(states) == 12 and {e.t for e in states} == {0.0}
    assert states[0] == link_state_event(0.0, states[0].link, "lossy")


def test_the_opening_says_the_design_once_and_the_lossy_lines_then_add_nothing():
    """The launcher hears the t = 0 lossy states with the agents' stats, after a kill at 1 s
    had been printed: it says the design line at the start (ConsoleQuota.opening) instead."""
    sc = load_scenario("configs/lake_circle.toml", {"link.loss": 0.1})
    console = ConsoleQuota(scenario=sc)
    assert console.opening() == ["  event: t = 0.00 s: link faults from t = 0: loss 0.1 on 12 links (all)"]
    assert console.opening() == []
    lossy = [link_state_event(0.0, f"{e.k}->{e.i}", "lossy") for e in sc.edges]
    assert [line for e in lossy for line in console.printed(e)] == []
    assert ConsoleQuota(scenario=load_scenario("configs/lake_circle.toml")).opening() == []  # nothing lossy by design
    heard_first = ConsoleQuota(scenario=sc)  # a lossy state heard before the opening: said then, not again
    assert len(heard_first.printed(lossy[0])) == 1 and heard_first.opening() == []


@settings(max_examples=200, deadline=None)
@given(st.integers(2, 30), st.lists(st.floats(0.0, 20.0), max_size=30), st.integers(0, 9), st.booleans(),
       st.randoms())
def test_a_status_says_a_link_change_whole_wherever_its_events_fall(k, others, newer, late, rng):
    """newest_events: a change of k links is never shown in part, wherever its events fall among
    others heard; heard after them (the agents' counters come late) with up to 9 events after
    it, it is one event of k links among the newest 10 (a window of 10 raw events cut it to
    "6 links lossy ... and 2 more": issue 27)."""
    change = [link_state_event(10.0 + 0.01 * rng.randrange(50), f"v{j}->w{j}", "lossy") for j in range(k)]
    rng.shuffle(change)
    before = [FleetEvent.of(t, "fleet", f"other {i}") for i, t in enumerate(others)]
    if late:
        heard = before + change
    else:
        heard = before + change
        rng.shuffle(heard)
    after = [FleetEvent.of(30.0 + i, "fleet", f"after {i}") for i in range(newer)]
    shown = newest_events(heard + after)
    assert len(shown) == min(10, len(before) + 1 + newer) and [e.t for e in shown] == sorted(e.t for e in shown)
    assert shown[len(shown) - newer:] == after
    grouped = [e for e in shown if e.kind == "link_state"]
    assert all(e.text.startswith(f"{k} links lossy (from t = ") for e in grouped), grouped  # never a part
    if late and max(others, default=0.0) <= 10.0:
        assert len(grouped) == 1, shown


@settings(max_examples=200, deadline=None)
@given(st.lists(st.tuples(st.floats(0, 20), st.floats(0, 30)), max_size=40), st.lists(st.floats(0, 25), max_size=20))
def test_held_events_come_out_each_once_in_time_order_and_never_early(heard, polls):
    """EventHold (the launcher's and the console's): every event held comes out once; each batch
    is in time order; an event comes out before HOLD_S only with one stamped no earlier that did."""
    from cdus.sim.reports import EventHold

    hold, out = EventHold(), []
    events = sorted(((at, FleetEvent.of(t, "fleet", f"e{i}")) for i, (at, t) in enumerate(heard)), key=lambda x: x[0])
    when = {id(e): at for at, e in events}
    clock = sorted(set(polls) | {at for at, _ in events})
    for now in clock:
        for at, e in events:
            if at == now:
                hold.hold(e, now)
        batch = hold.due(now)
        assert [e.t for e in batch] == sorted(e.t for e in batch)
        if batch:
            upto = max(e.t for e in batch if now - when[id(e)] >= EventHold.HOLD_S)
            assert all(now - when[id(e)] >= EventHold.HOLD_S or e.t <= upto for e in batch)
        out += batch
    out += hold.flush()
    assert sorted(id(e) for e in out) == sorted(id(e) for _, e in events)
