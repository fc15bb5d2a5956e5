"""The safety in Rerun: a dot over each vehicle at the ticks its filter intervened, the
closest approach so far as a labelled line, the event lines; and the per-vehicle
intervention counts the world records from the agents' stats."""

from __future__ import annotations

import numpy as np
import pytest

from cdus.scenario.config import load_scenario
from cdus.sim.fleet import InProcessFleet
from cdus.wire import keys
from cdus.wire.schemas import AgentStats, encode_stats
from tests.fakes import Payload, Sample
from world_sim.sinks import make_sink
from world_sim.rerun_sink import CLOSEST, INTERVENTIONS, NEAR_COLOUR, intervened

from .test_recording import ROOT, Recording
from .test_world import FLEET, row, send_rows, started, world

CROSSING = ROOT / "configs" / "crossing.toml"


def _record(tmp_path, overrides):
    path = tmp_path / "run.rrd"
    sc = load_scenario(CROSSING, {"scenario.duration": 6.0, **overrides})
    sink = make_sink(f"save:{path}")
    res = InProcessFleet(sc, sink=sink).run()
    sink.close()
    return res, Recording(path)


@pytest.fixture(scope="module")
def filtered(tmp_path_factory):
    """crossing.toml for 6 s with the filter: usv_a1 and usv_b1 meet at the upper crossing."""
    return _record(tmp_path_factory.mktemp("on"), {})


@pytest.fixture(scope="module")
def unfiltered(tmp_path_factory):
    return _record(tmp_path_factory.mktemp("off"), {"safety.enabled": False})


def test_intervened_is_where_a_count_went_up_and_a_restarts_reset_is_not():
    counts = np.array([[0, 0], [1, 0], [1, 0], [2, 1], [0, 1], [1, 1]])  # vehicle 0 restarted at row 4
    np.testing.assert_array_equal(intervened(counts, None), [[0, 0], [1, 0], [0, 0], [1, 1], [0, 0], [1, 0]])
    np.testing.assert_array_equal(intervened(counts[3:], counts[2]), [[1, 1], [0, 0], [1, 0]])


def test_a_dot_marks_every_vehicle_at_exactly_the_ticks_its_filter_intervened(filtered):
    res, rec = filtered
    assert INTERVENTIONS in rec.static
    hit = intervened(res.recorder.view("interventions"), None)
    assert hit.sum() == res.metrics.interventions > 0
    times, labels = rec.column(INTERVENTIONS, "Points3D:labels")
    _, positions = rec.column(INTERVENTIONS, "Points3D:positions")
    ticks = np.round(times / 20_000_000).astype(int)  # 50 Hz: 20 ms a tick
    shown = {int(n): set(lab) for n, lab in zip(ticks, labels)}
    for n in np.nonzero(hit.any(axis=1))[0]:
        assert shown[n] == {res.recorder.ids[j] for j in np.nonzero(hit[n])[0]}, n
    for n, lab in shown.items():
        if not lab:  # a row that clears the dots follows one that showed some
            assert hit[n - 1].any() and not hit[n].any()
    n, lab = next((n, lab) for n, lab in zip(ticks, labels) if lab)
    j = res.recorder.ids.index(lab[0])
    k = list(ticks).index(n)
    np.testing.assert_allclose(positions[k][0][:2], res.recorder.view("q")[n, j, :2], atol=1e-4)
    _, texts = rec.column("comms/events", "TextLog:text")
    assert any(t[0].startswith("usv_a1: the safety filter intervenes") for t in texts)


def test_the_last_closest_line_is_the_metrics_closest_pair(filtered, unfiltered):
    for res, rec in (filtered, unfiltered):
        p = res.metrics.closest_pair
        times, labels = rec.column(f"{CLOSEST}/usv", "LineStrips3D:labels")
        _, strips = rec.column(f"{CLOSEST}/usv", "LineStrips3D:strips")
        assert times[-1] == round(p.t_s * 1e9)
        assert labels[-1] == [f"closest so far: {p.a} - {p.b} {p.distance_m:.2f} m at {p.t_s:.2f} s"]
        n = int(round(p.t_s * 50))
        ends = np.array(strips[-1][0])
        q = res.recorder.view("q")[n]
        np.testing.assert_allclose(ends[:, :2], q[[res.recorder.ids.index(p.a), res.recorder.ids.index(p.b)], :2],
                                   atol=1e-4)
        assert list(np.diff(times) > 0) == [True] * (len(times) - 1)


def test_without_the_filter_no_dots_a_red_line_and_a_near_collision_event(unfiltered):
    res, rec = unfiltered
    assert INTERVENTIONS not in rec.static and rec.rows(INTERVENTIONS) == 0
    _, colours = rec.column(f"{CLOSEST}/usv", "LineStrips3D:colors")
    r, g, b = NEAR_COLOUR
    assert colours[-1] == [(r << 24) | (g << 16) | (b << 8) | 0xFF]
    _, texts = rec.column("comms/events", "TextLog:text")
    assert [t[0] for t in texts if t[0].startswith("near collision")] == [
        "near collision: usv_a1 and usv_b1 1.07 m apart at t = 1.18 s, within the safety radius 2 m"]


def test_the_world_records_each_vehicles_interventions_as_its_processes_report_them():
    w = started(world())
    send = lambda s: w.feed(keys.stats(FLEET, s.id), encode_stats(s))  # noqa: E731

    def record(n):
        for j, vid in enumerate(w.ids):
            send_rows(w, vid, [row(j, n)])
        w.clock.record_complete()

    record(0)
    send(AgentStats(id="usv2", tick=1, interventions=3))
    record(1)
    w.alive("usv2", False)  # killed: its token goes
    send(AgentStats(id="usv2", tick=2, interventions=1, incarnation=9))  # a restarted process counts anew
    send(AgentStats(id="uav1", tick=2, interventions=2))
    record(2)
    counts = w.recorder.view("interventions")
    assert counts[:, w.ids.index("usv2")].tolist() == [0, 3, 4]
    assert counts[:, w.ids.index("uav1")].tolist() == [0, 0, 2]
    assert counts[:, w.ids.index("usv1")].tolist() == [0, 0, 0]
