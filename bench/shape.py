"""How is the code shaped? The figures issue 26 asks the shells to meet, printed by one command.

    python bench/shape.py [--top 10] [--check] [--root DIR]

- the longest source files (the aim: none over about 600 lines),
- ``grep -rnE "clock (==|!=)" world_sim vehicle_agent`` (the aim: only the place that picks
  the clock),
- where the finite-number check is defined and every other place that tests "a number, not a
  bool" itself (the aim: one definition, ``cdus/wire/bounds.py`` ``finite()``, used everywhere),
- the modules whose docstring does not open with the question they answer (the aim: none).

Reads the files as text and their syntax trees; runs nothing of the project. ``--check``
exits 1 when an aim is missed (the report is the same); ``--root`` reads another tree (the
tests give it a small one).
"""

from __future__ import annotations

import argparse
import ast
import re
import sys
from pathlib import Path

PACKAGES = ("cdus", "world_sim", "vehicle_agent", "ground_station")  # the source trees
CLOCK_TREES = ("world_sim", "vehicle_agent")  # where the clock's name must not be compared
CLOCK_RE = re.compile(r"clock (==|!=)")  # grep -E "clock (==|!=)"
MAX_LINES = 600  # "no source file over about 600 lines"
FINITE_HOME = ("cdus/wire/bounds.py", "finite")  # the one definition the issue wants
MAX_CLOCK_PLACES = 1  # the place that picks the clock


def sources(root: Path, trees: tuple[str, ...] = PACKAGES) -> list[Path]:
    """The Python files of ``trees`` under ``root``, in path order."""
    return sorted(p for t in trees for p in (root / t).rglob("*.py") if "__pycache__" not in p.parts)


def line_count(path: Path) -> int:
    """Lines as ``wc -l`` counts them (newlines)."""
    return path.read_bytes().count(b"\n")


def clock_comparisons(root: Path) -> list[str]:
    """``grep -rnE "clock (==|!=)" world_sim vehicle_agent``'s lines (``path:line:text``), in
    path order."""
    out = []
    for p in sources(root, CLOCK_TREES):
        for n, line in enumerate(p.read_text(errors="replace").splitlines(), 1):
            if CLOCK_RE.search(line):
                out.append(f"{p.relative_to(root)}:{n}:{line}")
    return out


def _isinstance_of(node: ast.AST, names: set[str]) -> str | None:
    """The variable's text if ``node`` is ``isinstance(v, T)`` with every name of ``names``
    among T's names, else None."""
    if not (isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "isinstance"
            and len(node.args) == 2):
        return None
    types = {n.id for n in ast.walk(node.args[1]) if isinstance(n, ast.Name)}
    return ast.unparse(node.args[0]) if names <= types else None


def number_tests(tree: ast.AST) -> list[tuple[int, str, bool]]:
    """Every expression that tests a number by hand: (line, the enclosing function, whether
    it is a finite-number check of its own). A finite-number check: ``isinstance(v, float)``
    (or ``(int, float)``) and ``isfinite(v)`` in one ``and``/``or``, or "a number, not a
    bool" (``isinstance(v, bool)`` and ``isinstance(v, (int, float))``) in a function that
    also calls ``isfinite``; else "a number, not a bool" alone."""
    found = []

    def isfinite_args(node: ast.AST) -> set[str]:
        return {ast.unparse(n.args[0]) for n in ast.walk(node) if isinstance(n, ast.Call) and n.args
                and (getattr(n.func, "attr", None) == "isfinite" or getattr(n.func, "id", None) == "isfinite")}

    def visit(node: ast.AST, func: ast.AST | None) -> None:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            func = node
        if isinstance(node, ast.BoolOp):
            calls = [n for n in ast.walk(node) if isinstance(n, ast.Call)]
            bools = {_isinstance_of(c, {"bool"}) for c in calls} - {None}
            numbers = {_isinstance_of(c, {"int", "float"}) for c in calls} - {None}
            floats = {_isinstance_of(c, {"float"}) for c in calls} - {None}
            if floats & isfinite_args(node) or bools & numbers:
                finite = bool(floats & isfinite_args(node)) or bool(isfinite_args(func if func is not None else tree))
                found.append((node.lineno, getattr(func, "name", "<module>"), finite))
                return  # one expression, counted once
        for child in ast.iter_child_nodes(node):
            visit(child, func)

    visit(tree, None)
    return found


QUESTION_WORDS = ("what", "which", "where", "when", "how", "who", "whose", "why", "is", "are", "does", "do", "can")


def opens_with_a_question(tree: ast.Module) -> bool:
    """The module's docstring opens with a question: its first sentence (to the first ``.``,
    ``?`` or ``:`` ending a word) has a ``?`` or its first word asks (``What pushes a vehicle
    off its reference: ...``, as cdus/core has them). An empty module (an ``__init__.py``
    with nothing in it) asks nothing and needs not."""
    if not tree.body:
        return True
    doc = " ".join((ast.get_docstring(tree) or "").split())
    first = re.split(r"(?<=[?.:])\s", doc, maxsplit=1)[0]
    return "?" in first or first.split(" ", 1)[0].lower() in QUESTION_WORDS


def report(root: Path, top: int = 10) -> tuple[list[str], list[str]]:
    """The report's lines, and the aims it misses (empty: every aim met)."""
    files = sources(root)
    sizes = sorted(((line_count(p), p.relative_to(root).as_posix()) for p in files), reverse=True)
    lines, missed = [], []
    over = [s for s in sizes if s[0] > MAX_LINES]
    lines.append(f"# The longest source files ({len(files)} in {', '.join(PACKAGES)}; aim: none over {MAX_LINES} "
                 f"lines; {len(over)} over)")
    lines += [f"{n:6d} {path}" for n, path in sizes[:top]]
    if over:
        missed.append(f"{len(over)} files over {MAX_LINES} lines, the longest {sizes[0][1]} ({sizes[0][0]})")

    clock = clock_comparisons(root)
    places = sorted({c.split(":", 1)[0] for c in clock})
    lines += ["", f'# grep -rnE "clock (==|!=)" {" ".join(CLOCK_TREES)} ({len(clock)} lines in {len(places)} '
                  f"files; aim: only the place that picks the clock)"]
    lines += clock or ["(none)"]
    if len(places) > MAX_CLOCK_PLACES:
        missed.append(f"the clock's name is compared in {len(places)} files")

    home, defs, copies, questionless = None, [], [], []
    for p in files:
        rel = p.relative_to(root).as_posix()
        try:
            tree = ast.parse(p.read_text(errors="replace"))
        except SyntaxError as e:
            missed.append(f"{rel}: not Python ({e.msg}, line {e.lineno})")
            continue
        if not opens_with_a_question(tree):
            questionless.append(rel)
        for lineno, func, finite in number_tests(tree):
            where = f"{rel}:{lineno} {func}()"
            if (rel, func) == FINITE_HOME:
                home = where
            elif finite:
                defs.append(where)
            else:
                copies.append(where)
    n_defs = len(defs) + (home is not None)
    lines += ["", f"# The finite-number check (a number, not a bool, finite): {n_defs} definitions; aim: one, "
                  f"{FINITE_HOME[0]} {FINITE_HOME[1]}(), used everywhere"]
    lines.append(f"defined: {home}" if home else f"defined: nowhere ({FINITE_HOME[0]} has no {FINITE_HOME[1]}())")
    lines += [f"written again: {d}" for d in defs]
    lines += [f"a number, not a bool, tested by hand: {c}" for c in copies]
    if n_defs != 1 or defs or copies:
        missed.append(f"the finite-number check: {n_defs} definitions, {len(copies)} more places test a number "
                      f"themselves")

    lines += ["", f"# Modules whose docstring does not open with the question they answer ({len(questionless)} of "
                  f"{len(files)}; aim: none)"]
    lines += questionless or ["(none)"]
    if questionless:
        missed.append(f"{len(questionless)} modules do not open with their question")
    return lines, missed


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--top", type=int, default=10, help="how many of the longest files to list (default 10)")
    ap.add_argument("--check", action="store_true", help="exit 1 when an aim is missed")
    ap.add_argument("--root", type=Path, default=Path(__file__).resolve().parent.parent,
                    help="the tree to read (default: this checkout)")
    args = ap.parse_args(argv)
    lines, missed = report(args.root, args.top)
    print("\n".join(lines))
    print("\n# Aims missed: " + ("none" if not missed else str(len(missed))))
    for m in missed:
        print(f"- {m}")
    return 1 if args.check and missed else 0


if __name__ == "__main__":
    sys.exit(main())
