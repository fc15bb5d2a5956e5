"""A vehicle process loads only what it uses: numpy (and quadprog) cost ~14 MB of RSS in each of
64 processes, and only the safety filter's QP needs them (bench/realtime_capacity.py)."""

from __future__ import annotations

from tests.test_startup import modules_after as _modules_after


def test_an_agent_without_a_safety_filter_loads_no_numpy():
    mods = _modules_after("""
        from cdus.scenario.config import load_scenario
        from cdus.wire.transport import Transport
        from vehicle_agent.__main__ import build_parser
        from vehicle_agent.agent import Agent
        sc = load_scenario("configs/lake_circle.toml")
        agent = Agent(sc, sc.ids[0], "t", Transport(), clock="realtime", log=lambda s: None)
        for n in range(20):
            agent.node.step(n)
    """)
    assert "vehicle_agent.agent" in mods and "zenoh" in mods  # the probe did build and step an agent
    assert not {"numpy", "quadprog", "rerun", "matplotlib"} & mods


def test_the_safety_filter_still_solves_its_qp_when_it_needs_one():
    # the QP path imports numpy/quadprog where it solves: a conflict the projection cannot settle
    mods = _modules_after("""
        from cdus.core.safety import SafetyParams, _solve
        u, how, _ = _solve((1.0, 0.0), [(-1.0, 0.0), (0.0, -1.0), (0.7071067811865476, 0.7071067811865476)],
                           [0.5, 0.5, 0.5], 1e-12)
        assert how in ("qp", "relaxed"), how
    """)
    assert "numpy" in mods and "quadprog" in mods
