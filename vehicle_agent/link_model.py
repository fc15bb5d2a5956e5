"""Which link model a scenario asks for. (The fault emulator plugs in here.)"""

from __future__ import annotations

from typing import Any

from vehicle_agent.link import IdealLink, LinkModel


def link_model_for(scenario: Any) -> LinkModel:
    return IdealLink()
