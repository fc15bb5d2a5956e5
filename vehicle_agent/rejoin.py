"""Where does a restarted vehicle pick up a run under way? Where the world last saw it (its
newest telemetry row, ``world/last/<id>``), with ω near what its neighbours' consensus asks
(their newest rows), not laps away; from the configured start if the world knows nothing."""

from __future__ import annotations

from typing import TYPE_CHECKING

from cdus.wire import keys
from cdus.wire.messages import StateMsg, decode_states
from cdus.wire.rejected import Rejected

if TYPE_CHECKING:
    from vehicle_agent.agent import Agent

ASK_TIMEOUT = 2.0  # s for the world's answer about one vehicle


def rejoin(agent: Agent, tick: int) -> None:
    """Join the run at ``tick`` (the join the world sent, or the realtime tick now)."""
    a, node = agent, agent.node
    last: dict[int, StateMsg] = {}
    for j in [a.index, *node.neighbours]:
        for reply in a.session.get(keys.world_last(a.fleet, a.ids[j]), timeout=ASK_TIMEOUT):
            if reply.ok is None:
                continue
            rows = decode_states(reply.ok.payload.to_bytes(), len(a.ids))
            if not isinstance(rows, Rejected) and rows[0].sender == j:
                last[j] = rows[-1]
    mine = last.pop(a.index, None)
    omegas = {k: m.omega for k, m in last.items()}
    node.rejoin(tick, mine.q if mine else None, mine.heading if mine else None, mine.omega if mine else None, omegas)
    where = (f"its last known state q = {tuple(round(x, 2) for x in mine.q)}" if mine
             else "the configured start (no last state known)")
    a.log(f"rejoining at tick {tick} (t = {tick * a.period:.2f} s) from {where}, "
          f"ω = {node.vehicle.omega:.3f}" + (" (near its neighbours' consensus)" if omegas else ""))
