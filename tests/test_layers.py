"""The code is layered by role, and the import graph says so.

From the bottom: ``cdus.wire`` (what goes over Zenoh) and ``cdus.files``; ``cdus.core``
(the pure math and decisions); ``cdus.scenario`` (the config schema and its checks);
``cdus.sim`` (a scenario's pieces, the per-vehicle tick protocol, the in-process fleet);
the process shells ``vehicle_agent``, ``world_sim`` and ``ground_station``; and the app
(``cdus.app``: cli, launcher, sweep, report). A module imports only from its own layer
or below, there are no import cycles, and no project module is imported inside a
function (which is how cycles hide), but for the heavy optional ones listed in LAZY.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("cdus", "vehicle_agent", "world_sim", "ground_station")
LAYERS = {  # module prefix -> layer rank (longest prefix wins)
    "cdus.wire": 0, "cdus.files": 0,
    "cdus.extras": 0,  # the ImportError of a table helper without pandas or xarray
    "cdus.core": 1,
    "cdus.core.vocabulary": 0,  # the fleet's words, importing nothing: the wire checks messages against them
    "cdus.scenario": 2,
    "cdus.commands": 2,  # the run-time commands: the scenario's checks, typed (the scenario imports its gains and faults)
    "cdus.sim": 3,
    "vehicle_agent": 4, "world_sim": 4, "ground_station": 4, "cdus.ros2": 4,
    "cdus.app": 5, "cdus.__main__": 5, "cdus.api": 5, "cdus.results": 5,
}
EXACT = {"cdus": 5}  # the package itself (cdus/__init__.py): the public API's names, from cdus.api
PURE = ("cdus.core", "cdus.scenario", "cdus.commands", "cdus.sim")  # no Zenoh, no Rerun, no clocks or printing
IMPURE_MODULES = {"zenoh", "rerun", "time", "threading", "subprocess", "socket", "signal"}
# The only project imports allowed inside a function: heavy optional dependencies, with why.
# They still count for the cycle check.
LAZY = {
    ("world_sim.sinks", "world_sim.rerun_sink"): "Rerun and pandas cost ~0.8 s of CPU and 55 MB to import; only a "
                                                 "recording needs them (tests/test_startup.py)",
    ("cdus.api", "cdus.app.fleet_run"): "Zenoh, the launcher and credentials: only a lockstep run needs them, so "
                                        "`import cdus` and in-process runs import no Zenoh",
    ("cdus.app.cli", "cdus.api"): "each `cdus` subcommand imports its own machinery where it runs, so `cdus gs` and "
                                  "`cdus launch` start without the rest (tests/test_startup.py)",
    ("cdus.app.cli", "cdus.app.sweep"): "the sweep (tqdm, numpy, the plot): only `cdus sweep` (as above)",
    ("cdus.app.cli", "cdus.app.launcher"): "the launcher: only `cdus launch` (as above)",
    ("cdus.app.cli", "cdus.app.fleet_run"): "credentials and the router: only `cdus launch` (as above)",
    ("cdus.app.cli", "cdus.ros2.export"): "numpy and the MCAP writer: only `cdus export` (as above)",
    ("cdus", "cdus.api"): "`import cdus` is cheap (every process imports the package): the API loads on first use",
    ("ground_station.__main__", "ground_station.tui"): "Textual costs ~0.4 s to import; only `cdus gs ... console` "
                                                       "needs it, not every `cdus` command",
}


def modules() -> dict[str, Path]:
    out = {}
    for pkg in PACKAGES:
        for path in (ROOT / pkg).rglob("*.py"):
            rel = path.relative_to(ROOT).with_suffix("")
            parts = rel.parts[:-1] if rel.name == "__init__" else rel.parts
            out[".".join(parts)] = path
    return out


def layer(module: str) -> int:
    if module in EXACT:
        return EXACT[module]
    best = max((p for p in LAYERS if module == p or module.startswith(p + ".")), key=len, default=None)
    assert best is not None, f"{module} is in no layer; add it to LAYERS"
    return LAYERS[best]


def imports(path: Path, known: set[str]) -> tuple[set[str], list[tuple[int, str]], set[str]]:
    """(project modules imported at module level, (line, module) imported inside a function,
    every top-level name imported)."""
    tree = ast.parse(path.read_text())
    top: set[str] = set()
    nested: list[tuple[int, str]] = []
    names: set[str] = set()

    def resolve(node: ast.AST) -> list[str]:
        found = []
        if isinstance(node, ast.Import):
            for a in node.names:
                names.add(a.name.split(".")[0])
                found.append(a.name)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.add(node.module.split(".")[0])
            for a in node.names:
                full = f"{node.module}.{a.name}"
                found.append(full if full in known else node.module)
        return [m for m in found if m.split(".")[0] in PACKAGES]

    for node in tree.body:
        top.update(resolve(node))
    for fn in ast.walk(tree):
        if isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)):
            for node in ast.walk(fn):
                for m in resolve(node):
                    nested.append((node.lineno, m))
    return top, nested, names


MODS = modules()
GRAPH = {m: imports(p, set(MODS)) for m, p in MODS.items()}


@pytest.mark.parametrize("module", sorted(MODS))
def test_imports_go_down_the_layers(module):
    up = [m for m in GRAPH[module][0] if layer(m) > layer(module)]
    assert not up, f"{module} (layer {layer(module)}) imports from a higher layer: {up}"


@pytest.mark.parametrize("module", sorted(MODS))
def test_no_project_imports_inside_functions(module):
    nested = [(line, m) for line, m in GRAPH[module][1] if (module, m) not in LAZY]
    assert not nested, f"{module} imports inside a function: {nested}"


@pytest.mark.parametrize("module", sorted(m for m in MODS if m.startswith(PURE)))
def test_the_core_is_pure(module):
    bad = GRAPH[module][2] & IMPURE_MODULES
    assert not bad, f"{module} imports {sorted(bad)}; the core does no I/O and reads no clock"


def test_no_import_cycles():
    edges = {m: {d for d in GRAPH[m][0] | {n for _, n in GRAPH[m][1]} if d in MODS} for m in MODS}
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(m: str) -> None:
        state[m] = 1
        stack.append(m)
        for d in sorted(edges[m]):
            if state.get(d) == 1:
                raise AssertionError("import cycle: " + " -> ".join(stack[stack.index(d):] + [d]))
            if d not in state:
                visit(d)
        stack.pop()
        state[m] = 2

    for m in sorted(MODS):
        if m not in state:
            visit(m)
