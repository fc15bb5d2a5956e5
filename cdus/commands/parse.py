"""Which command is this? The three entries (CLI arguments, wire fields, scenario event) into one.

Each entry turns its raw input into a command's fields (the wire's shape,
cdus.wire.messages.COMMAND_OPS) and calls that command's own ``parse``, so equal input gives an
equal command whichever door it came through, and a refusal is a
:class:`cdus.wire.rejected.Rejected` naming the field:

- :func:`parse_cli`: a ground station's action word and its ``KEY=VALUE`` settings,
  ``--vehicle``, ``--at`` (``cdus gs ... gains k=2 --vehicle usv1``);
- :func:`parse_wire`: a decoded control map's op and fields (cdus.wire.messages.decode_control),
  the world's and the agent's entry; :func:`decode_command` reads the payload too;
- :func:`parse_event`: a scenario ``[[event]]`` table (cdus.scenario.events checks its time and
  its place in the run's sequence).

The registry (:data:`COMMANDS`, :data:`BY_CLI`, :data:`BY_OP`, :data:`BY_EVENT`) is built from
each command's ``NAMES``, so a name is written once, with the command.
"""

from __future__ import annotations

from typing import Any, Mapping, Sequence, Union

from cdus.commands.base import Rejected
from cdus.commands.changes import Formation, Path
from cdus.commands.fleet import Pause, Resume, Stop
from cdus.commands.gains import Gains
from cdus.commands.link import Link
from cdus.commands.radio import Radio
from cdus.commands.vehicle import Kill, PauseVehicle, Restart, ResumeVehicle
from cdus.scenario.config import parse_value
from cdus.wire.messages import COMMAND_OPS, MAX_CONTROL_PAYLOAD, decode_control, encode_control
from cdus.wire.rejected import Rejected

Command = Union[Stop, Pause, Resume, Gains, Link, Formation, Path, Radio, Kill, PauseVehicle, ResumeVehicle, Restart]
COMMANDS: tuple[type, ...] = (Stop, Pause, Resume, Gains, Link, Formation, Path, Radio,
                              Kill, PauseVehicle, ResumeVehicle, Restart)
BY_CLI: dict[str, type] = {c.NAMES.cli: c for c in COMMANDS}
#: the wire's ops, the older spellings included (a ground station of an older version says set_gains)
BY_OP: dict[str, type] = {op: c for c in COMMANDS for op in (c.NAMES.op, *c.NAMES.old_ops)}
BY_EVENT: dict[str, type] = {c.NAMES.event: c for c in COMMANDS if c.NAMES.event is not None}
#: the commands a ground station's CLI takes KEY=VALUE settings for, and under which field
SETTINGS_FIELD = {Gains: "gains", Link: "link", Radio: "radio", Path: "path"}
#: event keys that are the scenario's, not the command's
EVENT_ONLY = ("at", "action", "duration")


def parse_wire(op: str, fields: Mapping[str, Any]) -> Command | Rejected:
    """The command a wire op and its fields make (the fields as decode_control checked them)."""
    cls = BY_OP.get(op) if isinstance(op, str) else None
    if cls is None:
        return Rejected(f"no command {op!r}; commands are {', '.join(c.NAMES.op for c in COMMANDS)}", "op")
    return cls.parse(fields)


def decode_command(payload: bytes) -> Command | Rejected:
    """A command map from the wire (``to/+world+/cmd/<from>``) as a typed command, or why not (the
    decoder's reasons: ``malformed``, ``version``, ``unknown_op``, ``type``, ...)."""
    c = decode_control(payload, COMMAND_OPS)
    if isinstance(c, Rejected):
        return c
    return parse_wire(c.op, c.fields)


#: a KEY=VALUE each command with settings takes, for a refusal's "e.g."
EXAMPLE = {"gains": "k=2", "link": "loss=0.3", "radio": "tx_power=20", "formation": "phases.usv2=3.1416",
           "path": "family=circle"}


def nested(settings: Sequence[str], example: str = "loss=0.3") -> dict | Rejected:
    """``["loss=0.3", "delay.base=0.1"]`` -> ``{"loss": 0.3, "delay": {"base": 0.1}}`` (values as TOML).
    A setting without ``=`` is refused with ``example``, or with ``KEY=VALUE`` when it was
    given as two words (``k 2``)."""
    out: dict = {}
    for n, item in enumerate(settings):
        key, sep, value = item.partition("=")
        if not sep or not key:
            after = settings[n + 1] if n + 1 < len(settings) else ""
            if key and after and "=" not in after:
                return Rejected(f"expected KEY=VALUE: did you mean {key}={after}?", item)
            return Rejected(f"expected KEY=VALUE, e.g. {example}", item)
        node = out
        parts = key.split(".")
        for n, part in enumerate(parts[:-1]):
            node = node.setdefault(part, {})
            if not isinstance(node, dict):
                return Rejected(f"given both a value and, in {item}, fields of it; give one", ".".join(parts[:n + 1]))
        if isinstance(node.get(parts[-1]), dict):
            return Rejected(f"given both fields of it and, in {item}, a value; give one", key)
        node[parts[-1]] = parse_value(value)
    return out


def formation_settings(table: Mapping[str, Any]) -> dict | Rejected:
    """``{"phases": {id: θ}}`` or ``{"offsets": {i: {k: Δ}}}`` (the CLI's phases.ID=θ,
    offsets.I.K=Δ) -> the formation command's fields."""
    bad = sorted(set(table) - {"phases", "offsets"})
    if bad or len(table) != 1:
        return Rejected("give phases.ID=θ ... (ω units) or offsets.I.K=Δ ... (I listens to K), not both",
                        bad[0] if bad else "formation")
    for name in ("phases", "offsets"):
        if not isinstance(table.get(name, {}), dict):
            return Rejected(f"write phases.ID=θ (ω units) or offsets.I.K=Δ (I listens to K), got "
                            f"{name}={table[name]!r}", name)
    offsets = []
    for i, row in table.get("offsets", {}).items():
        if not isinstance(row, dict):
            return Rejected("write offsets.I.K=Δ (I listens to K)", f"offsets.{i}")
        offsets += [{"i": i, "k": k, "delta": d} for k, d in row.items()]
    return {"phases": dict(table.get("phases", {})), "offsets": offsets}


def parse_cli(action: str, settings: Sequence[str] = (), *, vehicle: str | None = None,
              at: float | None = None) -> Command | Rejected:
    """The command a ground station's action word and arguments make: ``settings`` (KEY=VALUE)
    for gains, link, radio, formation and path; ``vehicle`` (``--vehicle`` or a fault's
    positional id); ``at`` (``--at``, s) for link and radio."""
    cls = BY_CLI.get(action)
    if cls is None:
        return Rejected(f"no command {action!r}; commands are {', '.join(BY_CLI)}", "action")
    fields: dict[str, Any] = {}
    if cls in SETTINGS_FIELD or cls is Formation:
        table = nested(settings, EXAMPLE.get(action, "loss=0.3"))
        if isinstance(table, Rejected):
            return table
        if cls is Formation:
            table = formation_settings(table)
            if isinstance(table, Rejected):
                return table
            fields.update(table)
        else:
            fields[SETTINGS_FIELD[cls]] = table
    elif settings:
        return Rejected(f"{action} takes no KEY=VALUE settings", settings[0])
    if "vehicle" in cls.KEYS and (vehicle is not None or cls is not Gains):
        fields["vehicle"] = vehicle
    if "at" in cls.KEYS and at is not None:
        fields["at"] = at
    got = cls.parse(fields)
    if not isinstance(got, Rejected):
        got = unsendable(got) or got
    if cls is Path and isinstance(got, Rejected) and (got.field or "").startswith("path."):
        return Rejected(got.reason, got.field[len("path."):])  # named as typed: waypoints, not path.waypoints
    return got


#: the longest name a ground station adds to a command (``--name``, cdus.wire.messages._NAME_RE)
LONGEST_NAME = "n" * 64


def unsendable(command: Command) -> Rejected | None:
    """Why a command would not reach the world whole (the wire's control map holds at most 64
    entries in a list or a table, 256 characters in a text, MAX_CONTROL_PAYLOAD bytes in all: a
    spline of 65 waypoints was answered "could not be read: malformed"), None if it would."""
    op, fields = wire_of(command)
    why = decode_control(encode_control(op, **fields, name=LONGEST_NAME), COMMAND_OPS)
    if not isinstance(why, Rejected):
        return None
    where = "path.waypoints" if isinstance(command, Path) and "waypoints" in command.path_table() else \
        SETTINGS_FIELD.get(type(command), "phases" if isinstance(command, Formation) else None)
    hint = (" a longer route goes in the scenario (a [[vehicle]]'s path or a path [[event]] take up to 10,000 "
            "waypoints)" if where == "path.waypoints" else " split it into several commands")
    return Rejected(f"too large for one command message ({why}: at most 64 entries in a list or a table, 256 "
                    f"characters in a text, {MAX_CONTROL_PAYLOAD} bytes in all):{hint}", where)


def parse_event(event: Mapping[str, Any]) -> Command | Rejected:
    """The command a scenario ``[[event]]`` table carries out (its ``at`` and a pause's
    ``duration`` are the scenario's: cdus.scenario.events)."""
    action = event.get("action")
    cls = BY_EVENT.get(action) if isinstance(action, str) else None
    if cls is None:
        return Rejected(f"no event action {action!r}; actions are {', '.join(BY_EVENT)}", "action")
    fields = {k: v for k, v in event.items() if k not in EVENT_ONLY}
    if cls is Radio:
        fields = {"radio": fields}  # the event's tx_power and station are the command's radio table
    return cls.parse(fields)


def wire_of(command: Command) -> tuple[str, dict]:
    """(op, fields) to send a command (cdus.wire.messages.encode_control(op, **fields))."""
    return command.NAMES.op, command.fields()
