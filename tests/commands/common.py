"""A recorded stand-in for a VehicleNode: what a command's apply calls on it."""

from __future__ import annotations

from cdus.core.changes import Applied as CoreApplied


class RecordedNode:
    def __init__(self, index=0, dim=2, radio=None):
        self.index, self.period, self.calls, self.radio = index, 0.1, [], radio
        self.vehicle = type("V", (), {"dim": dim, "k": (1.0,) * dim, "c": 1.0, "plant": "ideal", "physics_steps": 1})()
        self.table = type("T", (), {"links": ()})()

    def on_roster(self, ch):
        self.calls.append(ch)

    # each set_* answers as cdus.core.changes does: Applied(tick[, at]) or Refused(reason)
    def set_gains(self, k, c, tick):
        self.calls.append(("gains", k, c, tick))
        return CoreApplied(tick)

    def set_formation(self, phases, tick):
        self.calls.append(("formation", phases, tick))
        return CoreApplied(tick)

    def set_path(self, path, tick):
        self.calls.append(("path", path.dim, tick))
        return CoreApplied(tick)

    def set_link(self, spec, at):
        self.calls.append(("link", spec.loss if hasattr(spec, "loss") else spec, at))
        at = max(at, 1.0)
        return CoreApplied(round(at / self.period), at)

    def set_policy(self, policy, timeout, tick):
        self.calls.append(("policy", policy, timeout, tick))
        return CoreApplied(tick)
