"""Which link model does a scenario ask for? The ideal link, or the fault emulator."""

from __future__ import annotations

from typing import Any

from vehicle_agent.faults import LinkSpec, validate_link
from vehicle_agent.link import IdealLink, LinkEmulator, LinkModel


def link_spec_for(scenario: Any) -> LinkSpec:
    """The validated ``[link]`` table of a ``cdus.config.Scenario`` (raises ``ConfigError``)."""
    return validate_link(scenario.link or {}, list(scenario.ids), scenario.source)


def link_seed(spec: LinkSpec, scenario: Any) -> int:
    """``link.seed`` if given, else the scenario's seed."""
    return spec.seed if spec.seed is not None else scenario.seed


def link_model_for(scenario: Any) -> LinkModel:
    """:class:`IdealLink` when the ``[link]`` table has no faults, else a :class:`LinkEmulator`
    (seeded with ``link.seed``, else ``scenario.seed``). Raises ``ConfigError`` for a bad table."""
    spec = link_spec_for(scenario)
    if spec.is_ideal:
        return IdealLink()
    return LinkEmulator(spec, scenario.ids, link_seed(spec, scenario))


def link_emulator_for(scenario: Any) -> LinkEmulator:
    """Always an emulator (ideal links take its fast path), so faults can change at run time."""
    spec = link_spec_for(scenario)
    return LinkEmulator(spec, scenario.ids, link_seed(spec, scenario))
