"""vehicle_agent.rejoin: a restarted vehicle picks up the run where the world last saw it, with ω
near its neighbours' newest; from the configured start when the world knows nothing (or sends a
row that is not its own). The world's answers are scripted on the fake session."""

from __future__ import annotations

from types import SimpleNamespace

from cdus.wire import keys
from cdus.wire.messages import StateMsg, encode_states
from tests.fakes import Payload
from tests.vehicle_agent.fake_session import FLEET, ME
from vehicle_agent.rejoin import rejoin


def answers(s, rows: dict[str, list[StateMsg]]) -> None:
    """The world answers ``world/last/<id>`` with ``rows[id]``; nobody answers for the others."""
    def get(key, **kw):
        vid = str(key).rsplit("/", 1)[-1]
        assert str(key) == keys.world_last(FLEET, vid)
        return [SimpleNamespace(ok=SimpleNamespace(payload=Payload(encode_states(rows[vid]))))] if vid in rows else []
    s.get = get


def state(j: int, n: int, q: tuple, omega: float) -> StateMsg:
    return StateMsg(j, n, n * 0.02, q, 0.5, 0.0, omega, 0.0, 0.5)


def test_a_restarted_vehicle_rejoins_where_the_world_last_saw_it(fake):
    a, s, lines = fake()
    answers(s, {ME: [state(a.index, 40, (3.0, 4.0), 1.25)]})
    rejoin(a, 50)
    assert a.node.joined_at == 50 and a.node.state == "live"
    assert tuple(a.node.vehicle.q[:2]) == (3.0, 4.0)
    assert any("rejoining at tick 50" in ln and "q = (3.0, 4.0)" in ln for ln in lines), lines


def test_with_nothing_known_it_rejoins_from_the_configured_start(fake):
    a, s, lines = fake()
    start = tuple(a.node.vehicle.q)
    answers(s, {})
    rejoin(a, 20)
    assert a.node.joined_at == 20 and tuple(a.node.vehicle.q) == start
    assert any("the configured start (no last state known)" in ln for ln in lines), lines


def test_a_row_of_another_vehicle_on_its_key_is_not_taken_as_its_own(fake):
    a, s, lines = fake()
    start = tuple(a.node.vehicle.q)
    other = a.ids.index("usv2")
    answers(s, {ME: [state(other, 40, (90.0, 90.0), 1.0)]})
    rejoin(a, 20)
    assert tuple(a.node.vehicle.q) == start
    assert any("the configured start" in ln for ln in lines)


def test_its_omega_is_taken_near_the_neighbours_newest_not_its_own(fake):
    a, s, lines = fake()
    mine = state(a.index, 40, (3.0, 4.0), 9.0)
    near = {v: [state(a.ids.index(v), 40, (0.0, 0.0) if v.startswith("usv") else (0.0, 0.0, 20.0), 2.0)]
            for v in ("usv2", "uav3")}
    answers(s, {ME: [mine], **near})
    rejoin(a, 50)
    assert abs(a.node.vehicle.omega - 9.0) > 1.0  # not its own stale 9 rad
    assert any("near its neighbours' consensus" in ln for ln in lines), lines
