"""How does the whole suite run in the time it has? In two phases (tests/conftest.py says which
test goes where):

1. the shared phase: the tests that start no process and open no Zenoh session, on one
   pytest-xdist worker per core (``-n auto``);
2. the procs phase: the tests that start fleets, routers and other processes, one at a time,
   so their timing is not the load of the first phase's workers.

``python3 tests/run.py [pytest arguments]`` is the README's test command and CI's (.ci/run); any
argument goes to both phases (``tests/run.py tests/core`` runs what of tests/core each phase
has). The exit status is the worse of the two (a phase with nothing to run counts as passed).
Plain ``python3 -m pytest`` still runs everything in one serial pass.

Both phases keep compiled bytecode, outside the tree, in the user's cache directory (:func:`bytecode_env`): with
PYTHONDONTWRITEBYTECODE set, as on this machine, every process a test starts compiled cdus from
source again (measured: a 1 s lockstep launch of lake_circle 3.3 s -> 2.7 s), and every pytest
process rewrote every test module's asserts again (collection 9.6 s -> 4.5 s).
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
NO_TESTS = 5  # pytest's exit status when it collected nothing


def bytecode_env(env: dict[str, str]) -> dict[str, str]:
    """``env`` with bytecode kept: PYTHONDONTWRITEBYTECODE dropped, and, unless the caller chose a
    place, PYTHONPYCACHEPREFIX a folder of the user's cache directory (``$XDG_CACHE_HOME``, else
    ``~/.cache``), so nothing is written into the tree (the caches are the interpreter's and
    pytest's own, keyed by source). Not a fixed name in the shared temporary directory: another
    user could create it first and plant bytecode there."""
    out = {k: v for k, v in env.items() if k != "PYTHONDONTWRITEBYTECODE"}
    cache = Path(env.get("XDG_CACHE_HOME") or Path(env.get("HOME") or Path.home()) / ".cache")
    out.setdefault("PYTHONPYCACHEPREFIX", str(cache / "cdus" / "pycache"))
    return out


def phase(name: str, args: list[str], extra: list[str], env: dict[str, str]) -> int:
    t0 = time.monotonic()
    print(f"== tests/run.py: the {name} phase", flush=True)
    rc = subprocess.call([sys.executable, "-m", "pytest", *extra, *args], cwd=ROOT, env=env)
    print(f"== tests/run.py: the {name} phase ended with {rc} after {time.monotonic() - t0:.0f} s", flush=True)
    return 0 if rc == NO_TESTS else rc


def main(argv: list[str]) -> int:
    t0 = time.monotonic()
    env = bytecode_env(dict(os.environ))
    shared = phase("shared", argv, ["-m", "not procs", "-n", os.environ.get("CDUS_TEST_WORKERS", "auto")],
                   {**env, "CDUS_SUITE_PHASE": "shared"})
    procs = phase("procs", argv, ["-m", "procs"], {**env, "CDUS_SUITE_PHASE": "procs"})
    print(f"== tests/run.py: both phases took {time.monotonic() - t0:.0f} s "
          f"(shared {'passed' if shared == 0 else 'FAILED'}, procs {'passed' if procs == 0 else 'FAILED'})",
          flush=True)
    return max(shared, procs, key=lambda rc: rc != 0)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
