"""vehicle_agent.report: what the agent tells the world: its counters (only new latency samples),
and after an outage as much ω and telemetry as can have been lost."""

from __future__ import annotations

from cdus.wire.messages import decode_states
from cdus.wire.schemas import decode_stats, encode_stats
from tests.vehicle_agent.fake_session import granted, stop_when_idle


def test_stats_round_trip_and_send_only_new_latency_samples(fake):
    a, s, lines = fake(duration=0.1)
    granted(s, a, until=5)
    stop_when_idle(s)
    a.run()
    first = a.stats()
    assert decode_stats(encode_stats(first)) == first
    assert a.stats().latencies_ms == ()  # already reported


def test_after_an_outage_an_agent_says_again_every_omega_its_lookahead_can_have_run_ahead(fake):
    """With a least link delay of 0.5 s (25 ticks) a sender steps 25 ticks past its neighbours'
    newest ω, so more than 16 of its messages can be lost in flight when the router goes: it
    says again (far) more than that."""
    a, s, lines = fake(duration=2.0, **{"link.delay.base": 0.5})
    a.clock.begun, a.clock.granted = True, a.last_tick
    for n in range(40):
        a.step(n)
    sent = list(a.report.pub_omega.puts)
    a.report.pub_omega.puts.clear()
    a.report.resend()
    assert a.report.pub_omega.puts == sent  # all 40, in order


def test_after_an_outage_an_agent_says_again_the_telemetry_a_grant_window_can_hold(fake):
    """A vehicle runs up to a grant window (hundreds of ticks) past the world's newest row of the
    slowest vehicle: rows lost in flight then are said again, in messages the world takes."""
    a, s, lines = fake(duration=10.0)
    a.clock.begun, a.clock.granted = True, a.last_tick
    for n in range(300):
        a.step(n)
    a.report.flush()
    a.report.pub_state.puts.clear()
    a.report.resend()
    rows = [r for p in a.report.pub_state.puts for r in decode_states(p, len(a.ids))]
    assert [r.tick for r in rows] == list(range(300))
