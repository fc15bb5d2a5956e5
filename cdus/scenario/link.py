"""Is a ``[link]`` table valid? Its validation, into a :class:`cdus.core.linkspec.LinkSpec`.

:func:`link_section` checks the scenario's ``[link]`` table against the vehicle ids and
builds the frozen spec that ``Scenario.link`` carries; :func:`validate_link` does the same
for a table that arrives at run time (a ground-station link command merged over the
scenario's table) and raises :class:`ConfigError`. docs/link.md is the user reference.
"""

from __future__ import annotations

import math
from typing import Any, Callable, Mapping, Sequence, TypeVar

from cdus.core.linkspec import (
    ANY, DEFAULT_POLICY, DEFAULT_TIMEOUT, DISTRIBUTIONS, POLICIES, Burst, Delay, Down, LinkSpec, Override, Partition,
)
from cdus.scenario.checks import IdList, Problems, describe, quote, show
from cdus.scenario.errors import ConfigError

LINK_KEYS = ("policy", "timeout", "seed", "delay", "loss", "burst", "duplicate", "override", "down", "partition")
DELAY_KEYS = ("base", "jitter", "distribution", "reorder")
BURST_KEYS = ("p", "r", "bad_loss", "good_loss")
OVERRIDE_KEYS = ("src", "dst", "delay", "loss", "burst", "duplicate")
DOWN_KEYS = ("src", "dst", "from", "to")
PARTITION_KEYS = ("from", "to", "groups", "drops")
FAULT_KEYS = ("delay", "loss", "burst", "duplicate")  # what a table or an override can set

DELAY_EXAMPLE = '{ base = 0.1, jitter = 0.02, distribution = "uniform", reorder = true } (seconds)'
BURST_EXAMPLE = "{ p = 0.05, r = 0.5, bad_loss = 1.0, good_loss = 0.0 } (Gilbert-Elliott)"
BURST_WHAT = {"p": "P(good -> bad) per message", "r": "P(bad -> good) per message",
              "bad_loss": "loss in the bad state, netem's 1-h", "good_loss": "loss in the good state, netem's 1-k"}
LOSS_WHAT = "Bernoulli loss"
DUPLICATE_WHAT = "of delivering a message twice"

T = TypeVar("T")
Ids = Sequence[str] | None  # None: the vehicle ids are not known (references are not checked)


def merge_link_tables(base: dict, change: dict) -> dict:
    """``change`` over ``base``, sub-tables key by key (``delay = {jitter = ...}`` keeps the
    base's ``delay.base``); lists (``down``, ``partition``, ``override``) are replaced whole."""
    out = dict(base)
    for key, value in change.items():
        old = out.get(key)
        out[key] = {**old, **value} if isinstance(old, dict) and isinstance(value, dict) else value
    return out


def validate_link(link: Any, ids: Ids, source: str) -> LinkSpec:
    """Check a raw ``[link]`` table and build its :class:`LinkSpec` (``ids`` None: vehicle
    references are not checked).

    Raises ``ConfigError(source, [(field, message), ...])`` with every problem.
    """
    p = Problems()
    spec = link_section(p, link, None if ids is None else IdList(str(i) for i in ids))
    if p:
        raise ConfigError(source, p.items)
    assert spec is not None
    return spec


def link_section(p: Problems, link: Any, ids: Ids) -> LinkSpec | None:
    """The [link] table as a :class:`LinkSpec`, or None after recording its problems."""
    t = p.table(link, "link", "a [link] section with keys " + ", ".join(LINK_KEYS))
    if t is None:
        return None
    mark = len(p)
    p.unknown_keys(t, LINK_KEYS, "link")
    policy = DEFAULT_POLICY
    if "policy" in t:
        policy = p.choice(t["policy"], "link.policy", POLICIES, "stale-neighbour policy") or DEFAULT_POLICY
    timeout = DEFAULT_TIMEOUT
    if "timeout" in t:
        timeout = p.number(t["timeout"], "link.timeout", "link.timeout",
                           unit=" (s a neighbour may stay silent under policy timeout)") or DEFAULT_TIMEOUT
    seed = p.integer(t["seed"], "link.seed", ge=0, unit=" (leave it out to use scenario.seed)") if "seed" in t else None
    delay = Delay(**{**Delay().__dict__, **_delay_fields(p, t["delay"], "link.delay")}) if "delay" in t else Delay()
    loss = p.probability(t["loss"], "link.loss", LOSS_WHAT) if "loss" in t else 0.0
    burst = _burst(p, t["burst"], "link.burst") if "burst" in t else None
    duplicate = p.probability(t["duplicate"], "link.duplicate", DUPLICATE_WHAT) if "duplicate" in t else 0.0
    overrides = _each(p, t, "override", lambda o, f: _override(p, o, f, ids))
    down = _each(p, t, "down", lambda w, f: _down(p, w, f, ids))
    partitions = _each(p, t, "partition", lambda w, f: _partition(p, w, f, ids))
    if p.since(mark):
        return None
    return LinkSpec(policy=policy, timeout=timeout, seed=seed, delay=delay, loss=loss or 0.0, burst=burst,
                    duplicate=duplicate or 0.0, overrides=overrides, down=down, partitions=partitions)


def _each(p: Problems, t: Mapping[str, Any], key: str, check: Callable[[dict, str], T | None]) -> tuple[T, ...]:
    """Check every table of the array ``[[link.<key>]]``; the good ones."""
    tables = p.tables(t.get(key, []), f"link.{key}", f"link.{key}")
    return tuple(x for x in (check(w, f"link.{key}[{j}]") for j, w in enumerate(tables)) if x is not None)


def _delay_fields(p: Problems, v: Any, field: str) -> dict[str, Any]:
    """The keys a delay table gives, checked ({} if it is not a table)."""
    d = p.table(v, field, DELAY_EXAMPLE)
    if d is None:
        return {}
    p.unknown_keys(d, DELAY_KEYS, field)
    out: dict[str, Any] = {}
    for key, what in (("base", " (s, the mean delay; the minimum for pareto)"),
                      ("jitter", " (s, the spread: ± for uniform, σ for normal, tail mean for pareto)")):
        if key in d:
            out[key] = p.number(d[key], f"{field}.{key}", f"link.delay.{key}", unit=what)
    if "distribution" in d:
        out["distribution"] = p.choice(d["distribution"], f"{field}.distribution", DISTRIBUTIONS, "distribution")
    if "reorder" in d:
        out["reorder"] = p.boolean(d["reorder"], f"{field}.reorder",
                                   true=" (delays are independent, messages may overtake)",
                                   false=" (per-link FIFO)")
    return {k: x for k, x in out.items() if x is not None}


def _burst(p: Problems, v: Any, field: str) -> Burst | None:
    b = p.table(v, field, BURST_EXAMPLE)
    if b is None:
        return None
    p.unknown_keys(b, BURST_KEYS, field)
    mark = len(p)
    for key in ("p", "r"):
        if key not in b:
            p.missing(f"{field}.{key}", f"a burst needs p ({BURST_WHAT['p']}) and r ({BURST_WHAT['r']}); "
                                        f"the mean burst length is 1/r")
    values = {key: p.probability(b[key], f"{field}.{key}", BURST_WHAT[key]) for key in BURST_KEYS if key in b}
    return None if p.since(mark) else Burst(**values)


def _override(p: Problems, o: dict, field: str, ids: Ids) -> Override | None:
    p.unknown_keys(o, OVERRIDE_KEYS, field)
    mark = len(p)
    src = p.vehicle(o.get("src", ANY), f"{field}.src", ids, wildcard=True)
    dst = p.vehicle(o.get("dst", ANY), f"{field}.dst", ids, wildcard=True)
    if not any(k in o for k in FAULT_KEYS):
        p.add(field, f"sets nothing; give at least one of {', '.join(FAULT_KEYS)}")
    delay = _delay_fields(p, o["delay"], f"{field}.delay") if "delay" in o else {}
    loss = p.probability(o["loss"], f"{field}.loss", LOSS_WHAT) if "loss" in o else None
    burst = _burst(p, o["burst"], f"{field}.burst") if "burst" in o else None
    dup = p.probability(o["duplicate"], f"{field}.duplicate", DUPLICATE_WHAT) if "duplicate" in o else None
    if p.since(mark) or src is None or dst is None:
        return None
    return Override(src=src, dst=dst, delay=tuple(sorted(delay.items())), loss=loss, burst=burst, duplicate=dup)


def _window(p: Problems, w: dict, field: str) -> tuple[float, float] | None:
    """[from, to) in simulated seconds; ``to`` may be left out (until the end)."""
    start = p.number(w.get("from", 0.0), f"{field}.from", "link.window.from", unit=" (s of simulated time)")
    end = p.number(w.get("to", math.inf), f"{field}.to", "link.window.to",
                   unit=" (s of simulated time, exclusive; leave it out for 'until the end')")
    if start is None or end is None:
        return None
    if not end > start:
        p.add(f"{field}.to", f"must be > from ({show(w.get('from', 0.0))}): the window is [from, to), "
                             f"got to = {show(w.get('to'))}")
        return None
    return start, end


def _down(p: Problems, w: dict, field: str, ids: Ids) -> Down | None:
    p.unknown_keys(w, DOWN_KEYS, field)
    src = p.vehicle(w.get("src", ANY), f"{field}.src", ids, wildcard=True)
    dst = p.vehicle(w.get("dst", ANY), f"{field}.dst", ids, wildcard=True)
    times = _window(p, w, field)
    if src is None or dst is None or times is None:
        return None
    return Down(times[0], times[1], src, dst)


def _partition(p: Problems, w: dict, field: str, ids: Ids) -> Partition | None:
    p.unknown_keys(w, PARTITION_KEYS, field)
    times = _window(p, w, field)
    if ("groups" in w) == ("drops" in w):
        if "groups" in w:
            p.add(field, "give either groups or drops, not both")
        else:
            p.missing(field, 'give groups = [["usv1", "usv2"], ["uav1"]] (messages between groups are dropped) '
                             'or drops = { usv2 = ["usv1"] } (receiver -> senders it drops)')
        return None
    mark = len(p)
    groups = _groups(p, w["groups"], f"{field}.groups", ids) if "groups" in w else ()
    drops = _drops(p, w["drops"], f"{field}.drops", ids) if "drops" in w else ()
    if times is None or p.since(mark):
        return None
    return Partition(times[0], times[1], groups=groups, drops=drops)


def _groups(p: Problems, v: Any, field: str, ids: Ids) -> tuple[tuple[str, ...], ...]:
    if not isinstance(v, list) or not v or not all(isinstance(g, list) and g for g in v):
        p.add(field, f'must be a non-empty list of non-empty lists of vehicle ids, like [["usv1", "usv2"], '
                     f'["uav1", "uav2"]] (vehicles in no group form one more group), got {describe(v)}')
        return ()
    seen: dict[str, int] = {}
    out = []
    for j, group in enumerate(v):
        members = []
        for x in group:
            vid = p.vehicle(x, f"{field}[{j}]", ids)
            if vid is None:
                continue
            if vid in seen:
                where = "twice in this group" if seen[vid] == j else f"in groups {seen[vid]} and {j}"
                p.add(field, f"vehicle {quote(vid)} is {where}; a vehicle belongs to one group at most")
                continue
            seen[vid] = j
            members.append(vid)
        out.append(tuple(members))
    return tuple(out)


def _drops(p: Problems, v: Any, field: str, ids: Ids) -> tuple[tuple[str, tuple[str, ...]], ...]:
    if not isinstance(v, dict) or not v:
        p.add(field, f'must be a non-empty table receiver -> senders it drops, like '
                     f'{{ usv2 = ["usv1"], uav1 = ["usv3", "uav3"] }}, got {describe(v)}')
        return ()
    out = []
    for receiver, senders in v.items():
        where = f"{field}.{receiver}"
        rid = p.vehicle(receiver, where, ids)
        if not isinstance(senders, list) or not senders:
            p.add(where, f"must be a non-empty list of the vehicle ids whose messages {receiver} drops, "
                         f"got {describe(senders)}")
            continue
        got: list[str] = []
        for x in senders:
            sid = p.vehicle(x, where, ids)
            if sid is not None and sid == rid:
                p.add(where, f"{quote(sid)} cannot drop its own messages; list other vehicles")
            elif sid is not None and sid not in got:
                got.append(sid)
        if rid is not None:
            out.append((rid, tuple(got)))
    return tuple(out)
