"""End to end: the example plug-in package (examples/cdus_plugin_example), installed in a
directory of its own, found through its entry points by `cdus sim` and by every process of
`cdus launch --clock lockstep` (the world and each agent read the scenario), equal to the bit;
a broken plug-in refused by `cdus launch` before anything starts; one that fails in the run
a lost vehicle whose log names it, never a hang."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from tests.e2e.conftest import ROOT, TRACE_FIELDS, fleet_processes, launches, run_cli, unique_fleet  # noqa: F401 (a fixture)
from tests.plugins.install import EXAMPLE, install_example
from tests.plugins.test_plugins import PLANT

CONFIG = EXAMPLE / "fleet.toml"


@pytest.fixture
def installed(tmp_path, monkeypatch) -> Path:
    """The example installed under tmp_path, on the subprocesses' PYTHONPATH (not this process's)."""
    target = install_example(tmp_path / "site")
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(target), str(ROOT)]))
    return target


def test_the_example_runs_in_lockstep_equal_to_cdus_sim_to_the_bit(tmp_path, installed, launches):
    """4 s of examples/cdus_plugin_example/fleet.toml: three unicycle boats and a drone on a
    lemniscate of Gerono, names that only the package's entry points give."""
    sim = run_cli(["sim", str(CONFIG), "--duration", "4", "--rerun", "off", "-q",
                   "--metrics-out", str(tmp_path / "sim.json"), "--trace-out", str(tmp_path / "sim.npz")])
    assert sim.returncode == 0, sim.stderr
    assert "unicycle" in sim.stdout  # the summary's plant column
    fleet = unique_fleet()
    la = launches([str(CONFIG), "--clock", "lockstep", "--duration", "4", "--rerun", "off", "-q",
                   "--logs", str(tmp_path / "run"), "--trace-out", str(tmp_path / "launch.npz")], fleet)
    assert la.wait() == 0, la.output()
    got, want = np.load(tmp_path / "launch.npz"), np.load(tmp_path / "sim.npz")
    assert want["q"].shape[0] == 4 * 20 + 1  # every control tick of 4 s at 20 Hz, and t = 0
    for name in TRACE_FIELDS:
        assert got[name].shape == want[name].shape and np.array_equal(got[name], want[name], equal_nan=True), name
    assert not fleet_processes(fleet)


def test_launch_refuses_a_plugin_that_fails_to_import_before_starting_anything(tmp_path, installed):
    """A second package whose entry point raises on import: `cdus launch` names it (the
    group, the name, the package, module:object) and the fix, exits 2, starts no process."""
    broken = installed / "broken_plugin"
    broken.mkdir()
    (broken / "__init__.py").write_text("raise RuntimeError('no licence file found')\n")
    info = installed / "broken_plugin-1.0.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: broken-plugin\nVersion: 1.0\n")
    (info / "entry_points.txt").write_text("[cdus.plants]\nbroken = broken_plugin:MODEL\n")
    fleet = unique_fleet()
    out = run_cli(["launch", str(CONFIG), "--clock", "lockstep", "--duration", "1", "--rerun", "off", "-q",
                   "--logs", str(tmp_path / "run"), "--fleet", fleet])
    assert out.returncode == 2, out.stderr
    assert ('fleet.toml: plugins (installed): plug-in plant "broken" (entry point cdus.plants "broken" of package '
            'broken-plugin 1.0: broken_plugin:MODEL) cannot be loaded: RuntimeError: no licence file found; fix the '
            'package, or uninstall it\n') in out.stderr
    assert "nothing was started" in out.stderr
    assert "unknown" not in out.stderr  # not also every vehicle's family and plant
    assert not fleet_processes(fleet) and not (tmp_path / "run" / "metrics.json").exists()


LATE = """
[plugins.plants]
late = "late_plant:MODEL"

[scenario]
name = "late"
duration = 3.0

[rates]
control = 10.0

[[vehicle]]
id = "b1"
kind = "usv"
plant = "late"
path = { family = "circle", center = [0, 0], radius = 5 }

[[vehicle]]
id = "b2"
kind = "usv"
phase = 1.0
path = { family = "circle", center = [0, 0], radius = 5 }
"""


def test_a_plugin_plant_failing_in_a_lockstep_run_is_a_lost_vehicle_naming_it(tmp_path, monkeypatch, launches):
    """b1's plant (the scenario's [plugins] table, a module on PYTHONPATH) raises at t = 1 s: its
    process says why, naming the plug-in, and exits; the world ends the run (vehicles_lost, exit
    1) instead of waiting for it; nothing is left running."""
    (tmp_path / "late_plant.py").write_text(
        PLANT.replace("{change}", "if t > 1.0: raise RuntimeError('motor controller lost')"))
    (tmp_path / "late.toml").write_text(LATE)
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(tmp_path), str(ROOT)]))
    fleet = unique_fleet()
    la = launches([str(tmp_path / "late.toml"), "--clock", "lockstep", "--rerun", "off", "-q",
                   "--logs", str(tmp_path / "run")], fleet)
    assert la.wait() == 1, la.output()
    assert "vehicles_lost" in la.output()
    log = (tmp_path / "run" / "logs" / "b1.log").read_text()
    assert ('[b1] error: vehicle b1: its numbers overflowed at t = 0.90 s (the vehicle diverged; gains k = (1.5, 1.5), '
            'c = 2.0): plug-in plant "late" ([plugins.plants] of the scenario: late_plant:MODEL): step raised '
            'RuntimeError: motor controller lost') in log
    assert not fleet_processes(fleet)
