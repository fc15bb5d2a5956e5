"""The agent's watch of the world's liveliness token: only the world's own key, and its return
after every world token went, is news of an outage (docs/security.md, "Liveliness"); back from
one, its recent ω are said again once, and again only while the fleet is held."""

from __future__ import annotations

from collections import Counter, deque

import zenoh
from hypothesis import HealthCheck, example, given, settings, strategies as hs

from cdus.sim.build import listeners_of
from cdus.wire import keys
from cdus.wire.messages import OmegaMsg, decode_omega, encode_control, encode_omega
from tests.fakes import Payload, Sample
from tests.vehicle_agent.fake_session import FLEET, ME, Liveliness
from vehicle_agent import lockstep, outage
from vehicle_agent.agent import WORLD_BACK

W = keys.alive(FLEET, keys.WORLD, "e1")  # the world's token


class Token:
    def __init__(self, key: str, up: bool = True):
        self.key_expr = key
        self.kind = zenoh.SampleKind.PUT if up else zenoh.SampleKind.DELETE


def watch(a):
    """The agent's callback for the world's token, as declared in open()."""
    callback = next(cb for k, cb in reversed(Liveliness.callbacks) if k == keys.alive_of(FLEET, keys.WORLD))
    return lambda k, up=True: (callback(Token(k, up)), a.drain())


def test_a_wildcard_token_is_counted_and_never_taken_for_the_worlds_return(fake):
    a, _, _ = fake()
    hear = watch(a)
    hear(W)  # the world's token as the watch's history gives it: no return
    for key in (f"cdus/{FLEET}/alive/**", f"cdus/{FLEET}/alive/world", f"cdus/{FLEET}/alive/*/*"):
        hear(key)
        hear(key, up=False)
        hear(key)
    hear(keys.alive(FLEET, keys.WORLD, "f0"))  # a second world while the world's is up
    hear(keys.alive(FLEET, keys.WORLD, "f0"), up=False)
    hear(keys.alive(FLEET, keys.WORLD, "f0"))
    assert a.outage.resend_until == 0.0
    assert a.rejected == {"token_key": 6, "token_extra": 2}
    assert a.stats().rejected_by_reason == {"token_key": 6, "token_extra": 2}


def test_the_worlds_token_back_after_every_world_token_went_is_an_outage(fake):
    a, _, lines = fake()
    hear = watch(a)
    hear(W)
    hear(keys.alive(FLEET, keys.WORLD, "f0"))
    hear(W, up=False)  # the forger's is still up: this session still hears the router
    hear(W)
    assert a.outage.resend_until == 0.0
    hear(W, up=False)
    hear(keys.alive(FLEET, keys.WORLD, "f0"), up=False)  # every world token gone: cut off
    assert not any(WORLD_BACK in ln for ln in lines)
    hear(W)
    assert a.outage.resend_until > 0.0 and any(WORLD_BACK in ln for ln in lines)


junk = hs.one_of(hs.sampled_from([f"cdus/{FLEET}/alive/**", f"cdus/{FLEET}/alive/world", f"cdus/{FLEET}/alive/*/*",
                                  keys.alive(FLEET, keys.WORLD, "f0"), keys.alive(FLEET, keys.WORLD, "f1"),
                                  keys.alive(FLEET, "usv2", "a2"), f"cdus/{FLEET}/alive/world/*"]),
                 hs.text(max_size=20))


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(hs.lists(hs.tuples(junk, hs.booleans()), max_size=25))
def test_while_the_worlds_own_token_is_up_nothing_else_makes_the_agent_say_its_messages_again(fake, news):
    a, _, _ = fake()
    hear = watch(a)
    hear(W)
    for key, up in news:
        hear(key, up)
    assert a.outage.resend_until == 0.0


# ------------------------------------------------------------------ what is said again, and how often
class Clock:
    """The time vehicle_agent.lockstep and .outage read (``time.monotonic``, ``time.time``): moved
    by the test's inbox, not by the wall."""

    def __init__(self) -> None:
        self.now = 1000.0

    def monotonic(self) -> float:
        return self.now

    def time(self) -> float:
        return self.now


class Script:
    """The agent's inbox as a script: each wait takes the next sample, ``dt`` s after the last (a
    callable on the way is news from another thread: run, and it takes no time)."""

    def __init__(self, clock: Clock, items: list) -> None:
        self.clock, self.items = clock, deque(items)

    def recv(self) -> Sample:
        while self.items:
            item = self.items.popleft()
            if callable(item):
                item()
                continue
            dt, sample = item
            self.clock.now += dt
            return sample
        raise AssertionError("the agent waited on an empty inbox (it would block for ever)")

    def try_recv(self) -> None:
        return None


def _sample(key: str, payload: bytes) -> Sample:
    return Sample(key, Payload(payload))


def run_with_an_outage(fake, monkeypatch, dts: list[float], at: int = 20, held: list[float] = ()) -> dict[int, int]:
    """usv1 of the lake ring runs 40 ticks in lockstep, each neighbour's ω arriving ``dts[n]`` s
    after the one before (it waits for each); before tick ``at`` its session is cut off and back
    (every world token goes and comes back), then ``held``: wakes ``dt`` s apart that bring no ω
    (the fleet held). Returns how many times each of its ω seqs was put."""
    clock = Clock()
    monkeypatch.setattr(lockstep, "time", clock)
    monkeypatch.setattr(outage, "time", clock)
    a, s, _ = fake(duration=0.8)  # ticks 0..40 at 50 Hz
    hear = watch(a)
    hear(W)  # the watch's history: the world is up
    a.inbox = script = Script(clock, [])
    items = script.items
    items.extend((0.0, _sample(keys.ctl(FLEET, [ME]), encode_control(op, **kw)))
                 for op, kw in (("join", {"tick": 0}), ("grant", {"until": a.last_tick})))
    callback = next(cb for k, cb in reversed(Liveliness.callbacks) if k == keys.alive_of(FLEET, keys.WORLD))
    for seq in range(a.last_tick):  # tick seq + 1 needs both neighbours' ω of seq
        if seq + 1 == at:
            items.append(lambda: (callback(Token(W, False)), callback(Token(W))))
            items.extend((dt, _sample(keys.wake(FLEET, ME), b"")) for dt in held)
        for vid in ("usv2", "uav3"):
            j = a.ids.index(vid)
            msg = OmegaMsg(j, seq, seq * a.period, 1.0 - seq * a.period, -1.0)
            items.append((dts[seq % len(dts)], _sample(keys.omega(FLEET, vid, listeners_of(a.scenario, vid)),
                                                       encode_omega(msg))))
    items.append((0.0, _sample(keys.ctl(FLEET, [ME]), encode_control("stop"))))
    assert a.run() == a.last_tick + 1
    puts = Counter(decode_omega(p).seq for p in s.pubs[keys.omega(FLEET, ME, listeners_of(a.scenario, ME))].puts)
    assert sorted(puts) == list(range(a.last_tick))  # every ω of the run, none at the last tick
    return puts


@settings(max_examples=20, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(hs.lists(hs.floats(0.0, 0.49), min_size=1, max_size=40))
@example(dts=[0.45])
def test_back_from_an_outage_a_fleet_that_moves_on_hears_each_omega_again_once(fake, monkeypatch, dts):
    """A paused process (SIGSTOP past its lease) comes back to the world's token going and coming
    back, like a router outage; what it sent before was delivered or lost once, and the fleet
    moves on after it is said again. It was said every second for RESEND_FOR s whatever the fleet
    did: 4,002 ω ten times to each listener after a 70 s pause (80,040 stale rejects). Each tick
    waits less than RESEND_EVERY here (two samples of < 0.5 s each): whatever the timing, each ω
    sent before the outage is said again exactly once (the old rule, at 0.9 s a tick: 9 times)."""
    puts = run_with_an_outage(fake, monkeypatch, dts)
    assert {seq: puts[seq] for seq in range(20)} == {seq: 2 for seq in range(20)}  # sent by tick 19
    assert all(puts[seq] == 1 for seq in range(20, 40))


def test_back_from_an_outage_a_held_fleet_hears_the_omegas_again_every_second(fake, monkeypatch):
    """A router outage can lose what is said at the world's return too (the router does not know
    the neighbours' subscriptions yet): the fleet then waits, and while it does the agent says
    its recent ω again every RESEND_EVERY s (tests/e2e/test_completion.py freezes the router).
    Held 3.25 s after the return (12 wakes, then usv2's ω, 0.25 s apart): said at the return and
    1, 2 and 3 s after it; once the fleet moves on (uav3's ω, 0.25 s later), never again."""
    assert outage.RESEND_EVERY == 1.0
    puts = run_with_an_outage(fake, monkeypatch, [0.25], held=[0.25] * 12)
    assert {seq: puts[seq] for seq in range(20)} == {seq: 5 for seq in range(20)}
    assert all(puts[seq] == 1 for seq in range(20, 40))
