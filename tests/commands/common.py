"""A recorded stand-in for a VehicleNode: what a command's apply calls on it."""

from __future__ import annotations


class RecordedNode:
    def __init__(self, index=0, dim=2, radio=None):
        self.index, self.period, self.calls, self.radio = index, 0.1, [], radio
        self.vehicle = type("V", (), {"dim": dim, "k": (1.0,) * dim, "c": 1.0, "plant": "ideal", "physics_steps": 1})()
        self.table = type("T", (), {"links": ()})()

    def on_roster(self, ch):
        self.calls.append(ch)

    def set_gains(self, k, c, tick):
        self.calls.append(("gains", k, c, tick))

    def set_formation(self, phases, tick):
        self.calls.append(("formation", phases, tick))

    def set_path(self, path, tick):
        self.calls.append(("path", path.dim, tick))

    def set_link(self, spec, at):
        self.calls.append(("link", spec.loss if hasattr(spec, "loss") else spec, at))
        return max(at, 1.0)

    def set_policy(self, policy, timeout, tick):
        self.calls.append(("policy", policy, timeout, tick))
