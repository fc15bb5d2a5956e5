"""What is a validated scenario? The frozen, typed result of reading a scenario file.

:func:`cdus.scenario.config.load_scenario` builds a :class:`Scenario` (docs/config.md is
the user reference); every runner takes it as it is: the link spec and the events in it
are already validated, so nothing downstream checks them again.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from cdus.core.events import Event
from cdus.core.formation import FormationChange, PathChange, base_phases
from cdus.core.linkspec import LinkSpec
from cdus.core.proximity import sample_every
from cdus.core.radio import RadioSpec
from cdus.core.radiolink import RadioEvent
from cdus.scenario.robot import RobotSpec
from cdus.scenario.ros2 import Ros2Spec

#: What the launcher does when a vehicle's process exits during the run (docs/config.md, [supervision]).
RESTART_POLICIES = ("never", "on-failure", "always")
DEFAULT_RESTART = "never"
DEFAULT_MAX_RESTARTS = 5
DEFAULT_BACKOFF_S = 0.5
MAX_BACKOFF_S = 30.0


@dataclass(frozen=True)
class Rates:
    physics: float  # Hz
    control: float
    broadcast: float


@dataclass(frozen=True)
class Edge:
    """i listens to k with weight a_ik; the coordination error of this edge is |ω_i - ω_k - delta|."""

    i: str
    k: str
    weight: float
    delta: float


@dataclass(frozen=True)
class VehicleSpec:
    id: str
    index: int  # position in Scenario.vehicles
    kind: str  # usv | uav
    dim: int  # 2 | 3
    plant: str  # ideal | usv_3dof | uav_double_integrator
    epsilon: tuple[float, ...] | None  # ε1..ε7 for usv_3dof, else None
    preset: str | None  # the preset ε came from, None if given as epsilon or not usv_3dof
    regulator: str | None  # None for the ideal plant
    regulator_gains: tuple[tuple[str, float], ...]  # sorted; empty = the regulator's defaults
    path: tuple[tuple[str, Any], ...]  # sorted pairs, lists as tuples: make_path(dict(v.path))
    phase: float  # θ_i, ω units
    start_position: tuple[float, ...] | None  # None = start on the path
    start_heading: float | None  # None = along the path (always None for a UAV)
    omega0: float | None  # None = the ω of the path point nearest the start
    k: tuple[float, ...]  # per-axis path gain, length dim
    c: float  # coordination gain
    limits: tuple[tuple[str, float], ...]
    disturbance: tuple[tuple[str, Any], ...]
    observer: float | None = None  # the disturbance observer's bandwidth (rad/s), None: no observer
    scale_omega: bool = False  # [guidance] scale_omega: σ also scales ω's path-following part
    robot: RobotSpec | None = None  # plant = "ros2": its topics and timeout (cdus.scenario.robot)


#: [safety] defaults (docs/config.md, docs/safety.md)
DEFAULT_SAFETY = {"enabled": False, "radius": 2.0, "gamma": 1.0, "range": 20.0, "rate": 10.0, "latency": 0.0,
                  "cross_domain": True, "sidestep": 0.3}


@dataclass(frozen=True)
class Safety:
    """The ``[safety]`` table: the collision-avoidance filter and the proximity sensor.

    ``radius`` R (m) and ``gamma`` γ (1/s) of ḣ ≥ -γ h, h = |q_i - q_k|² - R²; the sensor
    sees ``range`` m at ``rate`` Hz and its contacts are used ``latency`` s later (at least
    one control tick: :meth:`latency_ticks`); ``cross_domain``: a UAV also avoids boats.
    """

    enabled: bool = DEFAULT_SAFETY["enabled"]
    radius: float = DEFAULT_SAFETY["radius"]
    gamma: float = DEFAULT_SAFETY["gamma"]
    range: float = DEFAULT_SAFETY["range"]
    rate: float = DEFAULT_SAFETY["rate"]
    latency: float = DEFAULT_SAFETY["latency"]
    cross_domain: bool = DEFAULT_SAFETY["cross_domain"]
    sidestep: float = DEFAULT_SAFETY["sidestep"]

    def every(self, control_rate: float) -> int:
        """Control ticks between two sensor samples: round(control / rate), at least 1."""
        return sample_every(self.rate, control_rate)

    def latency_ticks(self, control_rate: float) -> int:
        """Control ticks from a sample to its first use: ceil(latency · control), at least 1."""
        return max(1, math.ceil(self.latency * control_rate - 1e-9))


@dataclass(frozen=True)
class Supervision:
    """The ``[supervision]`` table: what the launcher does when a vehicle's process exits.

    ``restart``: never | on-failure (a non-zero exit or a signal) | always. A vehicle is
    restarted at most ``max_restarts`` times by this policy; the wait before its n-th
    restart is ``backoff(n - 1)``: ``backoff_s``, doubling with each restart of that
    vehicle, capped at ``MAX_BACKOFF_S``.
    """

    restart: str = DEFAULT_RESTART
    max_restarts: int = DEFAULT_MAX_RESTARTS
    backoff_s: float = DEFAULT_BACKOFF_S

    def backoff(self, restarts_done: int) -> float:
        """Seconds to wait before restarting a vehicle already restarted ``restarts_done`` times."""
        return min(self.backoff_s * 2.0 ** max(0, restarts_done), MAX_BACKOFF_S)


@dataclass(frozen=True)
class Scenario:
    name: str
    description: str
    source: str
    duration: float
    seed: int
    rates: Rates
    path_tol: float
    coord_tol: float
    topology: str
    directed: bool
    vehicles: tuple[VehicleSpec, ...]
    edges: tuple[Edge, ...]  # every listening pair; undirected gives (i, k) and (k, i), Δ_ki = -Δ_ik
    link: LinkSpec  # the validated [link] table; the table as written is raw.get("link", {})
    events: tuple[Event, ...]  # sorted by time; a pause with a duration is followed by its resume
    supervision: Supervision
    raw: dict  # the overridden TOML data; parse_scenario(raw) rebuilds this scenario
    safety: Safety = Safety()  # the [safety] table
    radio: RadioSpec | None = None  # the validated [radio] table; None: absent, no radio channel
    #: the [[event]]s that change the formation or a vehicle's path, sorted by time (the file's
    #: order at the same time); a formation's phases are resolved (offsets turned into phases)
    changes: tuple[FormationChange | PathChange, ...] = ()

    @property
    def phases(self) -> tuple[float, ...]:
        """The phases in force at the start, per vehicle (cdus.core.formation.base_phases): the
        vehicles' ``phase``, or phases solved from the graph's deltas if it gives any."""
        return base_phases(self.ids, {v.id: v.phase for v in self.vehicles}, self.edges)
    radio_events: tuple[RadioEvent, ...] = ()  # [[event]] action = "radio": scheduled changes, by time
    ros2: Ros2Spec = Ros2Spec()  # the [ros2] table: the fleet as ROS 2 topics (docs/ros2.md), off by default
    obstacles: tuple = ()  # the [[obstacle]]s (cdus.core.obstacles shapes, cdus.scenario.obstacles)

    def vehicle(self, vid: str) -> VehicleSpec:
        for v in self.vehicles:
            if v.id == vid:
                return v
        raise KeyError(f"no vehicle {vid!r} in scenario {self.name!r}; ids are {', '.join(self.ids)}")

    @property
    def ids(self) -> tuple[str, ...]:
        return tuple(v.id for v in self.vehicles)

    def gain_context(self, vid: str) -> dict:
        """What bounds vehicle ``vid``'s guidance gains (cdus.core.gain_bounds): its rates, its
        plant and the sum of the weights of the edges it listens on."""
        return {"control_hz": self.rates.control, "plant": self.vehicle(vid).plant,
                "physics_hz": self.rates.physics, "weight_sum": sum(e.weight for e in self.edges if e.i == vid)}

    @property
    def link_table(self) -> dict:
        """The ``[link]`` table as written (run-time link commands merge over it)."""
        return dict(self.raw.get("link") or {})

    @property
    def link_seed(self) -> int:
        """``link.seed`` if given, else the scenario's seed."""
        return self.link.seed if self.link.seed is not None else self.seed

    @property
    def radio_seed(self) -> int:
        """``radio.seed`` if given, else the link seed (``link.seed``, else the scenario's)."""
        return self.radio.seed if self.radio is not None and self.radio.seed is not None else self.link_seed

    def neighbours(self, vid: str) -> tuple[Edge, ...]:
        """The edges vehicle ``vid`` listens on (e.i == vid)."""
        return tuple(e for e in self.edges if e.i == vid)

    def metric_edges(self) -> tuple[Edge, ...]:
        """Edges to measure coordination on: undirected, each pair once as index(i) < index(k)."""
        if self.directed:
            return self.edges
        index = {v.id: v.index for v in self.vehicles}
        return tuple(e for e in self.edges if index[e.i] < index[e.k])
