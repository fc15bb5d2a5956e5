"""Who may say what on a fleet's keys: the roles of a secured fleet and the Zenoh
access-control list that enforces them on the router (docs/multihost.md, "A secured fleet").

Every process of a secured fleet authenticates to the router as one role (a Zenoh
user name, and with TLS the same name as its certificate's common name):

    world               publishes the clock, roster and relayed commands (to/<set>/ctl),
                        the proximity sensor's contacts (to/+<id>+/contacts),
                        fault requests to the launcher (to/+launcher+/cmd), its status
                        and events (world/status, world/events), the liveliness token
                        alive/world/<zid>; answers world/last/<id> queries and commands
                        (world/cmd/<from>)
    vehicle-<id>        publishes only its own keys: its ω to its listeners
                        (to/+<listeners>+/omega/<id>, the exact set of the scenario), its
                        telemetry and counters (to/+world+/state/<id>, stats/<id>), the
                        liveliness token alive/<id>/<zid>, and answers its link check
                        (to/+<id>+/ping)
    ground              a ground station: commands to the world, as queries the world
                        answers (world/cmd/gs) or as puts (to/+world+/cmd/gs, no answer)

A fleet with ``[ros2] enabled`` (docs/ros2.md) has two more, and only then:

    ros2                the ROS 2 bridge: reads the fleet as every member does; publishes
                        exactly its topics' data keys (<domain>/<topic>/<type>/<hash>), the
                        caches of its transient-local ones (<key>/@adv/**: queryable, token;
                        the cache's replies carry the data key), its ROS graph tokens
                        (@ros2_lv/<domain>/**) and alive/ros2
    ros2-client         a ROS 2 machine (rmw_zenoh with this role's config file): subscribes
                        to and queries those topics and their caches, watches and declares
                        ROS graph tokens in the domain; publishes no data at all, and reads
                        nothing of cdus/<fleet>/

A fleet with ``plant = "ros2"`` vehicles (docs/ros2.md, "A ROS 2 robot as one of the vehicles")
has one more per robot, and grants its vehicle a little more:

    vehicle-<id>        (a robot's) also subscribes to the robot's odometry key, publishes its
                        command key, and declares its own node's and command publisher's ROS
                        graph tokens (any session id); that ROS data reaches it and nothing else
    robot-<id>          the robot (rmw_zenoh with this role's config file): publishes its
                        odometry key, subscribes to its command key, declares and watches ROS
                        graph tokens in the domain; nothing of cdus/<fleet>/

Every role may subscribe to and query anything under ``cdus/<fleet>/`` except the world's
command queryable (``world/cmd/**``), which only the ground role may query (a deny rule for
every other role: Zenoh's deny wins over an allow); nothing else may be published or
declared there, or anywhere else (the list denies by default). The
launcher is the router itself, so it needs no role: Zenoh checks what crosses the
router's links, not what its own session does. Session-local keys (``to/+<id>+/wake``)
never reach the router.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping, Sequence

from cdus.wire import keys

WORLD_ROLE = "world"
GROUND_ROLE = "ground"
ROS2_ROLE = "ros2"  # the bridge (cdus.ros2.bridge); also its process's name and alive/<name> token
ROS2_CLIENT_ROLE = "ros2-client"

#: every message kind Zenoh's access control knows (checked against eclipse-zenoh 1.10)
MESSAGES = ("put", "delete", "declare_subscriber", "query", "reply", "declare_queryable",
            "liveliness_token", "liveliness_query", "declare_liveliness_subscriber")
#: what any member of the fleet may ask the router for: watching and querying
READ = ("declare_subscriber", "declare_liveliness_subscriber", "liveliness_query", "query")


def vehicle_role(vid: str) -> str:
    return f"vehicle-{vid}"


def robot_role(vid: str) -> str:
    return f"robot-{vid}"


@dataclass(frozen=True)
class Ros2Grant:
    """What the ROS 2 side of a fleet may use: its domain and the data keys of its topics
    (``cdus.ros2.rmw.topic_key`` of each; the caller computes them, this layer knows no ROS)."""

    domain: int
    topic_keys: tuple[str, ...]

    def graph(self) -> str:
        return f"@ros2_lv/{self.domain}/**"

    def caches(self) -> list[str]:
        return [f"{k}/@adv/**" for k in self.topic_keys]


@dataclass(frozen=True)
class RobotGrant:
    """What a ``plant = "ros2"`` vehicle and its robot may use (the caller computes the keys:
    ``cdus.ros2.fleet.robot_grants``): the robot's odometry and command data keys, the vehicle's
    own ROS graph tokens (its node's and its command publisher's, ``*`` for the session id), and
    the domain's graph (the robot's tokens)."""

    vehicle: str
    odom: str
    cmd: str
    tokens: tuple[str, ...]
    graph: str


def roles(vehicle_ids: list[str] | tuple[str, ...], ros2: bool = False, robots: Sequence[str] = ()) -> list[str]:
    """Every role of a fleet: the world, the ground station, one per vehicle (and the two ROS 2
    roles when the fleet publishes to ROS 2, one per robot of ``robots``)."""
    return [WORLD_ROLE, GROUND_ROLE, *(vehicle_role(v) for v in vehicle_ids),
            *((ROS2_ROLE, ROS2_CLIENT_ROLE) if ros2 else ()), *(robot_role(v) for v in robots)]


def _rule(rule_id: str, messages: tuple[str, ...], key_exprs: list[str], flow: str = "ingress") -> dict:
    return {"id": rule_id, "permission": "allow", "flows": [flow], "messages": list(messages),
            "key_exprs": key_exprs}


def fleet_acl(fleet: str, listeners: Mapping[str, Sequence[str]], match_certificates: bool = False,
              ros2: Ros2Grant | None = None, robots: Sequence[RobotGrant] = ()) -> dict:
    """The ``access_control`` section of the router's Zenoh config for ``fleet``, whose
    vehicles are the keys of ``listeners`` (vehicle id -> the ids its ω is addressed to).

    A subject is a user name; with ``match_certificates`` it must also present a TLS
    certificate with that common name (Zenoh ANDs the two lists of a subject).
    """
    f = keys.check_fleet(fleet)
    everything = f"{keys.prefix(f)}/**"
    subjects, rules, policies = [], [], []

    def subject(role: str) -> str:
        s = {"id": role, "usernames": [role]}
        if match_certificates:
            s["cert_common_names"] = [role]
        subjects.append(s)
        return role

    members = [subject(r) for r in roles(list(listeners)) + ([ROS2_ROLE] if ros2 else [])]
    rules += [_rule("fleet-out", MESSAGES, [everything], flow="egress"),
              _rule("fleet-read", READ, [everything])]
    policies.append({"id": "members", "rules": ["fleet-out", "fleet-read"], "subjects": members})

    rules += [
        _rule("world-put", ("put",), [f"{keys.prefix(f)}/to/*/ctl", f"{keys.prefix(f)}/to/*/contacts",
                                      f"{keys.prefix(f)}/to/*/radio",
                                      keys.launcher_cmd(f), keys.world_status(f), keys.world_events(f)]),
        _rule("world-token", ("liveliness_token",), [keys.alive_of(f, keys.WORLD)]),
        _rule("world-last", ("declare_queryable", "reply"), [keys.world_last(f, "*"), keys.any_world_command(f),
                                                             keys.world_settings(f), keys.world_status(f)]),
    ]
    policies.append({"id": "world", "rules": ["world-put", "world-token", "world-last"], "subjects": [WORLD_ROLE]})

    rules.append(_rule("ground-commands", ("put",), [keys.world_cmd(f, keys.GROUND)]))
    rules.append(_rule("ground-query", ("query",), [keys.world_command(f, keys.GROUND)]))
    policies.append({"id": "ground", "rules": ["ground-commands", "ground-query"], "subjects": [GROUND_ROLE]})
    # nobody else may command the world through its queryable (their READ allows any query)
    no_commands = {**_rule("no-commands", ("query",), [f"{keys.prefix(f)}/world/cmd/**"]), "permission": "deny"}
    rules.append(no_commands)
    policies.append({"id": "not-ground", "rules": ["no-commands"],
                     "subjects": [WORLD_ROLE, *(vehicle_role(v) for v in listeners), *([ROS2_ROLE] if ros2 else [])]})
    # a vehicle asks the world only where vehicles were (world/last/*, on a restart); its status and
    # settings are the operators' (a vehicle's credentials flooding those queries slowed a lockstep run)
    rules.append({**_rule("no-status-queries", ("query",), [keys.world_status(f), keys.world_settings(f)]),
                  "permission": "deny"})
    policies.append({"id": "vehicles-no-status", "rules": ["no-status-queries"],
                     "subjects": [vehicle_role(v) for v in listeners]})
    if ros2 is not None:
        _ros2_rules(f, ros2, rules, policies, subject(ROS2_CLIENT_ROLE))

    for vid, heard_by in listeners.items():
        role = vehicle_role(vid)
        rules += [_rule(f"{role}-put", ("put",), [keys.omega(f, vid, heard_by), keys.state(f, vid),
                                                  keys.stats(f, vid)]),
                  _rule(f"{role}-token", ("liveliness_token",), [keys.alive_of(f, vid)]),
                  _rule(f"{role}-ping", ("declare_queryable", "reply"), [keys.ping(f, vid)])]
        policies.append({"id": role, "rules": [f"{role}-put", f"{role}-token", f"{role}-ping"], "subjects": [role]})
    for r in robots:
        _robot_rules(r, rules, policies, subject(robot_role(r.vehicle)))
    return {"enabled": True, "default_permission": "deny", "rules": rules, "subjects": subjects,
            "policies": policies}


def _ros2_rules(f: str, g: Ros2Grant, rules: list, policies: list, client: str) -> None:
    """The bridge's and a ROS 2 machine's rules (see the module's docstring)."""
    ros = [*g.topic_keys, *g.caches(), g.graph()]
    rules += [_rule("ros2-out", MESSAGES, ros, flow="egress"),
              _rule("ros2-put", ("put", "reply"), list(g.topic_keys)),  # a cache replies with the data key
              _rule("ros2-caches", ("declare_queryable", "reply", "liveliness_token"), g.caches()),
              _rule("ros2-tokens", ("liveliness_token",), [g.graph(), keys.alive_of(f, ROS2_ROLE)]),
              _rule("ros2-read", READ, ros)]
    policies.append({"id": "ros2", "rules": ["ros2-out", "ros2-put", "ros2-caches", "ros2-tokens"],
                     "subjects": [ROS2_ROLE]})
    rules.append(_rule("ros2-client-tokens", ("liveliness_token",), [g.graph()]))
    policies.append({"id": "ros2-client", "rules": ["ros2-out", "ros2-read", "ros2-client-tokens"],
                     "subjects": [client]})


def _robot_rules(r: RobotGrant, rules: list, policies: list, robot: str) -> None:
    """A robot's and its vehicle's rules (see the module's docstring)."""
    vehicle, ros = vehicle_role(r.vehicle), f"{robot}-ros"
    rules += [_rule(f"{vehicle}-ros-out", MESSAGES, [r.odom, r.cmd], flow="egress"),
              _rule(f"{vehicle}-odom", ("declare_subscriber",), [r.odom]),
              _rule(f"{vehicle}-cmd", ("put",), [r.cmd]),
              _rule(f"{vehicle}-ros-tokens", ("liveliness_token",), list(r.tokens)),
              _rule(f"{ros}-out", MESSAGES, [r.odom, r.cmd, r.graph], flow="egress"),
              _rule(f"{robot}-odom", ("put",), [r.odom]),
              _rule(f"{robot}-cmd", ("declare_subscriber",), [r.cmd]),
              _rule(f"{robot}-graph", ("liveliness_token", *READ), [r.graph])]
    policies.append({"id": f"{vehicle}-ros", "rules": [f"{vehicle}-ros-out", f"{vehicle}-odom", f"{vehicle}-cmd",
                                                       f"{vehicle}-ros-tokens"], "subjects": [vehicle]})
    policies.append({"id": robot, "rules": [f"{ros}-out", f"{robot}-odom", f"{robot}-cmd", f"{robot}-graph"],
                     "subjects": [robot]})
