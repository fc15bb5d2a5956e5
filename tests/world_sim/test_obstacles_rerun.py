"""The [[obstacle]]s in Rerun: every obstacle's outline logged once, static, at the start, where
the scenario puts it (world_sim.rerun_draw.obstacle_strips)."""

from __future__ import annotations

import numpy as np
import pytest
from rerun.chunk import RrdReader

from cdus.core.obstacles import Box, Cylinder
from cdus.scenario.config import load_scenario
from world_sim.rerun_draw import OBSTACLES, obstacle_strips

from tests.recordings import record

from .test_recording import ROOT


@pytest.fixture(scope="module")
def static_strips(tmp_path_factory):
    """island_crossing for 0.5 s saved to an .rrd: entity -> (its strips, its labels) of the static chunks."""
    config = ROOT / "configs" / "island_crossing.toml"
    path = record(config, tmp_path_factory.mktemp("obs") / "run.rrd", 0.5)
    reader = RrdReader(str(path))
    out = {}
    for chunk in reader.stream(store=reader.recordings()[0]):
        entity = chunk.entity_path.lstrip("/")
        if chunk.is_static and entity.startswith(OBSTACLES):
            b = chunk.to_record_batch()
            strips = b.column(b.schema.names.index("LineStrips3D:strips")).to_pylist()[-1]
            labels = b.column(b.schema.names.index("LineStrips3D:labels")).to_pylist()[-1]
            out[entity] = ([np.array(s) for s in strips], labels)
    return load_scenario(config), out


def test_every_obstacle_is_drawn_static_where_the_scenario_puts_it(static_strips):
    sc, drawn = static_strips
    assert sorted(drawn) == [f"{OBSTACLES}/{j}" for j in range(len(sc.obstacles))] and len(sc.obstacles) == 4
    for j, o in enumerate(sc.obstacles):
        strips, labels = drawn[f"{OBSTACLES}/{j}"]
        assert labels == [o.name]
        want = obstacle_strips(o)
        assert len(strips) == len(want) and all(np.allclose(a, b) for a, b in zip(strips, want))


def test_outlines_lie_on_the_shapes():
    from cdus.core.obstacles import Circle, clearance

    for o in (Circle((1.0, 2.0), 3.0, 1.0), Cylinder((0.0, 0.0), 2.0, (0.0, 30.0), 1.0),
              Box((0.0, 0.0, 0.0), (1.0, 2.0, 3.0), 1.0)):
        strips = obstacle_strips(o)
        assert len(strips) == (1 if o.shape == "circle" else 6)
        for s in strips:
            for p in s:
                q = tuple(p[:2]) if o.shape == "circle" else tuple(p)
                assert abs(clearance(o, q).distance) < 1e-9
