"""Which path families are there, and what does each take? The registry, one entry per family.

A family module (``circle.py``, ``spline.py``, ...) holds its curve and registers it once with
:func:`register`: its name, a one-line summary, its parameters (:class:`Param`: what kind of
value, how many axes, required or its default) and the function that builds the curve from
those values. The scenario layer reads a config table against this declaration
(``cdus.scenario.paths.make_path``); the core never sees a config table.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from typing import Any, Callable, Protocol

Vec = tuple[float, ...]

TAU = 2.0 * math.pi


class PathError(ValueError):
    """A path spec that cannot be built. ``field`` names the offending parameter."""

    def __init__(self, field: str, message: str):
        super().__init__(f"{field}: {message}")
        self.field = field
        self.message = message


class Path(Protocol):
    dim: int  # 2 (planar) or 3
    period: float | None  # ω-period of a closed path, None for an open one
    direction: float  # s = ±1: steady state has ω̇ = s

    def eval(self, w: float) -> tuple[Vec, Vec, Vec]:
        """f(ω), f'(ω), f''(ω)."""
        ...


class Centred:
    """A family whose ``center`` gives its dimension (2 or 3 numbers)."""

    center: Vec

    @property
    def dim(self) -> int:
        return len(self.center)


class OneTurn:
    """A closed family whose lap is one turn of βω: ω-period 2π/|β|."""

    beta: float

    @property
    def period(self) -> float:
        return TAU / abs(self.beta)


#: the kinds of value a parameter takes (cdus.scenario.paths reads each)
KINDS = ("vector", "number", "positive", "points", "flag")


@dataclass(frozen=True)
class Param:
    """One parameter of a family.

    ``kind``: ``vector`` (a list of numbers; ``dims`` its allowed lengths, or the name of the
    parameter whose length it takes), ``number``, ``positive`` (> 0), ``points`` (a list of
    vectors of 2 or 3 numbers, all of one length), ``flag`` (true/false). A parameter that is
    not ``required`` takes ``default`` when absent. ``check`` (optional) refuses a value the
    bounds let through, raising :class:`PathError`, right after the value is read."""

    name: str
    kind: str
    required: bool = False
    default: Any = None
    dims: tuple[int, ...] | str = (2, 3)
    check: Callable[[Any], None] | None = None


@dataclass(frozen=True)
class Family:
    """A path family: ``build(**values, beta=β, direction=s)`` makes its curve from the values
    of ``params`` (in their order). ``speed``: how a ``speed`` (m/s on the path) sets β, or None
    when the family has no constant on-path speed: ``"1"`` for β = speed (|f₀'| = 1), or the
    name of the parameter β = speed / it (a circle's radius)."""

    name: str
    summary: str
    params: tuple[Param, ...]
    build: Callable[..., Path]
    speed: str | None = None

    def __post_init__(self) -> None:
        for p in self.params:
            if p.kind not in KINDS:
                raise ValueError(f"path family {self.name}: parameter {p.name} has kind {p.kind!r}, not one of {KINDS}")

    @property
    def keys(self) -> frozenset[str]:
        return frozenset(p.name for p in self.params)


#: every family, by name, in the order they were registered
REGISTRY: dict[str, Family] = {}


def register(family: Family) -> Family:
    """Declare a family (once: a second family of the same name is a programming error)."""
    if family.name in REGISTRY:
        raise ValueError(f"path family {family.name!r} is registered twice")
    REGISTRY[family.name] = family
    return family


class _Summaries(Mapping[str, str]):
    """name -> one-line summary of its parameters, for every registered family (a live view)."""

    def __getitem__(self, name: str) -> str:
        return REGISTRY[name].summary

    def __iter__(self) -> Iterator[str]:
        return iter(REGISTRY)

    def __len__(self) -> int:
        return len(REGISTRY)


FAMILIES: Mapping[str, str] = _Summaries()
