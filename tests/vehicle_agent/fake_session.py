"""A fake Zenoh session for the agent's tests: its inbox a scripted list of samples (the agent's
one subscription), publishers that record puts; the ``fake`` fixture builds an opened agent on it
(tests/vehicle_agent/conftest.py)."""

from __future__ import annotations

from collections import deque

import pytest

from cdus.scenario.config import load_scenario
from cdus.sim.build import listeners_of
from cdus.wire import keys
from cdus.wire.messages import OmegaMsg, encode_control, encode_omega
from cdus.wire.transport import Transport
from tests.fakes import Payload, Sample
from vehicle_agent import agent as agent_module
from vehicle_agent.agent import Agent

FLEET = "tfake"
ME = "usv1"  # listens to usv2 and uav3 on the lake ring


class Inbox:
    """The agent's subscription: samples in the order a test scripts them; ``then``: samples
    that arrive only once the agent blocks on an empty inbox (e.g. the world's stop)."""

    def __init__(self) -> None:
        self.q: deque[Sample] = deque()
        self.then: deque[Sample] = deque()

    def recv(self) -> Sample:
        if not self.q and self.then:
            self.q.append(self.then.popleft())
        if not self.q:
            raise AssertionError("the agent waited on an empty inbox (it would block for ever)")
        return self.q.popleft()

    def try_recv(self) -> Sample | None:
        return self.q.popleft() if self.q else None


class Pub:
    def __init__(self, key: str):
        self.key = key
        self.puts: list[bytes] = []

    def put(self, payload) -> None:
        self.puts.append(bytes(payload))


class Reply:
    ok = b""


class Token:
    def undeclare(self) -> None:
        pass


class Liveliness:
    callbacks: list = []

    def declare_token(self, key: str) -> Token:
        return Token()

    def declare_subscriber(self, key: str, callback, **kw) -> Token:
        Liveliness.callbacks.append((key, callback))
        return Token()


class Session:
    def __init__(self) -> None:
        self.inbox = Inbox()
        self.pubs: dict[str, Pub] = {}
        self.puts: list[tuple[str, bytes]] = []
        self.closed = False

    def declare_subscriber(self, key, handler=None):
        return self.inbox

    def declare_publisher(self, key, **kw) -> Pub:
        return self.pubs.setdefault(key, Pub(key))

    def liveliness(self) -> Liveliness:
        return Liveliness()

    def zid(self) -> str:
        return "a9e1"

    def put(self, key, payload, **kw) -> None:
        self.puts.append((key, bytes(payload)))

    def declare_queryable(self, key, handler):
        return Token()

    def get(self, key, **kw):
        if str(key).endswith("/ping"):  # every listener answers a link check
            return [Reply()]
        return []  # nobody knows where the vehicle was

    def close(self) -> None:
        self.closed = True


@pytest.fixture
def fake(monkeypatch):
    sessions: list[Session] = []
    agents: list[Agent] = []

    def open_session(transport):
        s = Session()
        sessions.append(s)
        return s

    monkeypatch.setattr(agent_module, "open_session", open_session)

    def make(clock: str = "lockstep", duration: float = 0.1, **over) -> tuple[Agent, Session, list[str]]:
        sc = load_scenario("configs/lake_circle.toml", over)
        lines: list[str] = []
        a = Agent(sc, ME, FLEET, Transport(), clock=clock, duration=duration, log=lines.append)
        a.open()
        agents.append(a)
        return a, sessions[-1], lines

    yield make
    for a in agents:
        a.close()


def ctl(session: Session, op: str, **fields) -> None:
    session.inbox.q.append(Sample(keys.ctl(FLEET, [ME]), Payload(encode_control(op, **fields))))


def stop_when_idle(session: Session) -> None:
    session.inbox.then.append(Sample(keys.ctl(FLEET, [ME]), Payload(encode_control("stop"))))


def omega_from(session: Session, a: Agent, vid: str, seq: int, payload: bytes | None = None) -> None:
    j = a.ids.index(vid)
    msg = OmegaMsg(j, seq, seq * a.period, 1.0 - seq * a.period, -1.0)
    key = keys.omega(FLEET, vid, listeners_of(a.scenario, vid))
    session.inbox.q.append(Sample(key, Payload(encode_omega(msg) if payload is None else payload)))


def forged(session: Session, a: Agent, vid: str, seq: int, t: float, omega: float, rate: float = -1.0) -> None:
    j = a.ids.index(vid)
    key = keys.omega(FLEET, vid, listeners_of(a.scenario, vid))
    session.inbox.q.append(Sample(key, Payload(encode_omega(OmegaMsg(j, seq, t, omega, rate)))))


def granted(session: Session, a: Agent, until: int = 5, seqs: int = 5) -> None:
    """The world's join at tick 0 and grant to ``until``, and both neighbours' broadcasts of
    ticks 0 .. ``seqs`` - 1."""
    ctl(session, "join", tick=0)
    ctl(session, "grant", until=until)
    for seq in range(seqs):
        omega_from(session, a, "usv2", seq)
        omega_from(session, a, "uav3", seq)
