"""The agent's watch of the world's liveliness token: only the world's own key, and its return
after every world token went, is news of an outage (docs/security.md, "Liveliness")."""

from __future__ import annotations

import zenoh
from hypothesis import HealthCheck, given, settings, strategies as hs

from cdus.wire import keys
from tests.vehicle_agent.fake_session import FLEET, Liveliness
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
