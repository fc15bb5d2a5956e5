"""Is a ``[link]`` table valid? Its validation, into a :class:`cdus.core.linkspec.LinkSpec`.

:func:`validate_link` checks a raw ``[link]`` table against the vehicle ids, collects
every problem (field, what would be valid) and returns a frozen spec (docs/link.md is
the user reference).
"""

from __future__ import annotations

import difflib
import math
from typing import Any, Iterable, Mapping, Sequence

from cdus.core.linkspec import (
    ANY, DEFAULT_POLICY, DEFAULT_TIMEOUT, DISTRIBUTIONS, POLICIES, Burst, Delay, Down, LinkSpec, Override, Partition,
)
from cdus.scenario.errors import ConfigError
from cdus.scenario.show import quote as _q, show as _show

LINK_KEYS = ("policy", "timeout", "seed", "delay", "loss", "burst", "duplicate", "override", "down", "partition")
DELAY_KEYS = ("base", "jitter", "distribution", "reorder")
BURST_KEYS = ("p", "r", "bad_loss", "good_loss")
OVERRIDE_KEYS = ("src", "dst", "delay", "loss", "burst", "duplicate")
DOWN_KEYS = ("src", "dst", "from", "to")
PARTITION_KEYS = ("from", "to", "groups", "drops")


# --------------------------------------------------------------------------- validation


def validate_link(link: Mapping[str, Any], ids: Sequence[str], source: str) -> LinkSpec:
    """Check a raw ``[link]`` table (``Scenario.link``) and build its :class:`LinkSpec`.

    Raises ``ConfigError(source, [(field, message), ...])`` with every problem.
    """
    problems: list[tuple[str, str]] = []
    spec = _Validator(problems, [str(i) for i in ids]).link(link)
    if problems:
        raise ConfigError(source, problems)
    assert spec is not None
    return spec


def _describe(v: Any) -> str:
    kind = ("boolean" if isinstance(v, bool) else "string" if isinstance(v, str)
            else "number" if isinstance(v, (int, float)) else "list" if isinstance(v, list)
            else "table" if isinstance(v, dict) else None)
    return f"the {kind} {_show(v)}" if kind else repr(v)


def _did_you_mean(word: Any, options: Iterable[str]) -> str:
    close = difflib.get_close_matches(str(word), list(options), n=1, cutoff=0.6)
    return f" (did you mean {_q(close[0])}?)" if close else ""


def _is_number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


class _Validator:
    def __init__(self, problems: list[tuple[str, str]], ids: list[str]):
        self.problems = problems
        self.ids = ids

    def add(self, field: str, message: str) -> None:
        if (field, message) not in self.problems:
            self.problems.append((field, message))

    # ---- generic checks

    def table(self, v: Any, field: str, example: str) -> dict | None:
        if not isinstance(v, dict):
            self.add(field, f"must be a table like {example}, got {_describe(v)}")
            return None
        return v

    def unknown_keys(self, table: Mapping, allowed: Sequence[str], field: str) -> None:
        for key in table:
            if key not in allowed:
                close = difflib.get_close_matches(str(key), list(allowed), n=1, cutoff=0.6)
                hint = f"did you mean {_q(close[0])}? " if close else ""
                self.add(f"{field}.{key}", f"unknown key; {hint}valid keys here: {', '.join(allowed)}")

    def number(self, v: Any, field: str, *, ge: float | None = None, gt: float | None = None,
               le: float | None = None, unit: str = "", allow_inf: bool = False) -> float | None:
        bounds = []
        if ge is not None:
            bounds.append(f">= {ge:g}")
        if gt is not None:
            bounds.append(f"> {gt:g}")
        if le is not None:
            bounds.append(f"<= {le:g}")
        want = f"a number{' ' + ' and '.join(bounds) if bounds else ''}{unit}"
        if not _is_number(v):
            self.add(field, f"must be {want}, got {_describe(v)}")
            return None
        if math.isnan(v) or (math.isinf(v) and not allow_inf):
            self.add(field, f"must be {want} (finite), got {_show(v)}")
            return None
        if (ge is not None and v < ge) or (gt is not None and not v > gt) or (le is not None and v > le):
            self.add(field, f"must be {want}, got {_show(v)}")
            return None
        return float(v)

    def probability(self, v: Any, field: str, what: str) -> float | None:
        if not _is_number(v) or math.isnan(v) or not 0.0 <= v <= 1.0:
            got = _describe(v) if not _is_number(v) else _show(v)
            self.add(field, f"must be a probability in [0, 1] ({what}), got {got}")
            return None
        return float(v)

    def vehicle(self, v: Any, field: str, wildcard: bool) -> str | None:
        star = ' or "*" (any vehicle)' if wildcard else ""
        if not isinstance(v, str):
            self.add(field, f"must be a vehicle id{star}, got {_describe(v)}")
            return None
        if wildcard and v == ANY:
            return v
        if v not in self.ids:
            self.add(field, f"{_q(v)} is not a vehicle{_did_you_mean(v, self.ids)}; ids are "
                            f"{', '.join(self.ids) or '(none)'}{star}")
            return None
        return v

    def tables(self, v: Any, field: str, section: str) -> list[dict]:
        if not isinstance(v, list) or not all(isinstance(t, dict) for t in v):
            self.add(field, f"must be an array of tables ([[{section}]] sections), got {_describe(v)}")
            return []
        return v

    def each(self, t: Mapping, key: str, check: Any) -> tuple:
        """Check every table of the array ``link.<key>`` (``[[link.<key>]]``); the good ones."""
        tables = self.tables(t.get(key, []), f"link.{key}", f"link.{key}")
        return tuple(x for x in (check(w, f"link.{key}[{j}]") for j, w in enumerate(tables)) if x is not None)

    # ---- sections

    def link(self, link: Any) -> LinkSpec | None:
        t = self.table(link, "link", "[link] with keys " + ", ".join(LINK_KEYS))
        if t is None:
            return None
        self.unknown_keys(t, LINK_KEYS, "link")
        policy = DEFAULT_POLICY
        if "policy" in t:
            p = t["policy"]
            if p not in POLICIES:
                self.add("link.policy", f"unknown stale-neighbour policy {_show(p)}{_did_you_mean(p, POLICIES)}; "
                                        f"choose one of {', '.join(POLICIES)}")
            else:
                policy = p
        timeout = DEFAULT_TIMEOUT
        if "timeout" in t:
            timeout = self.number(t["timeout"], "link.timeout", gt=0,
                                  unit=" (s a neighbour may stay silent under policy timeout)") or DEFAULT_TIMEOUT
        seed = None
        if "seed" in t:
            s = t["seed"]
            if not isinstance(s, int) or isinstance(s, bool) or s < 0:
                self.add("link.seed", f"must be an integer >= 0 (leave it out to use scenario.seed), "
                                      f"got {_describe(s)}")
            else:
                seed = s
        delay = self.delay(t["delay"], "link.delay", Delay()) if "delay" in t else Delay()
        loss = self.probability(t["loss"], "link.loss", "Bernoulli loss") if "loss" in t else 0.0
        burst = self.burst(t["burst"], "link.burst") if "burst" in t else None
        duplicate = self.probability(t["duplicate"], "link.duplicate", "of delivering a message twice") \
            if "duplicate" in t else 0.0
        overrides = self.each(t, "override", self.override)
        down = self.each(t, "down", self.down)
        parts = self.each(t, "partition", self.partition)
        if self.problems:
            return None
        return LinkSpec(policy=policy, timeout=timeout, seed=seed, delay=delay, loss=loss or 0.0, burst=burst,
                        duplicate=duplicate or 0.0, overrides=overrides, down=down, partitions=parts)

    def delay_fields(self, v: Any, field: str) -> dict[str, Any] | None:
        d = self.table(v, field, "{ base = 0.1, jitter = 0.02, distribution = \"uniform\", reorder = true } "
                                 "(seconds)")
        if d is None:
            return None
        self.unknown_keys(d, DELAY_KEYS, field)
        out: dict[str, Any] = {}
        for key, what in (("base", " (s, the mean delay; the minimum for pareto)"),
                          ("jitter", " (s, the spread: ± for uniform, σ for normal, tail mean for pareto)")):
            if key in d:
                x = self.number(d[key], f"{field}.{key}", ge=0, unit=what)
                if x is not None:
                    out[key] = x
        if "distribution" in d:
            dist = d["distribution"]
            if dist not in DISTRIBUTIONS:
                self.add(f"{field}.distribution", f"unknown distribution {_show(dist)}"
                                                  f"{_did_you_mean(dist, DISTRIBUTIONS)}; choose one of "
                                                  f"{', '.join(DISTRIBUTIONS)}")
            else:
                out["distribution"] = dist
        if "reorder" in d:
            if not isinstance(d["reorder"], bool):
                self.add(f"{field}.reorder", f"must be true (delays are independent, messages may overtake) or "
                                             f"false (per-link FIFO), got {_describe(d['reorder'])}")
            else:
                out["reorder"] = d["reorder"]
        return out

    def delay(self, v: Any, field: str, base: Delay) -> Delay:
        given = self.delay_fields(v, field)
        return Delay(**{**base.__dict__, **(given or {})})

    def burst(self, v: Any, field: str) -> Burst | None:
        b = self.table(v, field, "{ p = 0.05, r = 0.5, bad_loss = 1.0, good_loss = 0.0 } (Gilbert-Elliott)")
        if b is None:
            return None
        self.unknown_keys(b, BURST_KEYS, field)
        what = {"p": "P(good -> bad) per message", "r": "P(bad -> good) per message",
                "bad_loss": "loss in the bad state, netem's 1-h", "good_loss": "loss in the good state, netem's 1-k"}
        values: dict[str, float] = {"bad_loss": 1.0, "good_loss": 0.0}
        ok = True
        for key in BURST_KEYS:
            if key not in b:
                if key in ("p", "r"):
                    self.add(f"{field}.{key}", f"missing; a burst needs p ({what['p']}) and r ({what['r']}); "
                                               f"the mean burst length is 1/r")
                    ok = False
                continue
            x = self.probability(b[key], f"{field}.{key}", what[key])
            if x is None:
                ok = False
            else:
                values[key] = x
        return Burst(**values) if ok else None

    def override(self, o: dict, field: str) -> Override | None:
        self.unknown_keys(o, OVERRIDE_KEYS, field)
        before = len(self.problems)
        src = self.vehicle(o.get("src", ANY), f"{field}.src", wildcard=True)
        dst = self.vehicle(o.get("dst", ANY), f"{field}.dst", wildcard=True)
        if not any(k in o for k in ("delay", "loss", "burst", "duplicate")):
            self.add(field, "sets nothing; give at least one of delay, loss, burst, duplicate")
        delay = self.delay_fields(o["delay"], f"{field}.delay") if "delay" in o else {}
        loss = self.probability(o["loss"], f"{field}.loss", "Bernoulli loss") if "loss" in o else None
        burst = self.burst(o["burst"], f"{field}.burst") if "burst" in o else None
        dup = self.probability(o["duplicate"], f"{field}.duplicate", "of delivering a message twice") \
            if "duplicate" in o else None
        if len(self.problems) > before:
            return None
        return Override(src=src or ANY, dst=dst or ANY, delay=tuple(sorted((delay or {}).items())),
                        loss=loss, burst=burst, duplicate=dup)

    def window(self, w: dict, field: str) -> tuple[float, float] | None:
        start = self.number(w.get("from", 0.0), f"{field}.from", ge=0, unit=" (s of simulated time)")
        end = self.number(w.get("to", math.inf), f"{field}.to", gt=0,
                          unit=" (s of simulated time, exclusive; leave it out for 'until the end')", allow_inf=True)
        if start is None or end is None:
            return None
        if not end > start:
            self.add(f"{field}.to", f"must be > from ({_show(w.get('from', 0.0))}): the window is [from, to), "
                                    f"got to = {_show(w.get('to'))}")
            return None
        return start, end

    def down(self, w: dict, field: str) -> Down | None:
        self.unknown_keys(w, DOWN_KEYS, field)
        src = self.vehicle(w.get("src", ANY), f"{field}.src", wildcard=True)
        dst = self.vehicle(w.get("dst", ANY), f"{field}.dst", wildcard=True)
        times = self.window(w, field)
        if src is None or dst is None or times is None:
            return None
        return Down(times[0], times[1], src, dst)

    def partition(self, p: dict, field: str) -> Partition | None:
        self.unknown_keys(p, PARTITION_KEYS, field)
        times = self.window(p, field)
        if ("groups" in p) == ("drops" in p):
            self.add(field, ("give either groups or drops, not both" if "groups" in p else
                             'missing; give groups = [["usv1", "usv2"], ["uav1"]] (messages between groups are '
                             'dropped) or drops = { usv2 = ["usv1"] } (receiver -> senders it drops)'))
            return None
        before = len(self.problems)
        groups: tuple[tuple[str, ...], ...] = ()
        drops: tuple[tuple[str, tuple[str, ...]], ...] = ()
        if "groups" in p:
            groups = self.groups(p["groups"], f"{field}.groups")
        else:
            drops = self.drops(p["drops"], f"{field}.drops")
        if times is None or len(self.problems) > before:
            return None
        return Partition(times[0], times[1], groups=groups, drops=drops)

    def groups(self, v: Any, field: str) -> tuple[tuple[str, ...], ...]:
        example = '[["usv1", "usv2"], ["uav1", "uav2"]]'
        if not isinstance(v, list) or not v or not all(isinstance(g, list) and g for g in v):
            self.add(field, f"must be a non-empty list of non-empty lists of vehicle ids, like {example} "
                            f"(vehicles in no group form one more group), got {_describe(v)}")
            return ()
        seen: dict[str, int] = {}
        out = []
        for j, g in enumerate(v):
            members = []
            for x in g:
                vid = self.vehicle(x, f"{field}[{j}]", wildcard=False)
                if vid is None:
                    continue
                if vid in seen:
                    where = "twice in this group" if seen[vid] == j else f"in groups {seen[vid]} and {j}"
                    self.add(field, f"vehicle {_q(vid)} is {where}; a vehicle belongs to one group at most")
                    continue
                seen[vid] = j
                members.append(vid)
            out.append(tuple(members))
        return tuple(out)

    def drops(self, v: Any, field: str) -> tuple[tuple[str, tuple[str, ...]], ...]:
        if not isinstance(v, dict) or not v:
            self.add(field, f'must be a non-empty table receiver -> senders it drops, like '
                            f'{{ usv2 = ["usv1"], uav1 = ["usv3", "uav3"] }}, got {_describe(v)}')
            return ()
        out = []
        for receiver, senders in v.items():
            where = f"{field}.{receiver}"
            rid = self.vehicle(receiver, where, wildcard=False)
            if not isinstance(senders, list) or not senders:
                self.add(where, f"must be a non-empty list of the vehicle ids whose messages {receiver} drops, "
                                f"got {_describe(senders)}")
                continue
            got = []
            for x in senders:
                sid = self.vehicle(x, where, wildcard=False)
                if sid is not None and sid == rid:
                    self.add(where, f"{_q(sid)} cannot drop its own messages; list other vehicles")
                elif sid is not None and sid not in got:
                    got.append(sid)
            if rid is not None:
                out.append((rid, tuple(got)))
        return tuple(out)
