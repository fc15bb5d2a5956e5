"""Zenoh's runtime per process: the launcher's children get cdus's small runtime, the launcher's
own session (the fleet's router) keeps Zenoh's pools unless told otherwise (a router on fewer
threads stalls every link behind a congested one: cdus.wire.transport.ROUTER_RUNTIME)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from cdus.wire.transport import CHILD_RUNTIME, ROUTER_RUNTIME, RUNTIME_ENV, SMALL_ROUTER_RUNTIME, use_runtime

REPO = Path(__file__).resolve().parents[2]

PROBE = textwrap.dedent("""
    import json, os, sys, tempfile
    from pathlib import Path
    from cdus.app.launcher import LaunchOptions, Launcher
    from cdus.scenario.config import load_scenario
    from cdus.wire.transport import router
    sc = load_scenario("configs/lake_circle.toml")
    with tempfile.TemporaryDirectory() as tmp:
        la = Launcher(sc, Path(tmp) / "run", router(), LaunchOptions(fleet="rt"), log=lambda s: None)
        la._open()
        names = sorted(open(f"/proc/self/task/{t}/comm").read().strip() for t in os.listdir("/proc/self/task"))
        child = la.env.get("ZENOH_RUNTIME")
        la.close_router()
        # a second fleet from the same program: its children still get theirs, not the router's
        la2 = Launcher(sc, Path(tmp) / "run2", router(), LaunchOptions(fleet="rt2"), log=lambda s: None)
        child2 = la2.env.get("ZENOH_RUNTIME")
    print(json.dumps({"threads": names, "env": os.environ.get("ZENOH_RUNTIME"), "child": child, "child2": child2}))
""")


def _probe(**env: str) -> dict:
    base = {k: v for k, v in os.environ.items() if k not in (RUNTIME_ENV, "CDUS_ROUTER_RUNTIME")}
    out = subprocess.run([sys.executable, "-c", PROBE], cwd=REPO, capture_output=True, text=True, timeout=120,
                         env={**base, "PYTHONPATH": str(REPO), **env})
    assert out.returncode == 0, out.stderr[-2000:]
    return json.loads(out.stdout.strip().splitlines()[-1])


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="thread names from /proc")
def test_the_router_keeps_zenohs_pools_and_the_children_get_the_small_runtime():
    # the router on fewer threads stalls every link behind a congested one (ROUTER_RUNTIME's note)
    got = _probe()
    assert ROUTER_RUNTIME == "default" and got["env"] is None
    assert got["child"] == got["child2"] == CHILD_RUNTIME
    assert [t for t in got["threads"] if t.startswith("acc-")], got["threads"]  # Zenoh's accept pool


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="thread names from /proc")
def test_the_routers_runtime_can_be_chosen_and_never_reaches_the_children():
    got = _probe(CDUS_ROUTER_RUNTIME=SMALL_ROUTER_RUNTIME)
    assert got["env"] == SMALL_ROUTER_RUNTIME and got["child"] == got["child2"] == CHILD_RUNTIME
    zenoh = [t for t in got["threads"] if t.split("-")[0] in ("app", "rx", "tx", "acc", "net")]
    assert not [t for t in zenoh if t.startswith(("rx-", "acc-"))], zenoh  # handed over to app
    assert [t for t in zenoh if t.startswith("app-")] == ["app-0"], zenoh


def test_a_users_zenoh_runtime_wins():
    mine = "(app: (worker_threads: 2))"
    got = _probe(ZENOH_RUNTIME=mine)
    assert got["env"] == mine and got["child"] == got["child2"] == mine


def test_use_runtime_sets_only_what_is_unset():
    env: dict[str, str] = {}
    assert use_runtime("(a)", env) == "(a)" and env == {RUNTIME_ENV: "(a)"}
    assert use_runtime("(b)", env) == "(a)"
