"""Was this session cut off from the world, and must the agent say its recent messages again?

Lockstep only (the clock strategy declares the watch): when every world liveliness token went
and one came back (a router frozen or restarted, a network cut), what was in flight may be lost
and the fleet would wait for it, so the agent says its newest ω and telemetry again
(vehicle_agent.report): once at the return, and again within :data:`RESEND_FOR` s only while
the fleet is held (its tick awaited for :data:`RESEND_EVERY` s: what was said again may have
been lost too). Only a token on exactly the world's key (``alive/world/<zid>``,
cdus.wire.keys.alive_token) counts. The same return follows this process's own freeze (a
``pause`` fault, SIGSTOP past the liveliness lease: the router closed its session): then only
what was in flight at the freeze can have been lost, once, and the fleet moves on after the
first saying, so it is said once (it was said every second for 10 s: 10 x 4,002 ω each to two
listeners, 80,040 stale rejects after a 70 s pause; tests/vehicle_agent/test_outage.py).
"""

from __future__ import annotations

import time
from collections import deque
from typing import TYPE_CHECKING, Any

import zenoh

from cdus.wire import keys

if TYPE_CHECKING:
    from vehicle_agent.agent import Agent

#: said again at most every RESEND_EVERY s while stuck, and for RESEND_FOR s after the world's token
#: came back while the tick is awaited that long: the token can arrive before the router knows the
#: neighbours' subscriptions again, and what is said before that is lost too (the fleet then waits)
RESEND_EVERY = 1.0
RESEND_FOR = 10.0
#: logged when taken: the session was cut off by the network or the router, or by this process's own
#: freeze past its lease (a pause fault), which the session cannot tell apart
WORLD_BACK = "the world's token is back after every world token went (an outage, or this process was frozen)"


class Outage:
    """The world's tokens as this session sees them, and until when to say things again."""

    def __init__(self, agent: Agent):
        self.agent = agent
        self.news: deque[tuple[str, bool]] = deque()  # the world's liveliness (Zenoh's thread -> main)
        self.tokens: set[str] = set()  # the session ids of the world's tokens up
        self.left = False  # every world token went (this session was cut off): their return is news
        self.resend_until = 0.0  # monotonic s: back from an outage, say recent messages again till then
        self.owed = False  # back from an outage: the recent messages are said again at the next wake
        self.resent_at = 0.0

    def on_token(self, sample: Any) -> None:
        """Liveliness of the world as this session sees it (Zenoh's thread): handed to the main
        thread (:meth:`take_news`), which a wake fetches."""
        self.news.append((str(sample.key_expr), sample.kind == zenoh.SampleKind.PUT))
        self.agent.wake()

    def take_news(self) -> None:
        """The world's tokens coming back after every one of them went means this session was
        cut off from the router and is back: the recent messages are said again (RESEND_FOR).
        A token on a key expression that intersects the world's (``alive/**``, anyone's) is
        counted (``token_key``) and ignored, and so is a second world token while one is up
        (``token_extra``: its coming and going is no news of this session's link)."""
        reject = self.agent.intake.reject
        while self.news:
            key, up = self.news.popleft()
            token = keys.alive_token(key)
            if token is None or token[0] != keys.WORLD:
                if up:  # counted once, when it comes
                    reject(key, "token_key")
                continue
            zid, tokens = token[1], self.tokens
            if not up:
                if zid in tokens:
                    tokens.discard(zid)
                    self.left |= not tokens
                continue
            if zid in tokens:
                continue
            if tokens:
                reject(keys.WORLD, "token_extra")
            elif self.left:
                self.left = False
                self.owed = True
                self.resend_until = time.monotonic() + RESEND_FOR
                self.agent.log(f"{WORLD_BACK}: saying recent messages again (and again within "
                               f"{RESEND_FOR:g} s while the fleet is held)")
            tokens.add(zid)

    def resend_due(self, now: float, waiting_since: float, stuck: bool) -> bool:
        """Say the recent messages again now (monotonic s)? Back from an outage, at once; then till
        ``resend_until`` only once the tick at hand has been awaited (since ``waiting_since``)
        RESEND_EVERY s after it was last said (the fleet is held: what was said may have been lost
        too); after that only while ``stuck`` (granted and waiting too long), every RESEND_EVERY s.
        A fleet that moves on after the first saying had what it needed: nothing is said twice."""
        if self.owed:
            self.owed = False
        elif now < self.resend_until:
            if now - max(waiting_since, self.resent_at) < RESEND_EVERY:
                return False
        elif not stuck or now - self.resent_at < RESEND_EVERY:
            return False
        self.resent_at = now
        return True
