"""The agent's tests share a fake Zenoh session (tests/vehicle_agent/fake_session.py)."""

from tests.vehicle_agent.fake_session import fake  # noqa: F401 (the fixture)
