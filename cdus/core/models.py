"""Which vehicle models can a scenario name? The plants, each with its regulators, in one table.

:data:`PLANTS` maps a scenario's ``plant`` name to a :class:`PlantModel`: the kinds of vehicle
it models, how to build its :class:`cdus.core.plants.Plant` object, and its regulators by the
scenario's ``regulator`` name (the first is the default; none for a velocity-level plant),
each with its gains type (the keys ``regulator_gains`` takes are its fields). The scenario's
validation (cdus.scenario.vehicles) reads its vocabulary from here and the build
(cdus.sim.build) its objects, so a model is declared once. :func:`register_plant` adds one
(the door for plug-ins: issue 28's ``cdus.plants`` entry points, issue 29's ``ros2``).
An unknown name is refused by :class:`UnknownName`, naming the field and the known names.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from typing import Any, Callable, Mapping

from cdus.core.plants import USV_PRESETS, DoubleIntegrator, IdealPlant, Plant, USV3DOF
from cdus.core.regulators import PD, Heading, HeadingGains, Paper, PaperGains, Regulator, UAVGains
from cdus.core.robot import RobotPlant

DEFAULT_PRESET = "cybership2"


class UnknownName(ValueError):
    """A name that is not in a registry: ``field`` (e.g. ``plant``), the name, the known ones."""

    def __init__(self, field: str, name: Any, known: tuple[str, ...], what: str):
        self.field, self.name, self.known = field, name, known
        super().__init__(f"{field}: unknown {what} {name!r}; known: {', '.join(known) or '(none)'}")


@dataclass(frozen=True)
class RegulatorModel:
    """A regulator of a plant: its gains type (a dataclass: the keys and defaults of
    ``regulator_gains``) and ``build(plant, gains) -> Regulator``."""

    gains: type
    build: Callable[[Any, Any], Regulator]

    @property
    def gain_keys(self) -> tuple[str, ...]:
        return tuple(f.name for f in fields(self.gains))

    def make(self, plant: Plant, gains: Mapping[str, float]) -> Regulator:
        return self.build(plant, self.gains(**gains))


@dataclass(frozen=True)
class PlantModel:
    """A plant a scenario can name: the kinds it models (``usv``, ``uav``), ``build(params) ->
    Plant`` (params: ``epsilon``, ``preset``), and its regulators by name (the first is the
    default; empty: the plant takes the velocity reference, no regulator)."""

    kinds: tuple[str, ...]
    build: Callable[[Mapping[str, Any]], Plant]
    regulators: Mapping[str, RegulatorModel] = field(default_factory=dict)

    def regulator(self, plant: str, name: str | None) -> RegulatorModel:
        """The regulator ``name`` of this plant (None: the default), or :class:`UnknownName`."""
        if name is None and self.regulators:
            return next(iter(self.regulators.values()))
        if name not in self.regulators:
            raise UnknownName("regulator", name, tuple(self.regulators), f"regulator of plant {plant!r}")
        return self.regulators[name]


def _usv(params: Mapping[str, Any]) -> USV3DOF:
    eps = params.get("epsilon")
    return USV3DOF(tuple(eps) if eps else USV_PRESETS[params.get("preset") or DEFAULT_PRESET])


PLANTS: dict[str, PlantModel] = {
    "ideal": PlantModel(("usv", "uav"), lambda params: IdealPlant()),
    "usv_3dof": PlantModel(("usv",), _usv, {
        "heading": RegulatorModel(HeadingGains, lambda plant, g: Heading(plant.eps, g)),
        "paper": RegulatorModel(PaperGains, lambda plant, g: Paper(plant.eps, g)),
    }),
    "uav_double_integrator": PlantModel(("uav",), lambda params: DoubleIntegrator(), {
        "pd": RegulatorModel(UAVGains, lambda plant, g: PD(g)),
    }),
    "ros2": PlantModel(("usv", "uav"), lambda params: RobotPlant()),  # a real robot (cdus.core.robot)
}


def plant_model(name: Any, field: str = "plant") -> PlantModel:
    """The model a scenario names ``plant = name``, or :class:`UnknownName` naming ``field``."""
    try:
        return PLANTS[name]
    except (KeyError, TypeError):
        raise UnknownName(field, name, tuple(PLANTS), "plant") from None


def register_plant(name: str, model: PlantModel) -> None:
    """Add a plant under ``name`` (a plug-in's); a name already taken is refused."""
    if not isinstance(name, str) or not name:
        raise ValueError(f"plant: a plant's name must be a non-empty string, got {name!r}")
    if name in PLANTS:
        raise ValueError(f"plant: {name!r} is already a plant; choose another name")
    PLANTS[name] = model


def build(plant: str, regulator: str | None, params: Mapping[str, Any],
          gains: Mapping[str, float]) -> tuple[Plant, Regulator | None]:
    """A vehicle's plant and regulator objects (None for a plant without regulators)."""
    model = plant_model(plant)
    obj = model.build(params)
    if not model.regulators:
        return obj, None
    return obj, model.regulator(plant, regulator).make(obj, gains)
