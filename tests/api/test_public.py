"""The public surface of ``import cdus``: the names docs/api.md lists under "Public names",
``cdus.__all__`` and ``cdus.api.__all__`` are one list, and each name is importable from
``cdus`` (a name in ``__all__`` that raised AttributeError, ``cdus.RadioMetrics``, went
unnoticed because nothing read the three lists together)."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import cdus
import cdus.api

ROOT = Path(__file__).resolve().parents[2]


def documented_names(text: str) -> list[str]:
    """The names of docs/api.md's "Public names" table: every backticked name of its first
    column, a call's signature cut at its parenthesis (``run(scenario, ...)`` -> ``run``)."""
    section = text.split("\n## Public names\n", 1)[1].split("\n## ", 1)[0]
    names = []
    for line in section.splitlines():
        if not line.startswith("| `"):
            continue
        first = line.split(" | ", 1)[0]
        for code in re.findall(r"`([^`]+)`", first):
            name = code.split("(", 1)[0].strip()
            assert name.isidentifier(), f"docs/api.md: {code!r} is not a name"
            names.append(name)
    return names


def test_the_parser_reads_a_row_of_names_and_a_signature():
    text = "x\n## Public names\n\n| name | what |\n|---|---|\n| `run(s, *, clock=\"inproc\")` | a run |\n" \
           "| `A`, `B` | two |\n\n## Next\n| `C` | not public |\n"
    assert documented_names(text) == ["run", "A", "B"]


def test_the_documented_names_are_all_and_importable_from_cdus():
    documented = documented_names((ROOT / "docs/api.md").read_text())
    assert len(documented) == len(set(documented)), "docs/api.md lists a name twice"
    assert sorted(documented) == sorted(cdus.__all__)
    assert sorted(cdus.api.__all__) == sorted(cdus.__all__)
    for name in cdus.__all__:
        assert getattr(cdus, name) is getattr(cdus.api, name), name


def test_every_name_imports_in_a_fresh_interpreter():
    """``from cdus import X`` as a user writes it (the lazy ``__getattr__`` of a fresh module)."""
    code = f"from cdus import {', '.join(cdus.__all__)}; print('ok')"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60, cwd=ROOT)
    assert out.returncode == 0 and out.stdout.strip() == "ok", out.stderr
