"""Is the [graph] section valid? Who listens to whom, with which weights and offsets.

Checks the [graph] table against the vehicles and builds every listening pair's
:class:`Edge`; the graph must have a directed spanning tree and offsets that close around
every cycle, and the errors say what to change (docs/config.md, "[graph]"). The graph
algorithms themselves are in :mod:`cdus.core.graph`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Mapping, Sequence

from cdus.core import graph as graphs
from cdus.core.paths import Path
from cdus.scenario.checks import IdList, Problems, describe, names, quote
from cdus.scenario.model import Edge
from cdus.scenario.vehicles import Fleet

TOPOLOGIES = graphs.TOPOLOGIES
GRAPH_KEYS = ("topology", "directed", "weight", "hub", "edges", "edge")
EDGE_KEYS = ("i", "k", "weight", "delta")
DEFAULT_WEIGHT = 1.0
#: The most listening pairs a graph may have: a complete graph of 256 vehicles (65,280).
#: Every pair is a term of a vehicle's consensus sum at every control tick and a coordination
#: error the world measures at every tick, and a vehicle's ω key names all its listeners
#: (``to/+id1+id2+.../omega/<id>``, up to 33 bytes per listener): a complete graph of 1,024
#: vehicles would be 1 M pairs and 34 kB keys.
MAX_PAIRS = 65_536

Pair = tuple[str, str]


@dataclass(frozen=True)
class _Refinement:
    """A [[graph.edge]] table: pair (i, k) gets this weight and/or delta."""

    j: int  # its index in graph.edge
    i: str
    k: str
    weight: float | None
    delta: float | None


def graph_section(p: Problems, gr: Mapping[str, Any], fleet: Fleet) -> tuple[str, bool, tuple[Edge, ...]]:
    """Validate [graph] and build the edges: (topology, directed, edges)."""
    p.unknown_keys(gr, GRAPH_KEYS, "graph")
    mark = len(p)
    topology = p.choice(gr.get("topology", "ring"), "graph.topology", TOPOLOGIES, "topology") or "ring"
    directed = p.boolean(gr.get("directed", False), "graph.directed") or False
    weight = DEFAULT_WEIGHT
    if "weight" in gr:
        weight = p.number(gr["weight"], "graph.weight", "graph.weight", unit=" (a_ik)") or DEFAULT_WEIGHT
    ids = fleet.known if fleet.complete else None  # None: some id is bad, so references are not checked
    hub = _hub(p, gr, topology, ids)
    explicit = _explicit_pairs(p, gr, topology, ids)
    refinements = _edge_tables(p, gr, ids)
    if topology == "explicit":
        explicit += [(r.i, r.k) for r in refinements]
    if ids is None or p.since(mark):
        return topology, directed, ()
    if topology == "ring" and len(ids) < 2:
        if "topology" in gr:
            p.add("graph.topology", f'a ring needs at least 2 vehicles, got {len(ids)}; leave topology unset or '
                                    f'use "complete" for a single vehicle')
        return topology, directed, ()
    n = len(ids)
    expected = {"ring": n if directed or n == 2 else 2 * n, "chain": (n - 1) * (1 if directed else 2),
                "complete": n * (n - 1), "star": (n - 1) * (1 if directed else 2),
                "explicit": len(explicit) * (1 if directed else 2)}[topology]
    if expected > MAX_PAIRS:
        p.add("graph.topology" if topology != "explicit" else "graph.edges",
              f"the {topology} graph of {n} vehicles has {expected} listening pairs, more than the limit of "
              f"{MAX_PAIRS} (a complete graph of 256 vehicles): each pair costs every control tick a term in a "
              f"consensus sum and a measured coordination error, and a vehicle's ω key names all its listeners; "
              f'use a sparser topology ("ring", "chain", "star") for a fleet this large')
        return topology, directed, ()
    pairs = graphs.build_pairs(topology, ids, directed, hub=hub, explicit=explicit)
    edges = _edges(p, pairs, refinements, weight, directed, f"{'directed' if directed else 'undirected'} "
                   f"{topology}", ids, {v.id: v.phase for v in fleet.specs if v is not None})
    if p.since(mark):
        return topology, directed, ()
    missing = graphs.unreachable(ids, pairs)
    if missing:
        p.add("graph", _spanning_message(ids, pairs, missing, directed, topology))
    found = graphs.inconsistent_cycle(ids, edges)
    if found is not None:
        p.add("graph.edge", _cycle_message(ids, edges, found, fleet.paths))
    return topology, directed, edges


def _hub(p: Problems, gr: Mapping[str, Any], topology: str, ids: Sequence[str] | None) -> str | None:
    if "hub" not in gr:
        return None
    if topology != "star":
        p.add("graph.hub", f'only used with topology = "star" (topology is {quote(topology)}); remove it')
        return None
    return p.vehicle(gr["hub"], "graph.hub", ids)


def _explicit_pairs(p: Problems, gr: Mapping[str, Any], topology: str, ids: Sequence[str] | None) -> list[Pair]:
    """The pairs of ``graph.edges`` (topology = "explicit" only)."""
    if "edges" not in gr:
        return []
    if topology != "explicit":
        p.add("graph.edges", f'only used with topology = "explicit" (topology is {quote(topology)}); set '
                             f'topology = "explicit" to list the pairs yourself, or remove graph.edges (use '
                             f"[[graph.edge]] tables to set the weight or delta of the {topology}'s pairs)")
        return []
    if not isinstance(gr["edges"], list):
        p.add("graph.edges", f'must be a list of [i, k] pairs, e.g. [["usv1", "usv2"]], got {describe(gr["edges"])}')
        return []
    pairs = []
    for j, pair in enumerate(gr["edges"]):
        where = f"graph.edges[{j}]"
        if not isinstance(pair, list) or len(pair) != 2:
            p.add(where, f"must be a pair [i, k] of vehicle ids (i listens to k), got {describe(pair)}")
            continue
        i, k = p.vehicle(pair[0], where, ids), p.vehicle(pair[1], where, ids)
        if i is not None and k is not None:
            if i == k:
                p.add(where, f"self-loop [{quote(i)}, {quote(k)}]: a vehicle cannot listen to itself")
            else:
                pairs.append((i, k))
    return pairs


def _edge_tables(p: Problems, gr: Mapping[str, Any], ids: Sequence[str] | None) -> list[_Refinement]:
    """The [[graph.edge]] tables that name a valid pair."""
    out = []
    tables = p.tables(gr.get("edge", []), "graph.edge", "graph.edge", " with i, k, weight, delta")
    for j, et in enumerate(tables):
        where = f"graph.edge[{j}]"
        p.unknown_keys(et, EDGE_KEYS, where)
        missing = [key for key in ("i", "k") if key not in et]
        for key in missing:
            p.missing(f"{where}.{key}", "a [[graph.edge]] names the pair with i (the listener) and k (the vehicle "
                                        "it listens to)")
        if missing:
            continue
        i, k = p.vehicle(et["i"], f"{where}.i", ids), p.vehicle(et["k"], f"{where}.k", ids)
        w = p.number(et["weight"], f"{where}.weight", "graph.weight", unit=" (a_ik)") if "weight" in et else None
        d = p.number(et["delta"], f"{where}.delta", "graph.edge.delta", unit=" (Δ_ik, the target of ω_i - ω_k)") if "delta" in et else None
        if i is None or k is None:
            continue
        if i == k:
            p.add(where, f"self-loop i = k = {quote(i)}: a vehicle cannot listen to itself")
            continue
        out.append(_Refinement(j, i, k, w, d))
    return out


def _edges(p: Problems, pairs: list[Pair], refinements: list[_Refinement], weight: float, directed: bool,
           kind_text: str, ids: Sequence[str], phases: Mapping[str, float]) -> tuple[Edge, ...]:
    """Every pair's weight and Δ (default θ_i - θ_k), refined by [[graph.edge]]."""
    ids = ids if isinstance(ids, IdList) else IdList(ids)
    listens_to: dict[str, list[str]] | None = None  # built on the first error that needs it
    weights = {pr: weight for pr in pairs}
    deltas = {(i, k): phases.get(i, 0.0) - phases.get(k, 0.0) for i, k in pairs}
    set_by: dict[Pair, int] = {}
    for r in refinements:
        where = f"graph.edge[{r.j}]"
        if (r.i, r.k) not in weights:
            if listens_to is None:
                listens_to = {}
                for a, b in pairs:
                    listens_to.setdefault(a, []).append(b)
            listens = listens_to.get(r.i, [])
            p.add(where, f"{r.i} does not listen to {r.k} in this {kind_text} ({r.i} listens to "
                         f"{names(listens) or 'nobody'}); a [[graph.edge]] can only refine an existing pair "
                         f'unless topology = "explicit"')
            continue
        key = (r.i, r.k) if directed else tuple(sorted((r.i, r.k), key=ids.position))
        if key in set_by:
            both = "" if directed else " (the graph is undirected: one table sets both directions)"
            p.add(where, f"the pair {r.i} - {r.k} is already set by graph.edge[{set_by[key]}]{both}")
            continue
        set_by[key] = r.j
        mirrored = () if directed else ((r.k, r.i),)
        if r.weight is not None:
            for pair in ((r.i, r.k),) + mirrored:
                weights[pair] = r.weight
        if r.delta is not None:
            deltas[(r.i, r.k)] = r.delta
            for pair in mirrored:
                deltas[pair] = -r.delta
    return tuple(Edge(i, k, weights[(i, k)], deltas[(i, k)]) for i, k in pairs)


# --------------------------------------------------------------------------- messages


def _spanning_message(ids: Sequence[str], pairs: list[Pair], missing: list[str], directed: bool,
                      topology: str) -> str:
    root = graphs.spanning_root(ids, pairs)
    gone = set(missing)
    reached = [v for v in ids if v not in gone]
    where = "graph.edges" if topology == "explicit" else 'graph.edges (with topology = "explicit")'
    if not directed:
        return (f"the graph is not connected: {names(missing)} cannot exchange ω with "
                f"{names(reached)}; add an edge such as [{quote(missing[0])}, {quote(root)}] to {where}")
    msg = (f"no directed spanning tree: {names(missing)} never hear{'s' if len(missing) == 1 else ''} "
           f"(even indirectly) from {root}, the vehicle that reaches the most others, and no other vehicle "
           f"reaches everyone (a pair [i, k] means i listens to k, so information flows from k to i); add a pair "
           f"such as [{quote(missing[0])}, {quote(root)}] ({missing[0]} listens to {root}) to {where}")
    reversed_pairs = [(k, i) for i, k in pairs]
    if not graphs.unreachable(ids, reversed_pairs):
        leader = graphs.spanning_root(ids, reversed_pairs)
        msg += (f"; or reverse the pairs: written the other way round they form a tree led by {leader} "
                f"(write each pair as [follower, leader])")
    return msg + ", or set directed = false"


def _cycle_message(ids: Sequence[str], edges: tuple[Edge, ...], found: tuple[list[str], float],
                   paths: Mapping[str, Path]) -> str:
    cycle, total = found
    msg = (f"inconsistent formation offsets: around the cycle {' -> '.join(cycle)} the deltas sum to "
           f"{_angle(total)}, not 0, so ω_i - ω_k -> Δ_ik cannot hold on every edge (Δs must come from "
           f"per-vehicle phases, Δ_ik = θ_i - θ_k)")
    period = _common_period([paths[v].period if v in paths else None for v in cycle[:-1]])
    phases = graphs.suggest_phases(ids, edges)
    if period is not None:
        n = round(total / period)
        if n != 0 and abs(total - n * period) <= 1e-6:
            lap_text = "one lap" if abs(n) == 1 else f"{abs(n)} laps"
            msg += (f"; the sum is {n} × {_pi_text(period) or f'{period:.6g}'}, {lap_text} of the path: "
                    f"the formation cannot close")
            wrapped = {}
            for v, t in phases.items():
                t = t % period
                wrapped[v] = 0.0 if abs(t - period) < 1e-9 * period else t
            return msg + ("; you probably meant per-vehicle phases (each Δ then holds modulo one lap): remove the "
                          "deltas and set " + _phase_lines(wrapped))
    return msg + "; to keep the offsets of a spanning tree, remove the deltas and set " + _phase_lines(phases)


def _common_period(periods: list[float | None]) -> float | None:
    """The smallest period shared by all (closed) paths on the cycle, if there is one."""
    if not periods or any(p is None for p in periods):
        return None
    longest = max(periods)
    for p in periods:
        ratio = longest / p
        if abs(ratio - round(ratio)) > 1e-6:
            return None
    return longest


def _phase_lines(phases: Mapping[str, float], most: int = 20) -> str:
    items = list(phases.items())
    text = ", ".join(f"vehicle {quote(v)} phase = {round(t, 6)!r}" for v, t in items[:most])
    return text if len(items) <= most else text + f" and so on for the {len(items) - most} other vehicles"


def _pi_text(x: float) -> str | None:
    """x as a simple multiple of π ("2π", "-2π/3"), or None."""
    r = x / math.pi
    for q in (1, 2, 3, 4, 6, 8, 12):
        n = round(r * q)
        if n != 0 and abs(r * q - n) < 1e-6:
            g = math.gcd(n, q)
            n, q = n // g, q // g
            sign = {1: "", -1: "-"}.get(n, str(n))
            return f"{sign}π" + ("" if q == 1 else f"/{q}")
    return None


def _angle(x: float) -> str:
    """A number, followed by its value as a multiple of π when it is a simple one."""
    pi = _pi_text(x)
    return f"{x:.6g}" + (f" ({pi})" if pi else "")
