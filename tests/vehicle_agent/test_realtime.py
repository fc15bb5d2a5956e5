"""vehicle_agent.realtime: a realtime agent cuts a flood at its sender's rate before decoding, and
genuine ω does not spend the budget."""

from __future__ import annotations

import time
from types import SimpleNamespace

from tests.vehicle_agent.fake_session import omega_from
from vehicle_agent import intake as intake_module, realtime


def test_a_realtime_flood_on_one_key_is_cut_at_the_senders_rate_before_decoding(fake, monkeypatch):
    a, s, lines = fake(clock="realtime", duration=0.1)
    decoded = []
    real = intake_module.decode_omega
    monkeypatch.setattr(intake_module, "decode_omega", lambda *x, **kw: decoded.append(1) or real(*x, **kw))
    # the bucket's clock stands still: no token refills while it drains, however slow the machine
    # (it refilled at 200 a second, and a loaded machine's drain of 640 samples took over 25 ms)
    monkeypatch.setattr(realtime, "time", SimpleNamespace(monotonic=lambda: 100.0, time=time.time))
    burst = realtime.RATE_BURST
    for _ in range(10 * burst):
        omega_from(s, a, "usv2", 0)
    a.drain(lambda: 0.0)
    # the first is taken (its token given back), the next `burst` decoded and stale, the rest cut
    assert len(decoded) == burst + 1
    assert a.rejected == {"stale": burst, "rate": 10 * burst - burst - 1}


def test_genuine_omega_does_not_spend_its_senders_rate_budget(fake):
    a, s, lines = fake(clock="realtime", duration=10.0)
    a.clock.t0 = time.time() - 5.0  # the run is at tick ~250
    for seq in range(3 * realtime.RATE_BURST):  # more genuine messages than the bucket holds
        omega_from(s, a, "usv2", seq)
    a.drain(lambda: 5.0)
    assert not a.rejected
