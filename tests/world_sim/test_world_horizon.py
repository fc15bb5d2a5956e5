"""The lockstep world sizes its grant window to the fleet's speed (world_sim.world.HORIZON_S)."""

from __future__ import annotations

from cdus.sim.lockstep import GRANT_WINDOW, MAX_GRANT_WINDOW
from tests.world_sim.test_world import started, world
from world_sim.world import HORIZON_S


def test_the_grant_window_is_about_horizon_s_of_the_fleets_speed():
    w = started(world())
    assert w.lockstep.window == GRANT_WINDOW
    w.next_tick = 1000  # 1000 ticks recorded in the last 0.5 s: 2000 ticks/s
    mark = w.clock.widen_horizon(10.5, (10.0, 0))
    assert mark == (10.5, 1000)
    assert w.lockstep.window == int(2000 * HORIZON_S) and w.lockstep.grant_step == w.lockstep.window // 4
    w.clock.widen_horizon(11.0, mark)  # nothing recorded meanwhile (paused, a fault): back to the least
    assert w.lockstep.window == GRANT_WINDOW
    w.next_tick = 10**6
    w.clock.widen_horizon(12.0, (11.0, 1000))
    assert w.lockstep.window == MAX_GRANT_WINDOW
