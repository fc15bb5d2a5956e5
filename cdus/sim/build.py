"""How are a scenario's pieces built? Its vehicles, neighbour terms, metric edges and link model.

The one place where the validated :class:`cdus.scenario.model.Scenario` is turned into
the pure core's objects, used alike by the in-process fleet and the process shells. The
scenario is taken as validated: nothing here checks it again.
"""

from __future__ import annotations

import math

from cdus.core import models
from cdus.core import regulators as reg
from cdus.core.events import event_tick
from cdus.core.formation import FormationChange, FormationSchedule, PathChange
from cdus.core.disturbance import Disturbance, DisturbanceSpec
from cdus.core.link import IdealLink, LinkEmulator, LinkModel
from cdus.core.graph import MetricEdge
from cdus.core.neighbours import NeighbourLink
from cdus.core.radio import RadioChannel
from cdus.core.radiolink import RadioLink
from cdus.core.node import VehicleNode
from cdus.core.schedule import broadcast_every, total_ticks
from cdus.core.paths import for_dimension, nearest_omega
from cdus.scenario.paths import make_path
from cdus.core.obstacles import seen_by
from cdus.core.safety import SafetyParams
from cdus.core.vehicle import Vehicle
from cdus.scenario.model import Rates, Safety, Scenario, VehicleSpec


def safety_params(safety: Safety, limits: reg.Limits, obstacles: tuple = ()) -> SafetyParams | None:
    """The filter's parameters from the [safety] table (None when it is off); the vehicle's
    speed limit bounds the filtered velocity too; ``obstacles``: the [[obstacle]]s it avoids."""
    if not safety.enabled:
        return None
    return SafetyParams(radius=safety.radius, gamma=safety.gamma, speed=limits.speed, sidestep=safety.sidestep,
                        obstacles=obstacles)


def start_point(spec: VehicleSpec, path=None) -> tuple[tuple[float, ...], float, tuple[float, ...]]:
    """Where a vehicle starts: its position q0, its ω0 and the path's tangent f'(ω0) there (its
    ``start`` position, or the path's point at ω0 = its ``omega0``, else its phase)."""
    path = path if path is not None else for_dimension(make_path(dict(spec.path)), spec.dim)
    if spec.start_position is None:
        w0 = spec.phase if spec.omega0 is None else spec.omega0
        q0, f1, _ = path.eval(w0)
        return q0, w0, f1
    q0 = tuple(float(x) for x in spec.start_position)
    if spec.omega0 is None:
        hint = spec.phase - (path.period / 2.0 if path.period else 0.0)
        w0 = nearest_omega(path, q0, hint)
    else:
        w0 = spec.omega0
    _, f1, _ = path.eval(w0)
    return q0, w0, f1


def build_vehicle(spec: VehicleSpec, rates: Rates, seed: int, safety: Safety | None = None,
                  obstacles: tuple = ()) -> Vehicle:
    """A vehicle's core object from its validated spec, the scenario's rates, [safety] and the
    [[obstacle]]s (those of its medium: cdus.core.obstacles.seen_by)."""
    path = for_dimension(make_path(dict(spec.path)), spec.dim)
    dim = spec.dim
    period = 1.0 / rates.control
    steps = max(1, math.ceil(rates.physics / rates.control - 1e-9))
    limits = reg.Limits(**dict(spec.limits))
    q0, w0, f1 = start_point(spec, path)
    s = path.direction
    heading = spec.start_heading if spec.start_heading is not None else math.atan2(s * f1[1], s * f1[0])
    zero = (0.0,) * dim
    plant, regulator = models.build(spec.plant, spec.regulator, {"epsilon": spec.epsilon, "preset": spec.preset},
                                    dict(spec.regulator_gains))
    state = plant.start(q0, heading)
    dist = None
    if spec.disturbance:
        d = dict(spec.disturbance)
        dist = Disturbance(
            DisturbanceSpec(tuple(d.get("constant", zero)), float(d.get("gust", 0.0)),
                            float(d.get("gust_tau", 2.0))),
            dim, seed, spec.id)
    return Vehicle(id=spec.id, kind=spec.kind, dim=dim, path=path, k=tuple(spec.k), c=spec.c,
                   plant=plant, regulator=regulator, control_period=period,
                   physics_steps=steps, state=state, omega=float(w0),
                   limits=limits, disturbance=dist, safety=safety_params(safety or Safety(), limits, seen_by(spec.kind, obstacles)),
                   observer=spec.observer, scale_omega=spec.scale_omega)


def links_of(scenario: Scenario, vid: str) -> tuple[NeighbourLink, ...]:
    """Vehicle ``vid``'s terms: whom it listens to, a_ik, Δ_ik."""
    index = {v.id: v.index for v in scenario.vehicles}
    return tuple(NeighbourLink(index[e.k], e.weight, e.delta) for e in scenario.neighbours(vid))


def listeners_of(scenario: Scenario, vid: str) -> tuple[str, ...]:
    """The vehicles that listen to ``vid`` (its ω goes to them), in scenario order."""
    listening = {e.i for e in scenario.edges if e.k == vid}
    return tuple(v for v in scenario.ids if v in listening)


def metric_edges(scenario: Scenario) -> tuple[MetricEdge, ...]:
    """The edges coordination is measured on, named ``<id_i>__<id_k>`` (also in Rerun)."""
    index = {v.id: v.index for v in scenario.vehicles}
    return tuple(MetricEdge(index[e.i], index[e.k], e.delta, f"{e.i}__{e.k}") for e in scenario.metric_edges())


def build_node(scenario: Scenario, vid: str, link: LinkModel, *, policy: str | None = None,
               timeout: float | None = None, last_tick: int | None = None, joined_at: int = 0) -> VehicleNode:
    """Vehicle ``vid``'s tick protocol: its vehicle, its neighbour terms and ``link`` (the model
    deciding its incoming messages), at the scenario's rates; policy and timeout default to
    the scenario's [link] table, the last tick to the scenario's duration."""
    spec = scenario.vehicle(vid)
    period = 1.0 / scenario.rates.control
    link_spec = scenario.link
    sensing = sensor_schedule(scenario)
    node = VehicleNode(spec.index, build_vehicle(spec, scenario.rates, scenario.seed, scenario.safety, scenario.obstacles),
                       links_of(scenario, vid), link,
                       period=period, every=broadcast_every(scenario.rates),
                       last_tick=total_ticks(scenario.duration, period) if last_tick is None else last_tick,
                       policy=policy or link_spec.policy, timeout=link_spec.timeout if timeout is None else timeout,
                       joined_at=joined_at, sense_every=sensing[0] if sensing else None,
                       sense_latency=sensing[1] if sensing else 1)
    node.formation = formation_schedule(scenario)
    for change in scenario.changes:
        if isinstance(change, PathChange) and change.vehicle == vid:
            node.set_path(path_of(change.path, spec.dim), event_tick(change.at, period))
    return node


def formation_schedule(scenario: Scenario) -> FormationSchedule:
    """The fleet's phases over ticks as the scenario schedules them: the phases in force at the
    start and each ``formation`` event from its tick (cdus.core.formation). Every runner (each
    node, the metrics recorder) starts from this and adds the ground stations' changes in the
    order the world relays them."""
    schedule = FormationSchedule(scenario.phases)
    period = 1.0 / scenario.rates.control
    index = {v.id: v.index for v in scenario.vehicles}
    for change in scenario.changes:
        if isinstance(change, FormationChange):
            schedule.add(event_tick(change.at, period), {index[vid]: theta for vid, theta in change.phases})
    return schedule


def path_of(table, dim: int):
    """A validated path table (a dict or its sorted pairs) as a vehicle of ``dim`` axes follows it."""
    return for_dimension(make_path(dict(table)), dim)


def sensor_schedule(scenario: Scenario) -> tuple[int, int] | None:
    """(ticks between proximity samples, ticks from a sample to its use) when the safety
    filter is on, else None (no sensor: nothing is sampled, sent or waited for)."""
    sf = scenario.safety
    if not sf.enabled:
        return None
    control = scenario.rates.control
    return sf.every(control), sf.latency_ticks(control)


def link_model_for(scenario: Scenario) -> LinkModel:
    """:class:`IdealLink` when the ``[link]`` table has no faults, else a :class:`LinkEmulator`
    (seeded with ``link.seed``, else ``scenario.seed``); with ``[radio]``, either under the
    radio channel (:func:`with_radio`)."""
    inner: LinkModel = IdealLink() if scenario.link.is_ideal else link_emulator_for(scenario)
    return with_radio(scenario, inner)


def with_radio(scenario: Scenario, inner: LinkModel) -> LinkModel:
    """``inner`` as it is without ``[radio]``; with it, a RadioLink: the hand-set faults of
    ``inner`` first, then the radio channel (cdus.core.radiolink)."""
    schedule = radio_schedule(scenario)
    if schedule is None:
        return inner
    return RadioLink(inner, radio_channel_for(scenario), period=1.0 / scenario.rates.control,
                     every=schedule[0], lag=schedule[1])


def radio_schedule(scenario: Scenario) -> tuple[int, int] | None:
    """(ticks between radio geometry samples, ticks from a sample to the first send tick it is
    in force at) with ``[radio]``, else None (nothing is sampled, sent or waited for). The lag
    is one sample period: the sample of tick k is in force from k + every, so a lockstep
    vehicle never waits for the world on the tick at hand and the grants keep a window."""
    spec = getattr(scenario, "radio", None)
    if spec is None:
        return None
    every = max(1, round(spec.sample_period * scenario.rates.control))
    return every, every


def radio_channel_for(scenario: Scenario) -> RadioChannel:
    """The scenario's radio channel (cdus.core.radio.RadioChannel), seeded with ``radio.seed``
    if it has one, else the link seed; every vehicle broadcasts ω at the scenario's rate; the
    scheduled radio events (``[[event]] action = "radio"``) are its epochs from the start."""
    period = 1.0 / scenario.rates.control
    channel = RadioChannel(scenario.radio, scenario.ids, [v.kind for v in scenario.vehicles], scenario.radio_seed,
                           rate=1.0 / (broadcast_every(scenario.rates) * period), tick_period=period)
    for ev in scenario.radio_events:  # scheduled changes: every runner knows them up front
        # one past the run's end (a shorter --duration) never applies; as an epoch it would refuse
        # every ground-station change of the run (epochs go in time order)
        if ev.at <= scenario.duration:
            channel.update(ev.at, tx_power_dbm=ev.tx_power, station=ev.station)
    return channel


def link_faults_of(link: LinkModel) -> LinkEmulator | None:
    """The link emulator inside ``link`` (under a radio channel or not), if any."""
    return link.faults


def link_emulator_for(scenario: Scenario) -> LinkEmulator:
    """Always an emulator (ideal links take its fast path), so faults can change at run time."""
    return LinkEmulator(scenario.link, scenario.ids, scenario.link_seed)
