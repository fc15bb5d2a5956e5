"""Which path families and vehicle models do a user's own packages add? The plug-ins: found,
checked, registered and probed once where a scenario is read, before anything starts.

A plug-in is a :class:`cdus.core.paths.Family` (group ``cdus.paths``) or a
:class:`cdus.core.models.PlantModel` (group ``cdus.plants``) named by ``module:object``, through
one of two doors (docs/plugins.md):

- an entry point of an installed package, ``[project.entry-points."cdus.paths"] gerono =
  "mypkg.gerono:FAMILY"`` (every installed one is loaded, once per process);
- the scenario's ``[plugins]`` table, the same lines: ``[plugins.paths] gerono = "mypkg.gerono:FAMILY"``.

Every process of a fleet (the world, each agent, ``cdus sim``, ``cdus launch``) reads the scenario
through :func:`cdus.scenario.config.parse_scenario`, which loads them here first, so all of them
know the same names. A plug-in that cannot be imported, has the wrong shape or takes a name
already taken is a problem of the config naming it, where it came from and the fix. What it
registers is wrapped (:class:`PluginPath`, :class:`PluginPlant`, :class:`PluginRegulator`): an
exception from its code while a vehicle runs becomes :class:`PluginFault` (a ``ValueError``,
which the tick protocol turns into a diverged vehicle, cdus.core.node), naming it; never a hang.
Its curve is probed with each path table of the scenario (:func:`path_problem`) and its plant
with each vehicle that names it (:func:`probe_plants`).
"""

from __future__ import annotations

import dataclasses
import functools
import importlib
import importlib.metadata
import math
import re
import sys
from dataclasses import dataclass
from typing import Any, Iterable, Mapping

from cdus.core import models
from cdus.core.guidance import desired_velocity
from cdus.core.models import PLANTS, PlantModel, RegulatorModel
from cdus.core.paths import REGISTRY, Family, Path, PathError, Vec, register
from cdus.core.regulators import Limits
from cdus.core.vocabulary import KINDS
from cdus.scenario.checks import Problems, describe, quote
from cdus.scenario.errors import ConfigError
from cdus.wire.bounds import MAX_METRES, MAX_RATE, finite, within

#: the [plugins] table's keys and the entry-point group of each
GROUPS = {"paths": "cdus.paths", "plants": "cdus.plants"}
WHAT = {"paths": "path family", "plants": "plant"}
#: the keys every path table takes besides its family's own (cdus.scenario.paths.COMMON)
RESERVED_PARAMS = frozenset({"family", "beta", "direction", "speed"})
NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_-]{0,63}")
EXAMPLE = '[plugins.paths] gerono = "mypkg.gerono:FAMILY"'


#: what a plug-in's code may raise that cdus catches and names: any Exception, and SystemExit (its
#: sys.exit() is its failure, not the process's end: `cdus sim` exited 0 with no word when a curve
#: called it). KeyboardInterrupt passes: it is Ctrl-C, whoever's code was running.
CAUGHT = (Exception, SystemExit)
#: a plug-in curve's f(ω) is a position (a scenario's bound, ±1,000 km); f' and f'' as a built-in
#: curve's can be at most (r β, r β² with β within ±MAX_RATE): beyond, the guidance's squares overflowed
POSITION = within(MAX_METRES)
DERIVATIVE = within(MAX_METRES * MAX_RATE ** 2)


class PluginFault(ValueError):
    """A plug-in's code raised, or gave a value a vehicle cannot use, while a vehicle ran (the
    tick protocol turns it into :class:`cdus.core.vehicle.DivergedError`, naming the vehicle)."""


@dataclass(frozen=True)
class Origin:
    """Where a plug-in came from: its kind (``paths`` | ``plants``), the name it registers, its
    ``module:object`` and the door (an entry point of a package, or the scenario's table)."""

    kind: str
    name: str
    ref: str
    door: str

    def __str__(self) -> str:
        return f"plug-in {WHAT[self.kind]} {quote(self.name)} ({self.door}: {self.ref})"


#: the plug-ins this process registered, by (kind, name)
LOADED: dict[tuple[str, str], Origin] = {}


def origin_of(kind: str, name: Any) -> Origin | None:
    """The plug-in that registered ``name`` (None: a built-in, or no such name)."""
    return LOADED.get((kind, name)) if isinstance(name, str) else None


@functools.cache
def entry_points() -> tuple[tuple[str, str, str, str], ...]:
    """(kind, name, module:object, door) of every installed plug-in, read once per process."""
    out: dict[tuple[str, str, str], str] = {}
    for kind, group in GROUPS.items():
        for ep in importlib.metadata.entry_points(group=group):
            dist = getattr(ep, "dist", None)
            package = f"package {dist.name} {dist.version}" if dist is not None else "an installed package"
            out.setdefault((kind, ep.name, ep.value), f'entry point {group} "{ep.name}" of {package}')
    return tuple((kind, name, ref, door) for (kind, name, ref), door in out.items())


def plugins_section(p: Problems, table: Any) -> None:
    """Load the installed plug-ins and those the scenario's ``[plugins]`` table names; each
    problem names the plug-in, where it came from and the fix."""
    wanted = [("plugins (installed)", kind, name, ref, door)
              for kind, name, ref, door in entry_points()]
    if table is not None:
        t = p.table(table, "plugins", EXAMPLE)
        p.unknown_keys(t or {}, GROUPS, "plugins", what="kind of plug-in", valid="[plugins] takes")
        for kind in GROUPS:
            if t is None or kind not in t:
                continue
            sub = p.table(t[kind], f"plugins.{kind}", f'{{ name = "module:object" }} ({EXAMPLE})') or {}
            for name, ref in sub.items():
                field = f"plugins.{kind}.{name}"
                if p.string(ref, field, nonempty=True, one_line=True) is not None:
                    wanted.append((field, kind, name, ref, f"[plugins.{kind}] of the scenario"))
    for field, kind, name, ref, door in wanted:
        problem = load(Origin(kind, name, ref, door))
        if problem is not None:
            p.add(field, problem)


def load_named(data: Mapping[str, Any], source: str) -> None:
    """Load in this process the plug-ins a scenario's data names (the installed ones and its
    ``[plugins]`` table), as reading it does: what a process handed a resolved Scenario instead
    of reading one (a sweep's worker, a fresh process) does before it builds the vehicles.
    Raises :class:`ConfigError` naming each that fails."""
    p = Problems()
    plugins_section(p, data.get("plugins"))
    if p:
        raise ConfigError(source, p.items)


def load(origin: Origin) -> str | None:
    """Import, check and register one plug-in (once per process); None, or what is wrong."""
    kind, name, ref = origin.kind, origin.name, origin.ref
    have = LOADED.get((kind, name))
    if have is not None:
        return None if have.ref == ref else (
            f"{origin} takes the name {quote(name)}, which {have} registered already; give one of them another name")
    fix = "fix the package, or uninstall it" if origin.door.startswith("entry point") else \
        "fix the module, or remove this line"
    if not NAME.fullmatch(name):
        return f"{origin}: {quote(name)} is not a name a scenario can give (letters, digits, _ and -); rename it"
    if name in (REGISTRY if kind == "paths" else PLANTS):
        return (f"{origin}: {quote(name)} is a built-in {WHAT[kind]} of cdus, which a plug-in cannot replace; give "
                f"the plug-in another name")
    module, sep, attr = (part.strip() for part in ref.partition(":"))
    if not sep or not module or not attr:
        return f"{origin}: {quote(ref)} is not module:object (e.g. mypkg.gerono:FAMILY); write it so"
    try:
        obj: Any = importlib.import_module(module)
        for part in attr.split("."):
            obj = getattr(obj, part)
    except CAUGHT as e:  # noqa: BLE001 (the plug-in's own code: anything)
        return f"{origin} cannot be loaded: {type(e).__name__}: {e}; {fix}"
    shape = family_problem(name, obj) if kind == "paths" else plant_problem(obj)
    if shape is not None:
        return f"{origin}: {shape}"
    if kind == "paths":
        register(dataclasses.replace(obj, build=_Build(obj.build, origin)))
    else:
        models.register_plant(name, guarded_model(obj, origin))
    LOADED[(kind, name)] = origin
    return None


def not_found_hint(kind: str) -> str:
    """What an unknown family or plant name adds after the known ones: where a plug-in of that
    name would have to be (its package in the Python that runs cdus, which is not always the
    one ``pip`` installed into: a virtual environment, a second Python), or the scenario's table."""
    return (f" (a plug-in's? install its package into the Python that runs cdus, {sys.executable}, or name it "
            f"in [plugins.{kind}]: docs/plugins.md)")


# --------------------------------------------------------------------------- shapes


def family_problem(name: str, obj: Any) -> str | None:
    """What keeps ``obj`` from being the path family ``name``, or None."""
    if not isinstance(obj, Family):
        return f"is a {type(obj).__name__}, not a cdus.core.paths.Family; point it at a Family"
    if obj.name != name:
        return f"its Family is named {quote(obj.name)}, not {quote(name)}; give both one name"
    if not callable(obj.build):
        return "its Family's build is not callable; give the function that makes the curve"
    taken = sorted({p.name for p in obj.params} & RESERVED_PARAMS)
    if taken:
        return (f"its parameter {quote(taken[0])} is a key every path table takes (family, beta, direction, "
                f"speed); rename it")
    kinds = {p.name: p.kind for p in obj.params}
    if obj.speed not in (None, "1") and kinds.get(obj.speed) != "positive":
        return f"its speed {obj.speed!r} must be None, \"1\" or the name of one of its positive parameters"
    return None


def plant_problem(obj: Any) -> str | None:
    """What keeps ``obj`` from being a plant model, or None."""
    if not isinstance(obj, PlantModel):
        return f"is a {type(obj).__name__}, not a cdus.core.models.PlantModel; point it at one"
    if not isinstance(obj.kinds, tuple) or not obj.kinds or not set(obj.kinds) <= set(KINDS):
        return f"its kinds {obj.kinds!r} must be a tuple of {' and/or '.join(map(quote, KINDS))}"
    if not callable(obj.build):
        return "its build is not callable; give the function that makes the plant from its parameters"
    if not isinstance(obj.regulators, Mapping):
        return f"its regulators must be a mapping name -> RegulatorModel, got {describe(obj.regulators)}"
    for rname, rm in obj.regulators.items():
        if not isinstance(rname, str) or not NAME.fullmatch(rname) or not isinstance(rm, RegulatorModel):
            return f"its regulator {rname!r} must be a name mapped to a cdus.core.models.RegulatorModel"
        if not (isinstance(rm.gains, type) and dataclasses.is_dataclass(rm.gains)):
            return f"the gains of its regulator {quote(rname)} must be a dataclass (its fields: regulator_gains)"
        try:
            defaults = rm.gains()
        except CAUGHT as e:  # noqa: BLE001
            return f"the gains of its regulator {quote(rname)} need a default for every field ({e})"
        bad = [f.name for f in dataclasses.fields(defaults) if not finite(getattr(defaults, f.name))]
        if bad:
            return f"the default of gain {quote(bad[0])} of its regulator {quote(rname)} is not a finite number"
    return None


# --------------------------------------------------------------------------- what runs


@dataclass(frozen=True)
class _Build:
    """A plug-in family's build: its own PathError passes (it names the parameter), anything
    else is said naming the plug-in; the curve it makes comes wrapped (:class:`PluginPath`)."""

    build: Any
    origin: Origin

    def __call__(self, **values: Any) -> "PluginPath":
        try:
            return PluginPath(self.build(**values), self.origin)
        except PathError:
            raise
        except CAUGHT as e:  # noqa: BLE001
            raise PathError("path", f"{self.origin}: building its curve raised {type(e).__name__}: {e}") from e


class PluginPath:
    """A plug-in family's curve: its ``dim``, ``period``, ``direction`` (and an open curve's
    ``span``) read and checked once; its ``eval`` raising becomes :class:`PluginFault` naming it."""

    __slots__ = ("inner", "origin", "dim", "period", "direction", "span")

    def __init__(self, inner: Any, origin: Origin):
        self.inner, self.origin = inner, origin
        try:
            dim, period, direction = inner.dim, inner.period, inner.direction
            self.span = getattr(inner, "span", None)
        except CAUGHT as e:  # noqa: BLE001
            raise PathError("path", f"{origin}: its curve lacks dim, period or direction ({e}); "
                                    f"give the attributes of cdus.core.paths.Path") from e
        if dim not in (2, 3) or isinstance(dim, bool):
            raise PathError("path", f"{origin}: its curve's dim is {dim!r}, not 2 or 3")
        if period is not None and not (finite(period) and period > 0):
            raise PathError("path", f"{origin}: its curve's period is {period!r}, not None (open) or a "
                                    f"finite number > 0")
        if direction not in (-1.0, 1.0) or isinstance(direction, bool):
            raise PathError("path", f"{origin}: its curve's direction is {direction!r}, not the -1 or +1 "
                                    f"its build was given")
        self.dim, self.period, self.direction = dim, period, direction

    def eval(self, w: float) -> tuple[Vec, Vec, Vec]:
        """Its (f, f', f'') at ``w``, checked as the probe checks them (:func:`values_problem`):
        what its code raises or a value a vehicle cannot use is :class:`PluginFault` naming it."""
        try:
            values = self.inner.eval(w)
        except CAUGHT as e:  # noqa: BLE001
            raise PluginFault(f"{self.origin}: f(ω) at ω = {w:g} raised {type(e).__name__}: {e}") from e
        if (why := values_problem(values, self.dim, w)) is not None:
            raise PluginFault(f"{self.origin}: {why}")
        return values


#: the ω at which a plug-in's curve is probed with a scenario's parameters: its values and their
#: shape, a tangent that does not vanish, and f', f'' against central differences of f and f'
PROBE_OMEGAS = (0.0, 0.37, 1.0, 2.2, -1.3, 4.0, 100.0, -1000.0)
DIFF_STEP = 1e-5  # of ω, for the central differences
DIFF_TOL = 1e-3  # relative to max(|f'|, |f''|, 1): a wrong sign, a missing β or a swapped axis is far beyond


def values_problem(values: Any, dim: int, w: float) -> str | None:
    """What a vehicle cannot use in a curve's (f, f', f'') at ``w``: not three tuples of ``dim``
    numbers, a value not finite, f beyond ±1,000 km or f', f'' beyond :data:`DERIVATIVE`; or None."""
    wrong = returned_problem(values, ("f", "f'", "f''"), dim)
    if wrong is not None:
        return f"its eval(ω) must return (f, f', f''), three tuples of {dim} numbers; at ω = {w:g} {wrong}"
    if not all(finite(x) for v in values for x in v):
        return f"its values are not finite numbers at ω = {w:g}: a vehicle cannot follow it"
    if not all(POSITION.holds(x) for x in values[0]) or not all(DERIVATIVE.holds(x) for v in values[1:] for x in v):
        return (f"its values at ω = {w:g} are beyond what a vehicle can follow (f within ±{MAX_METRES:g} m, "
                f"f' and f'' within ±{DERIVATIVE.hi:g}): {_vec(values[0])}, {_vec(values[1])}, {_vec(values[2])}")
    return None


def path_problem(path: Path, dim: int) -> str | None:
    """What a vehicle of ``dim`` axes cannot follow in a plug-in's curve (built with a scenario's
    parameters), probed at :data:`PROBE_OMEGAS`, or None. Never raises."""
    origin = plugin_of(path).origin
    try:
        for w in PROBE_OMEGAS:
            values = path.eval(w)
            if (why := values_problem(values, dim, w)) is not None:
                return f"{origin}: {why}"
            f, f1, f2 = values
            scale = max(1.0, *map(abs, f1), *map(abs, f2))
            if math.sqrt(sum(x * x for x in f1)) <= 1e-9 * scale:
                return (f"{origin}: its tangent f'(ω) vanishes at ω = {w:g} (the guidance needs |f'| > 0 "
                        f"everywhere)")
            h = DIFF_STEP * max(1.0, abs(w))
            (fa, f1a, _), (fb, f1b, _) = path.eval(w - h), path.eval(w + h)
            for which, of, got, lo, hi in (("f'", "f", f1, fa, fb), ("f''", "f'", f2, f1a, f1b)):
                diff = [(b - a) / (2 * h) for a, b in zip(lo, hi)]
                err = max(abs(x - y) for x, y in zip(got, diff))
                if not err <= DIFF_TOL * scale * max(1.0, abs(w) / 10):
                    return (f"{origin}: its {which} at ω = {w:g} is {_vec(got)}, but the central difference "
                            f"of {of} gives {_vec(diff)}: give the derivative of the curve")
    except PluginFault as e:
        return str(e)
    except CAUGHT as e:  # noqa: BLE001
        return f"{origin}: probing its curve raised {type(e).__name__}: {e}"
    return None


def returned_problem(values: Any, labels: tuple[str, ...], dim: int) -> str | None:
    """What keeps ``values`` from being ``len(labels)`` tuples of ``dim`` numbers (a curve's
    (f, f', f''), a plant's velocity), said so that the fix shows (a numpy array: make it a
    tuple), or None. Finite values are checked after."""
    if len(labels) > 1:
        if not isinstance(values, tuple) or len(values) != len(labels):
            got = f"{len(values)} values" if isinstance(values, (tuple, list)) else _typename(values)
            return f"it returned {got}, not the {len(labels)} of ({', '.join(labels)}): {str(values)[:80]}"
    else:
        values = (values,)
    for label, v in zip(labels, values):
        try:
            n = len(v)
        except TypeError:
            return f"its {label} is {_typename(v)} {str(v)[:60]}, not a tuple of {dim} numbers"
        if n != dim:
            return f"its {label} has {n} values, not {dim}: {str(v)[:80]}"
        if not isinstance(v, tuple):
            return (f"its {label} is {_typename(v)} {str(v)[:60]}, not a tuple (make it one: "
                    f"tuple(float(x) for x in ...))")
    return None


def _typename(v: Any) -> str:
    """``a list``, ``a numpy.ndarray``: the type of a value a plug-in gave, as its author knows it."""
    t = type(v)
    name = t.__qualname__ if t.__module__ == "builtins" else f"{t.__module__}.{t.__qualname__}"
    return f"{'an' if name[0] in 'aeiou' else 'a'} {name}"


def plugin_of(path: Any) -> PluginPath | None:
    """The plug-in curve ``path`` is or holds (a 3-D one as a boat follows it: cdus.core.paths.Planar), or None."""
    while not isinstance(path, PluginPath) and hasattr(path, "inner"):
        path = path.inner
    return path if isinstance(path, PluginPath) else None


def _vec(v: Iterable[float]) -> str:
    return "(" + ", ".join(f"{x:.6g}" for x in v) + ")"


def guarded_model(model: PlantModel, origin: Origin) -> PlantModel:
    """``model`` with its plant and regulators wrapped to name ``origin`` when they fail."""
    def build(params: Mapping[str, Any]) -> PluginPlant:
        return PluginPlant(model.build(params), origin)

    regulators = {name: RegulatorModel(rm.gains, _RegulatorBuild(rm.build, origin, name))
                  for name, rm in model.regulators.items()}
    return PlantModel(model.kinds, build, regulators)


@dataclass(frozen=True)
class _RegulatorBuild:
    build: Any
    origin: Origin
    name: str

    def __call__(self, plant: Any, gains: Any) -> "PluginRegulator":
        inner = plant.inner if isinstance(plant, PluginPlant) else plant
        return PluginRegulator(self.build(inner, gains), self.origin, self.name)


def _fault(origin: Origin, what: str, e: Exception) -> PluginFault:
    return PluginFault(f"{origin}: {what} raised {type(e).__name__}: {e}")


@dataclass
class PluginPlant:
    """A plug-in's plant (cdus.core.plants.Plant): what its code raises, and a state that is no
    longer finite after its step, become :class:`PluginFault` naming it."""

    inner: Any
    origin: Origin

    def __post_init__(self) -> None:
        self.name = self.origin.name
        self.velocity_level = bool(getattr(self.inner, "velocity_level", False))
        self.exact_when_held = bool(getattr(self.inner, "exact_when_held", False))

    def start(self, q: Vec, heading: float) -> Any:
        try:
            return self.inner.start(q, heading)
        except CAUGHT as e:  # noqa: BLE001
            raise _fault(self.origin, "start", e) from e

    def at_rest(self, state: Any, q: Vec, heading: float | None) -> Any:
        try:
            return self.inner.at_rest(state, q, heading)
        except CAUGHT as e:  # noqa: BLE001
            raise _fault(self.origin, "at_rest", e) from e

    def step(self, state: Any, u: Vec, d: Vec, h: float) -> Any:
        try:
            out = self.inner.step(state, u, d, h)
            ok = self.inner.finite(out) and all(math.isfinite(x) for x in out.q)
            shaped = isinstance(out.q, tuple) and len(out.q) == len(state.q)
            near = ok and all(POSITION.holds(x) for x in out.q)
        except CAUGHT as e:  # noqa: BLE001
            raise _fault(self.origin, "step", e) from e
        if not ok:
            raise PluginFault(f"{self.origin}: its state is no longer finite after a step of {h:g} s with the "
                              f"input {_vec(u)}: {out}")
        if not shaped or not near:
            what = f"not a tuple of {len(state.q)} numbers" if not shaped else f"beyond ±{MAX_METRES:g} m"
            raise PluginFault(f"{self.origin}: after a step of {h:g} s its state's q is {what}: {str(out.q)[:80]}")
        return out

    def velocity(self, state: Any) -> Vec:
        try:
            return self.inner.velocity(state)
        except CAUGHT as e:  # noqa: BLE001
            raise _fault(self.origin, "velocity", e) from e

    def heading(self, state: Any) -> float:
        try:
            return self.inner.heading(state)
        except CAUGHT as e:  # noqa: BLE001
            raise _fault(self.origin, "heading", e) from e

    def finite(self, state: Any) -> bool:
        try:
            return bool(self.inner.finite(state))
        except CAUGHT as e:  # noqa: BLE001
            raise _fault(self.origin, "finite", e) from e

    def point(self, state: Any, d: Vec, limits: Any) -> Any:
        try:
            return self.inner.point(state, d, limits)
        except CAUGHT as e:  # noqa: BLE001
            raise _fault(self.origin, "point (its model for the safety filter)", e) from e


@dataclass
class PluginRegulator:
    """A plug-in's regulator (cdus.core.regulators.Regulator): what its code raises becomes
    :class:`PluginFault` naming it."""

    inner: Any
    origin: Origin
    name: str

    def command(self, state, path, w, wdot, k, limits, d_hat, shift, h) -> Vec:
        try:
            return self.inner.command(state, path, w, wdot, k, limits, d_hat, shift, h)
        except CAUGHT as e:  # noqa: BLE001
            raise _fault(self.origin, f"its regulator {quote(self.name)}", e) from e


# --------------------------------------------------------------------------- the plants probed


def probe_plants(p: Problems, specs: Iterable[Any], paths: Mapping[str, Path], physics_hz: float, control_hz: float,
                 safety_on: bool) -> None:
    """Each vehicle whose plant is a plug-in: its plant and regulator built with the vehicle's
    parameters, started on its path and stepped over one control period at the physics rate;
    what fails is a problem of ``vehicle[i].plant`` naming the plug-in."""
    for spec in specs:
        if spec is None or origin_of("plants", spec.plant) is None or spec.id not in paths:
            continue
        field = f"vehicle[{spec.index}] (id {quote(spec.id)}).plant"
        problem = _plant_run_problem(spec, paths[spec.id], physics_hz, control_hz, safety_on)
        if problem is not None:
            p.add(field, problem)


#: what every plant object has (cdus.core.plants.Plant): its methods, and its two flags
PLANT_METHODS = ("start", "at_rest", "step", "velocity", "heading", "finite")
PLANT_FLAGS = ("velocity_level", "exact_when_held")


def plant_object_problem(plant: Any, regulated: bool, safety_on: bool = False) -> str | None:
    """What keeps the object a plug-in's ``build`` made from being a plant (a method or a flag
    missing; ``velocity_level`` saying the opposite of whether its model has regulators; with
    ``[safety]`` on, a regulated plant without ``point``), or None."""
    kind = _typename(plant)
    missing = [m for m in PLANT_METHODS if not callable(getattr(plant, m, None))]
    if missing:
        return (f"its plant ({kind}) has no method {', '.join(missing)}; give it every method of "
                f"cdus.core.plants.Plant ({', '.join(PLANT_METHODS)})")
    for flag in PLANT_FLAGS:
        if not isinstance(getattr(plant, flag, None), bool):
            return f"its plant ({kind}) has no {flag} = True or False; give it one (docs/plugins.md)"
    if plant.velocity_level == regulated:
        return (f"its plant ({kind}) has velocity_level = True, but its PlantModel has regulators too: a "
                f"velocity-level plant takes the guidance's velocity itself; drop its regulators, or set "
                f"velocity_level = False" if regulated else
                f"its plant ({kind}) has velocity_level = False, but its PlantModel has no regulator to turn the "
                f"guidance's velocity into its input; set velocity_level = True (it takes the velocity itself), "
                f"or give the PlantModel a regulator")
    if safety_on and regulated and not callable(getattr(plant, "point", None)):
        return (f"its plant ({kind}) has no point(state, d, limits), which [safety] needs of a plant with a "
                f"regulator (the dynamic safety filter's model of it, a cdus.core.safety.Point: docs/safety.md, "
                f"docs/plugins.md); give it one, or run this fleet without [safety]")
    return None


def _plant_run_problem(spec: Any, path: Path, physics_hz: float, control_hz: float, safety_on: bool) -> str | None:
    origin = origin_of("plants", spec.plant)
    if spec.observer is not None:
        return (f"{origin}: the disturbance observer knows the velocity of the built-in plants only "
                f"(cdus.core.observer.known_velocity); remove [observer] for this vehicle")
    try:
        plant, regulator = models.build(spec.plant, spec.regulator, {"epsilon": spec.epsilon, "preset": spec.preset},
                                        dict(spec.regulator_gains))
        wrong = plant_object_problem(plant.inner, regulator is not None, safety_on)
        if wrong is not None:
            return f"{origin}: {wrong}"
        w = spec.phase if spec.omega0 is None else spec.omega0
        f, f1, _ = path.eval(w)
        q = tuple(spec.start_position) if spec.start_position is not None else f
        heading = spec.start_heading if spec.start_heading is not None else math.atan2(f1[1], f1[0])
        state = plant.start(q, heading)
        if not (isinstance(getattr(state, "q", None), tuple) and len(state.q) == spec.dim):
            return f"{origin}: its state's q must be a tuple of {spec.dim} numbers (a {spec.kind}'s position)"
        limits = Limits(**dict(spec.limits))
        steps = max(1, math.ceil(physics_hz / control_hz - 1e-9))
        h = 1.0 / (control_hz * steps)
        zero = (0.0,) * spec.dim
        for _ in range(steps):
            u = desired_velocity(path, state.q, w, spec.k) if regulator is None else \
                regulator.command(state, path, w, 0.0, spec.k, limits, None, None, h)
            state = plant.step(state, tuple(u), zero, h)
        v, psi = plant.velocity(state), plant.heading(state)
        wrong = returned_problem(v, ("velocity",), spec.dim)
        if wrong is not None:
            return f"{origin}: {wrong}"
        if not (all(map(finite, v)) and finite(psi)):
            return f"{origin}: its velocity must be {spec.dim} finite numbers and its heading one, got {v!r}, {psi!r}"
        if safety_on and not plant.velocity_level:
            plant.point(state, zero, limits)
    except PluginFault as e:
        return f"{e} (probed with this vehicle's parameters, before anything started)"
    except CAUGHT as e:  # noqa: BLE001
        return f"{origin}: probing it with this vehicle's parameters raised {type(e).__name__}: {e}"
    return None
