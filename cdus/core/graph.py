"""What is the communication graph? Who listens to whom, and whether the offsets can close.

Pure functions over vehicle ids, no I/O. A *listening pair* ``(i, k)`` means vehicle i
listens to vehicle k: k is in N_i, the neighbour set of the paper's sum
``Σ_k a_ik (ω_i - ω_k - Δ_ik)`` (docs/control.md §2). Information therefore flows k -> i.

Two facts the controller needs from the graph:
- a directed spanning tree (the paper's Assumption 1): some root reaches every vehicle
  following the information flow (:func:`unreachable`);
- consistent offsets: the Δs come from per-vehicle phases, Δ_ik = θ_i - θ_k, i.e. they
  sum to zero around every cycle ("Formation offsets must be consistent",
  :func:`inconsistent_cycle`).
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass
from typing import Any, Iterable, Sequence

TOPOLOGIES = ("ring", "chain", "complete", "star", "explicit")

Pair = tuple[str, str]


@dataclass(frozen=True)
class MetricEdge:
    """An edge whose coordination error the metrics record (cdus.core.metrics)."""

    i: int
    k: int
    delta: float
    name: str  # "<id_i>__<id_k>", the Rerun entity name too


def build_pairs(topology: str, ids: Sequence[str], directed: bool, hub: str | None = None,
                explicit: Iterable[Pair] = ()) -> list[Pair]:
    """The listening pairs ``(i, k)`` (i listens to k) of a named topology.

    - ring: vehicle j listens to j-1 and, undirected, to j+1 (cyclic); needs >= 2 vehicles.
    - chain: directed, j listens to j-1 (the first vehicle is the leader and listens to
      nobody); undirected, both ways.
    - complete: every vehicle listens to every other.
    - star: directed, every vehicle listens to the hub (default: the first vehicle);
      undirected, the hub also listens to every vehicle.
    - explicit: the given pairs; undirected adds each reverse pair.

    Pairs are unique and sorted by (index of i, index of k). Raises ``ValueError`` for an
    unknown topology, a ring of fewer than 2 vehicles, or a hub/pair naming an unknown id.
    """
    ids = list(ids)
    n = len(ids)
    pos = {v: j for j, v in enumerate(ids)}
    pairs: list[Pair] = []
    if topology == "ring":
        if n < 2:
            raise ValueError(f"a ring needs at least 2 vehicles, got {n}")
        for j in range(n):
            pairs.append((ids[j], ids[j - 1]))
            if not directed:
                pairs.append((ids[j], ids[(j + 1) % n]))
    elif topology == "chain":
        for j in range(1, n):
            pairs.append((ids[j], ids[j - 1]))
            if not directed:
                pairs.append((ids[j - 1], ids[j]))
    elif topology == "complete":
        pairs = [(i, k) for i in ids for k in ids if i != k]
    elif topology == "star":
        hub = ids[0] if hub is None and ids else hub
        if n and hub not in pos:
            raise ValueError(f"hub {hub!r} is not one of the vehicles {ids}")
        for v in ids:
            if v != hub:
                pairs.append((v, hub))
                if not directed:
                    pairs.append((hub, v))
    elif topology == "explicit":
        for i, k in explicit:
            if i not in pos or k not in pos:
                raise ValueError(f"pair {[i, k]} names a vehicle not in {ids}")
            if i == k:
                raise ValueError(f"pair {[i, k]} is a self-loop")
            pairs.append((i, k))
            if not directed:
                pairs.append((k, i))
    else:
        raise ValueError(f"unknown topology {topology!r}; choose one of {', '.join(TOPOLOGIES)}")
    unique = set(pairs)
    return sorted(unique, key=lambda p: (pos[p[0]], pos[p[1]]))


def reachable_from(root: str, pairs: Iterable[Pair]) -> set[str]:
    """The vehicles that hear from ``root``, directly or not (information flows k -> i)."""
    return _reach(root, _listeners(pairs))


def _listeners(pairs: Iterable[Pair]) -> dict[str, list[str]]:
    """k -> the vehicles listening to k (the information-flow adjacency)."""
    listeners: dict[str, list[str]] = {}
    for i, k in pairs:
        listeners.setdefault(k, []).append(i)
    return listeners


def _reach(root: str, listeners: dict[str, list[str]]) -> set[str]:
    seen = {root}
    queue = deque([root])
    while queue:
        v = queue.popleft()
        for w in listeners.get(v, ()):
            if w not in seen:
                seen.add(w)
                queue.append(w)
    return seen


#: At most this many candidate roots are searched when no vehicle reaches everyone
#: (:func:`spanning_root`): each search costs O(n + m), so the check stays linear.
MAX_ROOT_SEARCHES = 32


def _components(ids: Sequence[str], listeners: dict[str, list[str]]) -> dict[str, int]:
    """Strongly connected components of the information-flow graph (Tarjan, iterative:
    no recursion limit, O(n + m)). Returns vehicle -> component number."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    comp: dict[str, int] = {}
    on_stack: set[str] = set()
    stack: list[str] = []
    counter = 0
    n_comps = 0
    for start in ids:
        if start in index:
            continue
        work = [(start, iter(listeners.get(start, ())))]
        index[start] = low[start] = counter
        counter += 1
        stack.append(start)
        on_stack.add(start)
        while work:
            v, it = work[-1]
            pushed = False
            for w in it:
                if w not in index:
                    index[w] = low[w] = counter
                    counter += 1
                    stack.append(w)
                    on_stack.add(w)
                    work.append((w, iter(listeners.get(w, ()))))
                    pushed = True
                    break
                if w in on_stack and index[w] < low[v]:
                    low[v] = index[w]
            if pushed:
                continue
            work.pop()
            if work:
                u = work[-1][0]
                if low[v] < low[u]:
                    low[u] = low[v]
            if low[v] == index[v]:
                while True:
                    w = stack.pop()
                    on_stack.discard(w)
                    comp[w] = n_comps
                    if w == v:
                        break
                n_comps += 1
    return comp


def spanning_root(ids: Sequence[str], pairs: Iterable[Pair]) -> str | None:
    """The root that reaches the most vehicles (ties: the first id); None without vehicles.

    O(n + m): the best root lies in a *source* component of the information flow (one no
    other vehicle is heard by); with one source component its first vehicle reaches
    everyone. With several, the first :data:`MAX_ROOT_SEARCHES` source components (by
    their first vehicle) are searched; for an undirected graph every component is a source
    and its size is its reach, so the answer there is always exact.
    """
    ids = list(ids)
    if not ids:
        return None
    listeners = _listeners(pairs)
    comp = _components(ids, listeners)
    heard = set()  # components that hear from another component
    for k, ws in listeners.items():
        for w in ws:
            if k in comp and w in comp and comp[w] != comp[k]:
                heard.add(comp[w])
    firsts: dict[int, str] = {}
    for v in ids:
        firsts.setdefault(comp[v], v)
    sources = [v for c, v in firsts.items() if c not in heard]  # ordered by first id
    if len(sources) == 1:
        return sources[0]
    sizes: dict[int, int] = {}
    for v in ids:
        sizes[comp[v]] = sizes.get(comp[v], 0) + 1
    if not heard:  # no edges between components (e.g. undirected): reach = own component
        return _first_largest(sources, lambda v: sizes[comp[v]])
    return _first_largest(sources[:MAX_ROOT_SEARCHES], lambda v: len(_reach(v, listeners)))


def _first_largest(candidates: list[str], size) -> str:
    """The candidate with the largest ``size`` (ties: the earliest in the list)."""
    best, best_n = candidates[0], -1
    for v in candidates:
        n = size(v)
        if n > best_n:
            best, best_n = v, n
    return best


def unreachable(ids: Sequence[str], pairs: Iterable[Pair]) -> list[str]:
    """[] if the graph has a directed spanning tree, else the vehicles the best root misses.

    The best root is the one reaching the most vehicles (ties: the first id;
    :func:`spanning_root`). For an undirected graph (both directions of every pair) this
    is "not connected to the largest component". O(n + m).
    """
    pairs = list(pairs)
    root = spanning_root(ids, pairs)
    if root is None:
        return []
    seen = reachable_from(root, pairs)
    return [v for v in ids if v not in seen]


# --------------------------------------------------------------------------- offsets


def _triples(edges: Iterable[Any]) -> list[tuple[str, str, float]]:
    """Accept ``(i, k, delta)`` tuples or objects with ``.i``, ``.k``, ``.delta``."""
    out = []
    for e in edges:
        if hasattr(e, "delta"):
            out.append((e.i, e.k, float(e.delta)))
        else:
            i, k, d = e
            out.append((i, k, float(d)))
    return out


def _potentials(ids: Sequence[str], triples: list[tuple[str, str, float]]):
    """BFS over the undirected constraint graph: θ with θ_i = θ_k + Δ_ik on tree edges.

    Returns (theta, parent) with parent[v] = (u, constraint index) for the tree edge
    that reached v, None for a root. Each component is rooted at its first id (θ = 0).
    """
    adj: dict[str, list[tuple[str, float, int]]] = {v: [] for v in ids}
    for idx, (i, k, d) in enumerate(triples):
        adj.setdefault(i, []).append((k, -d, idx))  # θ_k = θ_i - Δ_ik
        adj.setdefault(k, []).append((i, d, idx))  # θ_i = θ_k + Δ_ik
    theta: dict[str, float] = {}
    parent: dict[str, tuple[str, int] | None] = {}
    for root in list(ids) + [v for v in adj if v not in ids]:
        if root in theta:
            continue
        theta[root], parent[root] = 0.0, None
        queue = deque([root])
        while queue:
            v = queue.popleft()
            for w, step, idx in adj[v]:
                if w not in theta:
                    theta[w] = theta[v] + step
                    parent[w] = (v, idx)
                    queue.append(w)
    return theta, parent


def _step(a: str, b: str, triple: tuple[str, str, float]) -> float:
    """Δ along the step a -> b of a constraint: Δ_ab, or -Δ_ba for a reversed pair."""
    i, k, d = triple
    return d if (i, k) == (a, b) else -d


def inconsistent_cycle(ids: Sequence[str], edges_with_deltas: Iterable[Any]) -> tuple[list[str], float] | None:
    """A cycle whose Δs do not sum to zero, or None if Δ_ik = θ_i - θ_k is solvable.

    ``edges_with_deltas`` holds ``(i, k, Δ_ik)`` (or Edge objects); each is one
    constraint θ_i - θ_k = Δ_ik. Returns ``(cycle, total)``: the cycle as vehicle ids
    closing back to the first (started at its lowest-index vehicle) and the sum of Δ
    along it, each step a -> b adding Δ_ab (= -Δ_ba for a pair given the other way).
    Tolerance: 1e-9 · max(1, the largest |Δ| on that cycle), on the sum of its Δs. Not the
    potentials' residual on the edge that closes it: those are sums along tree paths from the
    root, and carry the rounding of the largest values on the way (phases 0 and 2^24 + 1 gave a
    residual of 4e-9 on an edge between 0 and 0.1, and a consistent set of offsets was refused).
    Not the largest value in the whole graph: a phase of 1e8 on a leaf then let a cycle
    elsewhere miss closing by 0.05.
    """
    ids = list(ids)
    triples = _triples(edges_with_deltas)
    theta, parent = _potentials(ids, triples)
    for idx, (i, k, d) in enumerate(triples):
        residual = theta[i] - theta[k] - d
        if abs(residual) <= 1e-9 * max(1.0, abs(d)):
            continue  # closes, whatever the values on its cycle (no need to walk it)
        # tree paths i -> root and k -> root, joined at their lowest common ancestor
        up_i = _path_to_root(i, parent)
        up_k = _path_to_root(k, parent)
        on_k = {v for v, _ in up_k}
        cut_i = next(j for j, (v, _) in enumerate(up_i) if v in on_k)
        lca = up_i[cut_i][0]
        cut_k = next(j for j, (v, _) in enumerate(up_k) if v == lca)
        # cycle: i -> ... -> lca -> ... -> k -> i; steps[j] = constraint from nodes[j] to nodes[j+1]
        nodes = [v for v, _ in up_i[:cut_i + 1]] + [v for v, _ in reversed(up_k[:cut_k])]
        steps = [c for _, c in up_i[:cut_i]] + [c for _, c in reversed(up_k[:cut_k])] + [idx]
        nodes, steps = _canonical(nodes, steps, ids)
        if len(nodes) == 2 and triples[steps[0]][:2] != (nodes[0], nodes[1]):
            steps = steps[::-1]  # two pairs on one link: read each as written, Δ_ab + Δ_ba
        total = sum(_step(nodes[j], nodes[(j + 1) % len(nodes)], triples[steps[j]]) for j in range(len(nodes)))
        if abs(total) <= 1e-9 * max([1.0, *(abs(triples[c][2]) for c in steps)]):
            continue  # the rounding of the potentials, not of this cycle's Δs
        return nodes + [nodes[0]], total
    return None


def _path_to_root(v: str, parent) -> list[tuple[str, int | None]]:
    """[(v, constraint to its parent), (parent, ...), ..., (root, None)]."""
    out = []
    while True:
        p = parent[v]
        out.append((v, None if p is None else p[1]))
        if p is None:
            return out
        v = p[0]


def _canonical(nodes: list[str], steps: list[int], ids: list[str]) -> tuple[list[str], list[int]]:
    """Rotate the cycle to start at its lowest-index vehicle, heading to the lower-index side."""
    pos = {v: j for j, v in enumerate(ids)}
    rank = lambda v: pos.get(v, len(ids))  # noqa: E731
    m = len(nodes)
    start = min(range(m), key=lambda j: rank(nodes[j]))
    nodes = nodes[start:] + nodes[:start]
    steps = steps[start:] + steps[:start]
    if m > 2 and rank(nodes[-1]) < rank(nodes[1]):
        # reverse: node order 0, m-1, ..., 1; step between nodes[j] and nodes[j-1] is steps[j-1]
        nodes = [nodes[0]] + nodes[:0:-1]
        steps = steps[::-1]
    return nodes, steps


def suggest_phases(ids: Sequence[str], edges_with_deltas: Iterable[Any]) -> dict[str, float]:
    """Per-vehicle phases propagated along a BFS tree from the first vehicle.

    θ_first = 0 and θ_i = θ_k + Δ_ik over the tree edges; a vehicle in another
    component roots its own tree at θ = 0. Consistent Δs are reproduced exactly.
    """
    theta, _ = _potentials(list(ids), _triples(edges_with_deltas))
    return {v: theta[v] for v in ids}
