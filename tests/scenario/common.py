"""Scenario data the scenario tests share: a small valid fleet and ways to break it."""

from __future__ import annotations

import pytest

from cdus.scenario.config import ConfigError, parse_scenario

MINIMAL = """
[scenario]
name = "two_boats"

[[vehicle]]
id = "usv1"
kind = "usv"
path = { family = "circle", center = [0, 0], radius = 10 }

[[vehicle]]
id = "usv2"
kind = "usv"
phase = 1.5
path = { family = "circle", center = [0, 0], radius = 10 }
"""


def base() -> dict:
    """Three vehicles (2 USVs, 1 UAV) on circles, every default left unset."""
    return {
        "scenario": {"name": "t"},
        "vehicle": [
            {"id": "usv1", "kind": "usv", "path": {"family": "circle", "center": [0, 0], "radius": 10}},
            {"id": "usv2", "kind": "usv", "path": {"family": "circle", "center": [0, 0], "radius": 10}},
            {"id": "uav1", "kind": "uav", "path": {"family": "circle", "center": [0, 0, 20], "radius": 10}},
        ],
    }


def problems(data: dict, overrides=None) -> str:
    """The ConfigError text of a bad scenario (read as x.toml)."""
    with pytest.raises(ConfigError) as info:
        parse_scenario(data, "x.toml", overrides)
    return str(info.value)


def edit(fn) -> dict:
    """base() changed by ``fn``."""
    data = base()
    fn(data)
    return data


def v0(**kw):
    return lambda d: d["vehicle"][0].update(kw)


def v2(**kw):
    return lambda d: d["vehicle"][2].update(kw)


def section(table, **kw):
    return lambda d: d.setdefault(table, {}).update(kw)


def drop(*path):
    def fn(d):
        node = d
        for p in path[:-1]:
            node = node[p]
        del node[path[-1]]
    return fn


def check_bad(fn, fragment: str) -> None:
    """The scenario ``edit(fn)`` is rejected with ``fragment`` in its message, every line naming the file."""
    message = problems(edit(fn))
    assert fragment in message
    assert all(line.startswith("x.toml: ") for line in message.splitlines())
