"""The Python API (cdus.api, docs/api.md): the same numbers as the command line, typed
metrics that give their JSON back, the trace as arrays and tables, inputs checked where they
enter, and ``import cdus`` without Zenoh or Rerun."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import cdus
from cdus.wire.schemas import decode_status, encode_status
from cdus.api import Metrics, Trace
from cdus.core.metrics import min_separation, settle_time
from cdus.sim.fleet import InProcessFleet
from cdus.wire.rejected import Rejected
from tests.jsontree import JSON, paths

ROOT = Path(__file__).resolve().parents[2]
LAKE = str(ROOT / "configs/lake_circle.toml")
CONCENTRIC = str(ROOT / "configs/concentric_circles.toml")
FAULTS = {  # link faults, a kill and a restart: every nested part of the metrics JSON is there
    "link.loss": 0.2, "link.burst": {"p": 0.01, "r": 0.25}, "link.delay": {"base": 0.04, "jitter": 0.01},
    "event": [{"at": 5.0, "action": "kill", "vehicle": "usv2"}, {"at": 10.0, "action": "restart", "vehicle": "usv2"}],
}
WALL = ("wall_s", "realtime_factor")  # wall-clock fields: differ between any two runs


def toml(v) -> str:
    """A value as `--set` reads it (TOML inline syntax)."""
    if isinstance(v, dict):
        return "{" + ", ".join(f"{k} = {toml(x)}" for k, x in v.items()) + "}"
    if isinstance(v, list):
        return "[" + ", ".join(toml(x) for x in v) + "]"
    return json.dumps(v)


def cli_sim(tmp_path: Path, config: str, overrides: dict) -> tuple[dict, dict]:
    """`cdus sim CONFIG --duration 20 --metrics-out X --rerun off`, in its own process: the
    metrics JSON and the trace it wrote."""
    sets = [a for k, v in overrides.items() for a in ("--set", f"{k}={toml(v)}")]
    m, tr = tmp_path / "m.json", tmp_path / "trace.npz"
    proc = subprocess.run([sys.executable, "-m", "cdus.app.cli", "sim", config, "--duration", "20", "--metrics-out",
                           str(m), "--trace-out", str(tr), "--rerun", "off", "-q", *sets], cwd=tmp_path,
                          capture_output=True, text=True, timeout=120, start_new_session=True)
    assert proc.returncode == 0, proc.stderr
    with np.load(tr) as z:
        return json.loads(m.read_text()), {k: z[k] for k in z.files}


@pytest.mark.parametrize("config,overrides", [(CONCENTRIC, {}), (LAKE, FAULTS)], ids=["concentric", "faults"])
def test_the_api_gives_the_numbers_of_the_command_line(tmp_path, config, overrides):
    want, trace = cli_sim(tmp_path, config, overrides)
    res = cdus.run(cdus.load(config, {**overrides, "scenario.duration": 20}))
    got = res.metrics.to_dict()
    assert {k: v for k, v in got.items() if k not in WALL} == {k: v for k, v in want.items() if k not in WALL}
    assert list(got) == list(want)  # the same fields, in the file's order
    for name, arr in trace.items():
        assert np.array_equal(arr, getattr(res.trace, name)), name


def test_the_metrics_fields_are_those_of_docs_metrics_md():
    text = (ROOT / "docs/metrics.md").read_text()
    table = text[text.index("## Fields"):text.index("### `link`")]
    documented = set(re.findall(r"^\| `(\w+)` \|", table, flags=re.M))
    assert len(documented) >= 20
    assert documented == {f for f in Metrics.__dataclass_fields__ if f != "extra"}
    link = text[text.index("### `link`"):text.index("`link.faults`")]
    fields = {f for names in re.findall(r"^\| (`[^|]+`) \|", link, flags=re.M) for f in re.findall(r"`(\w+)`", names)}
    assert fields == {f for f in cdus.LinkMetrics.__dataclass_fields__ if f != "extra"}


def metric_dicts(tmp_path) -> dict[str, dict]:
    """Metrics JSONs of every writer: a run, a run with faults, an interrupted one (as `cdus
    sim` writes it after Ctrl-C), the world's (a lockstep run: rejected_by_reason,
    missed_deadlines) and the launcher's when the world died (link {}, extra fields)."""
    from cdus.app.launcher import LaunchOptions, Launcher
    from cdus.wire.transport import local_router

    sc = cdus.load(LAKE, {"scenario.duration": 4})
    out = {"run": InProcessFleet(sc).run().metrics.to_dict(),
           "faults": InProcessFleet(cdus.override(sc, {**FAULTS, "scenario.duration": 12})).run().metrics.to_dict()}
    fleet = InProcessFleet(sc)
    for _ in range(30):
        fleet.step()
    out["interrupted"] = {**fleet.partial_metrics().to_dict(), "interrupted": True}
    la = Launcher(sc, tmp_path / "run", local_router(), LaunchOptions(fleet="t1", quiet=True))
    la.status = decode_status(encode_status(2.5, 4.0, "lockstep", ["usv1"], list(sc.ids), 0.5, 0.1, [], False))
    out["world_lost"] = la.write_world_lost(-9, 1.0).to_dict()
    world = dict(out["faults"], mode="lockstep", rejected_by_reason={"world": {"key": 2}, "vehicles": {}})
    world["link"] = {**world["link"], "missed_deadlines": 0}
    world["link"] = {k: world["link"][k] for k in ("sent", "delivered", "dropped", "duplicated", "rejected",
                                                   "latency_ms_p50", "latency_ms_p99", "missed_deadlines", "faults")}
    out["world"] = world
    # the world's when the run never began (the launcher gave up waiting for a --remote vehicle)
    out["not_started"] = {**world, "completed": False, "completion": "not_started", "never_up": ["uav2"]}
    return {k: json.loads(json.dumps(v)) for k, v in out.items()}  # as read back from the file


def test_metrics_read_from_any_writer_give_their_json_back_in_order(tmp_path):
    for name, d in metric_dicts(tmp_path).items():
        m = Metrics.from_dict(d)
        assert json.dumps(m.to_dict()) == json.dumps(d), name
    dicts = metric_dicts(tmp_path)
    faults = Metrics.from_dict(dicts["faults"])
    assert faults.link.faults.total.dropped_by.loss > 0 and faults.link.faults.links["usv1->usv2"].sent > 0
    kill = next(e for e in faults.events if e.kind == "fault")
    assert (kill.t, kill.vehicle, kill.severity, kill.link) == (5.0, "usv2", "warn", None)
    lost = Metrics.from_dict(dicts["world_lost"])
    assert lost.link is None and lost.written_by == "launcher" and lost.world_lost.last_status_t == 2.5 and lost.completion == "world_lost"
    world = Metrics.from_dict(dicts["world"])
    assert world.rejected_by_reason.world == {"key": 2} and world.link.missed_deadlines == 0
    assert Metrics.from_dict(dicts["interrupted"]).interrupted is True and faults.interrupted is None
    assert Metrics.from_dict(dicts["not_started"]).never_up == ("uav2",) and faults.never_up is None


BASE = json.loads(json.dumps(InProcessFleet(cdus.load(LAKE, {"scenario.duration": 2, **FAULTS}))
                             .run().metrics.to_dict()))
PATHS = [p for p in paths(BASE) if p]


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.sampled_from(PATHS), JSON, st.booleans())
def test_a_damaged_metrics_json_is_refused_naming_the_field_or_kept_whole(path, value, delete):
    d = json.loads(json.dumps(BASE))
    node = d
    for k in path[:-1]:
        node = node[k]
    if delete and isinstance(node, dict):
        del node[path[-1]]
    else:
        node[path[-1]] = value
    m = Metrics.from_json(d)
    if isinstance(m, Rejected):  # refused naming the field (where it was damaged, or one inside it)
        assert m.field and m.reason
        with pytest.raises(ValueError, match=f"^metrics: {re.escape(str(m))}$"):
            Metrics.from_dict(d)
    else:
        assert json.dumps(m.to_dict()) == json.dumps(d)  # accepted: nothing lost, nothing changed


KNOWN = sorted(set(BASE) | {"rejected_by_reason", "radio", "interrupted", "never_up", "integrity"})


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.dictionaries(st.sampled_from(KNOWN) | st.text(max_size=4), JSON, max_size=6),
       st.sets(st.sampled_from(KNOWN), max_size=3), JSON)
def test_any_json_gives_metrics_or_a_rejected_naming_a_field_never_an_exception(changes, deleted, anything):
    """Metrics.from_json on whatever a file holds (a run's metrics with fields changed to any
    JSON value, added or deleted; or any JSON at all): the record, or a Rejected naming the
    field; never an exception."""
    d = {k: v for k, v in {**json.loads(json.dumps(BASE)), **changes}.items() if k not in deleted}
    for value in (d, anything):
        m = Metrics.from_json(value)
        assert isinstance(m, Metrics) or (isinstance(m, Rejected) and m.field), m
        if isinstance(m, Metrics):  # kept whole (the key order of any writer's is the test above's)
            assert m.to_dict() == value
    assert isinstance(m, Metrics) or (isinstance(m, Rejected) and m.field), m


def test_a_metrics_file_reads_back(tmp_path):
    d = metric_dicts(tmp_path)["faults"]
    (tmp_path / "m.json").write_text(json.dumps(d))
    assert Metrics.read(tmp_path / "m.json").to_dict() == d
    assert Metrics.from_json(d).to_dict() == d
    assert Metrics.from_json({**d, "seed": "1"}) == Rejected("expected an integer, got '1'", "seed")
    assert Metrics.from_json(tmp_path / "m.json").field == "metrics"  # a path is not the JSON: read() reads it
    (tmp_path / "cut.json").write_text(json.dumps(d)[:100])  # a file cut short (a full disk)
    with pytest.raises(ValueError, match="cut.json: not a metrics JSON"):
        Metrics.read(tmp_path / "cut.json")
    (tmp_path / "old.json").write_text(json.dumps({k: v for k, v in d.items() if k != "completion"}))
    with pytest.raises(ValueError, match="old.json: metrics: completion: missing"):
        Metrics.read(tmp_path / "old.json")
    with pytest.raises(ValueError, match="metrics: seed: expected an integer"):
        Metrics.from_dict({**d, "seed": "1"})
    with pytest.raises(ValueError, match="metrics: link.faults.total.dropped_by.loss: missing"):
        bad = json.loads(json.dumps(d))
        del bad["link"]["faults"]["total"]["dropped_by"]["loss"]
        Metrics.from_dict(bad)


# ---------------------------------------------------------------- the trace


@pytest.fixture(scope="module")
def concentric():
    return cdus.run(CONCENTRIC if False else cdus.load(CONCENTRIC, {"scenario.duration": 20}))


def test_the_trace_agrees_with_the_metrics(concentric):
    res = concentric
    tr, m, sc = res.trace, res.metrics, res.scenario
    T, N = int(round(20 * sc.rates.control)) + 1, len(sc.vehicles)
    assert len(tr) == T and tr.q.shape == (T, N, 3) and tr.path_error.shape == (T, N)
    assert tr.ids == sc.ids and tr.edge_error.shape == (T, len(tr.edge_names)) and tr.live.dtype == bool
    assert tr.live.all() and m.live_final == sc.ids
    assert m.duration_s == tr.t[-1] - tr.t[0] == 20.0
    assert m.final_path_error == {vid: tr.path_error[-1, j] for j, vid in enumerate(tr.ids)}
    assert m.final_path_error_max == tr.path_error[-1].max()
    assert m.final_coord_error_max == tr.edge_error[-1].max()
    assert m.path_settle_s == settle_time(tr.t, tr.path_error.max(axis=1), m.path_tol) is not None
    assert m.coord_settle_s == settle_time(tr.t, tr.edge_error.max(axis=1), m.coord_tol) is not None
    assert m.min_separation_m == round(min_separation(tr.q, [v.kind for v in sc.vehicles]), 6)


def test_the_trace_saves_as_trace_out_does_and_reads_back(tmp_path, concentric):
    from cdus.core.metrics import Recorder

    sc = concentric.scenario
    fleet = InProcessFleet(sc)
    fleet.run()
    fleet.recorder.save_trace(str(tmp_path / "rec.npz"))
    concentric.trace.save(tmp_path / "api.npz")
    with np.load(tmp_path / "rec.npz") as a, np.load(tmp_path / "api.npz") as b:
        assert a.files == b.files
        for k in a.files:
            assert np.array_equal(a[k], b[k]) and a[k].dtype == b[k].dtype, k
    back = Trace.from_npz(tmp_path / "api.npz")
    assert back.ids == concentric.trace.ids and back.edge_names == concentric.trace.edge_names
    assert all(np.array_equal(getattr(back, k), getattr(concentric.trace, k)) for k in ("t", "q", "live"))
    np.savez(tmp_path / "other.npz", t=np.zeros(3))
    with pytest.raises(ValueError, match="not a cdus trace: no q"):
        Trace.from_npz(tmp_path / "other.npz")
    assert isinstance(fleet.recorder, Recorder)


def test_the_trace_as_a_dataframe_and_a_dataset(concentric):
    tr = concentric.trace
    T, N = len(tr), len(tr.ids)
    df = tr.to_dataframe()
    assert list(df.columns) == ["t", "vehicle", "x", "y", "z", "heading", "omega", "omega_rate", "path_error", "live",
                                "interventions"]
    assert len(df) == T * N
    row = df.iloc[7 * N + 2]  # tick 7, the third vehicle
    assert (row.t, row.vehicle, row.x, row.z, row.omega) == (tr.t[7], tr.ids[2], tr.q[7, 2, 0], tr.q[7, 2, 2],
                                                             tr.omega[7, 2])
    last = df[df.t == tr.t[-1]].set_index("vehicle")["path_error"].to_dict()
    assert last == concentric.metrics.final_path_error
    edges = tr.edges_dataframe()
    assert len(edges) == T * len(tr.edge_names)
    assert edges.groupby("edge", observed=True)["error"].last().max() == concentric.metrics.final_coord_error_max
    ds = tr.to_xarray()
    assert dict(ds.sizes) == {"t": T, "vehicle": N, "axis": 3, "edge": len(tr.edge_names)}
    assert float(ds.q.sel(vehicle=tr.ids[1], axis="y").isel(t=-1)) == tr.q[-1, 1, 1]
    assert ds.path_error.attrs["units"] == "m" and ds.t.attrs["units"] == "s"


def test_without_pandas_the_error_names_the_extra(concentric, monkeypatch):
    monkeypatch.setitem(sys.modules, "pandas", None)
    monkeypatch.setitem(sys.modules, "xarray", None)
    with pytest.raises(ImportError, match=r"Trace.to_dataframe needs pandas.*pip install -e '\.\[api\]'"):
        concentric.trace.to_dataframe()
    with pytest.raises(ImportError, match=r"Trace.to_xarray needs xarray.*pip install -e '\.\[api\]'"):
        concentric.trace.to_xarray()


# ---------------------------------------------------------------- inputs


def test_override_on_a_loaded_scenario():
    sc = cdus.load(LAKE)
    other = cdus.override(sc, {"scenario.seed": 4, "link.loss": np.float64(0.25), "rates.control": np.int64(20)})
    assert (other.seed, other.link.loss, other.rates.control) == (4, 0.25, 20)
    assert type(other.raw["link"]["loss"]) is float and type(other.raw["rates"]["control"]) is int
    assert other.vehicles[0].start_position != sc.vehicles[0].start_position  # starts drawn again from the new seed
    assert sc.seed == 1 and "link" not in sc.raw  # the first is untouched
    assert cdus.override(other, {"scenario.seed": 1}).vehicles == sc.vehicles


def deep(n: int) -> list:
    out: list = []
    for _ in range(n):
        out = [out]
    return out


@pytest.mark.parametrize("call,match", [
    (lambda: cdus.load("nowhere.toml"), r"nowhere.toml: file: not found; give the path of a scenario .toml"),
    (lambda: cdus.load(3), r"cdus.load: path: expected the path of a scenario .toml file.*got int"),
    (lambda: cdus.load(LAKE, ["link.loss=0.2"]), r"overrides: expected a mapping of dotted keys to values"),
    (lambda: cdus.load(LAKE, {"vehicle.nobody.gains.k": 2}), r"override vehicle.nobody.gains.k: .*usv1"),
    (lambda: cdus.load(LAKE, {"rates.control": -5}), r"rates.control"),
    (lambda: cdus.load(LAKE, {"link.loss": {0.1}}), r"override link.loss: a set is not a config value"),
    (lambda: cdus.load(LAKE, {"link.loss": deep(100_000)}), r"override link.loss: lists and tables nested deeper"),
    (lambda: cdus.load(LAKE, {1: 2}), r"overrides: keys are dotted config keys"),
    (lambda: cdus.override("not a scenario" and 5, {}), r"cdus.override: scenario: expected a Scenario"),
    (lambda: cdus.run(LAKE, clock="fast"), r"cdus.run: clock: 'fast' is not one of inproc, lockstep"),
    (lambda: cdus.run(LAKE, policy="wait"), r"policy: 'wait' is not one of hold, timeout, extrapolate"),
    (lambda: cdus.run(LAKE, rerun="somewhere"), r"cdus.run: rerun: .*off"),
    (lambda: cdus.run(LAKE, clock="lockstep", rerun="auto"), r"rerun: 'auto' may save the recording into the run"),
    (lambda: cdus.run(LAKE, progress=1), r"progress: expected True, False or a callable"),
    (lambda: cdus.run(LAKE, clock="lockstep", progress=print), r"progress: a lockstep run shows the launcher's own"),
    (lambda: cdus.run(LAKE, progress="yes"), r"progress: expected True, False or a callable"),
    (lambda: cdus.run(LAKE, clock="lockstep", secure=False, tls=True), r"tls: TLS is a mode of the secured fleet"),
    (lambda: cdus.run(LAKE, clock="lockstep", fleet="a b"), r"fleet: fleet name 'a b': use 1-64 letters"),
    (lambda: cdus.run(LAKE, clock="lockstep", ready_timeout=0), r"ready_timeout: expected seconds > 0"),
    (lambda: cdus.sweep(LAKE, {"link.loss": 0.2}, out="x"), r"grid link.loss: expected a non-empty list"),
    (lambda: cdus.sweep(LAKE, {"link.loss": [2.0]}, out="x"), r"link.loss"),
    (lambda: cdus.sweep(LAKE, {}, out="x", seeds=0), r"seeds: expected how many seeds"),
    (lambda: cdus.sweep(LAKE, {}, out=None), r"cdus.sweep: out: expected a directory path"),
    (lambda: cdus.sweep(LAKE, {}, out="x", jobs=0), r"jobs: expected a number of parallel runs"),
    (lambda: cdus.sweep(LAKE, {}, out="x", plot_format="jpg"), r"plot_format: 'jpg' is not one of png, pdf, svg"),
    (lambda: cdus.sweep(LAKE, {}, out="x", duration=-1), r"duration: expected simulated seconds > 0"),
])
def test_bad_inputs_are_a_config_error_naming_the_field_and_nothing_runs(call, match, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(cdus.ConfigError, match=match):
        call()
    assert not (tmp_path / "x").exists()  # a sweep refused before it made its directory


def test_a_lockstep_run_outside_the_main_thread_is_refused_before_anything_starts():
    import threading

    errors = []
    t = threading.Thread(target=lambda: errors.append(pytest.raises(cdus.ConfigError, cdus.run, LAKE,
                                                                    clock="lockstep")))
    t.start()
    t.join()
    assert "call it from the main thread" in str(errors[0].value)


def test_ctrl_c_during_an_in_process_run_gives_what_ran():
    sc = cdus.load(LAKE, {"scenario.duration": 20})

    def stop(t, total):
        if t >= 5:
            raise KeyboardInterrupt

    with pytest.raises(cdus.RunInterrupted) as info:
        cdus.run(sc, progress=stop)
    assert isinstance(info.value, KeyboardInterrupt)
    res = info.value.result
    assert res.metrics.interrupted is True and res.metrics.completed is False
    assert res.metrics.completion == "interrupted" and res.metrics.duration_s == res.trace.t[-1] == pytest.approx(4.98)


def test_errors_pickle_with_what_they_carry():
    import pickle

    res = cdus.run(cdus.load(LAKE, {"scenario.duration": 1}))
    back = pickle.loads(pickle.dumps(cdus.RunInterrupted(res)))
    assert back.result.metrics == res.metrics and np.array_equal(back.result.trace.q, res.trace.q)
    err = pickle.loads(pickle.dumps(cdus.RunError("no fleet", ["a", "b"])))
    assert err.log == ("a", "b") and str(err).startswith("no fleet\nthe launcher's log:\na\nb")


def test_ctrl_c_during_cdus_sim_still_writes_the_metrics_and_trace_of_what_ran(tmp_path, monkeypatch, capsys):
    from cdus.app import cli

    class CtrlC(cli.Progress):
        def __call__(self, t, total):
            if t >= 2:
                raise KeyboardInterrupt

    monkeypatch.setattr(cli, "Progress", CtrlC)
    m, tr = tmp_path / "m.json", tmp_path / "t.npz"
    assert cli.main(["sim", LAKE, "--duration", "20", "--rerun", "off", "-q", "--metrics-out", str(m),
                     "--trace-out", str(tr)]) == 130
    d = json.loads(m.read_text())
    assert d["interrupted"] is True and d["completion"] == "interrupted"
    assert d["duration_s"] == pytest.approx(4.98)  # progress is called every 250 ticks: stopped at the 250th
    assert len(Trace.from_npz(tr)) == 250
    assert f"metrics: {m}" in capsys.readouterr().out


# ---------------------------------------------------------------- import cost and sweeps


def test_import_cdus_and_an_in_process_run_import_neither_zenoh_nor_rerun():
    code = ("import sys, cdus\n"
            "assert 'cdus.api' not in sys.modules and 'numpy' not in sys.modules, sorted(sys.modules)\n"
            f"res = cdus.run(cdus.load({LAKE!r}, {{'scenario.duration': 1}}))\n"
            "print(sorted(m for m in sys.modules if m.split('.')[0] in ('zenoh', 'rerun')), res.metrics.completed)\n"
            "assert sorted(dir(cdus)) == sorted(set(dir(cdus)) | set(cdus.__all__))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60, cwd=ROOT)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["[]", "True"]
    with pytest.raises(AttributeError, match="no attribute 'nothing'"):
        cdus.nothing  # noqa: B018


def test_a_sweep_through_the_api_gives_its_table(tmp_path):
    import matplotlib.pyplot as plt
    import pandas as pd

    sc = cdus.load(LAKE, {"scenario.seed": 7})
    before = plt.get_backend()
    plt.switch_backend("pdf")  # the caller's (a notebook's is inline)
    try:
        table = cdus.sweep(sc, {"link.loss": [0, 0.3]}, out=tmp_path / "sw", seeds=2, duration=4, jobs=1)
        assert plt.get_backend() == "pdf"  # the sweep's own plot did not take it away
    finally:
        plt.switch_backend(before)
    assert (tmp_path / "sw/sweep.png").exists()
    assert (tmp_path / "sw/results.csv").exists() and (tmp_path / "sw/results.parquet").exists()
    assert json.loads((tmp_path / "sw/scenario.json").read_text())["scenario"]["seed"] == 7  # the fixed override
    assert isinstance(table, cdus.SweepTable) and len(table) == 4 and table.keys == ("link.loss",)
    assert [(r["link.loss"], r.seed) for r in table] == [(0, 7), (0, 8), (0.3, 7), (0.3, 8)]
    assert {r.status for r in table.rows} == {"ok"}
    df = table.to_dataframe()
    assert list(df["link.loss"]) == [0, 0, 0.3, 0.3] and list(df["seed"]) == [7, 8, 7, 8]
    assert list(df["final_coord_error_max"]) == [r.final_coord_error_max for r in table.rows]
    assert df.equals(pd.read_parquet(tmp_path / "sw/results.parquet"))  # the table the engine wrote, typed alike
    # the per-cell statistics of summary.md: typed, and as a DataFrame
    assert [(c["link.loss"], c.runs, c.ok) for c in table.cells] == [(0, 2, 2), (0.3, 2, 2)]
    for c in table.cells:
        errs = [r.final_coord_error_max for r in table.rows if r["link.loss"] == c["link.loss"]]
        st = c.stats["final_coord_error_max"]
        assert st.n == 2 and st.mean == pytest.approx(sum(errs) / 2) and st.lo <= st.mean <= st.hi
    cells = cdus.cell_statistics(table)
    assert list(cells["link.loss"]) == [0, 0.3] and list(cells["runs"]) == [2, 2]
    assert list(cells["final_coord_error_max_mean"]) == [c.stats["final_coord_error_max"].mean for c in table.cells]
    ds = table.to_xarray()  # grid x seed
    assert dict(ds.sizes) == {"link.loss": 2, "seed": 2} and list(ds.seed) == [7, 8]
    assert float(ds.final_coord_error_max.sel({"link.loss": 0.3, "seed": 8})) == table.rows[3].final_coord_error_max
    assert ds.link_dropped.dtype.kind == "i" and ds.coord_settle_s.attrs["units"] == "s"
    one = cdus.run(cdus.override(sc, {"link.loss": 0.3, "scenario.seed": 8, "scenario.duration": 4}))
    row = table.rows[3]
    assert row.final_coord_error_max == one.metrics.final_coord_error_max
    assert row.link_dropped == one.metrics.link.dropped > 0


def test_without_pandas_a_sweep_gives_the_same_typed_table(tmp_path, monkeypatch):
    """It gave a DataFrame with pandas and a list of dicts without: one type now, whatever is installed."""
    monkeypatch.setitem(sys.modules, "pandas", None)
    monkeypatch.setitem(sys.modules, "xarray", None)
    table = cdus.sweep(LAKE, {}, out=tmp_path / "plain", seeds=[3], duration=2, jobs=1)
    assert isinstance(table, cdus.SweepTable) and table.keys == () and table.seeds == (3,)
    (row,) = table.rows
    assert isinstance(row, cdus.SweepRow) and (row.seed, row.status, row.cell) == (3, "ok", ())
    assert isinstance(row.final_coord_error_max, float) and isinstance(row.link_sent, int)
    (cell,) = table.cells
    assert isinstance(cell, cdus.CellStats) and (cell.runs, cell.ok) == (1, 1)
    for call, what in ((table.to_dataframe, "SweepTable.to_dataframe needs pandas"),
                       (table.to_xarray, "SweepTable.to_xarray needs xarray"),
                       (lambda: cdus.cell_statistics(table), "cdus.cell_statistics needs pandas")):
        with pytest.raises(ImportError, match=what + r".*pip install -e '\.\[api\]'"):
            call()


def test_an_event_field_that_does_not_apply_is_absent_never_null():
    """Found by the Hypothesis test above in CI: ``"link": null`` was read as absent and written
    back without the key (not "kept whole"); FleetEvent.as_dict never writes a null."""
    d = json.loads(json.dumps(BASE))
    d["events"] = [{"t": 1.0, "kind": "fault", "text": "x", "severity": "warn", "vehicle": "usv1"}]
    assert Metrics.from_dict(d).to_dict() == d
    d["events"][0]["link"] = None
    with pytest.raises(ValueError, match=r"metrics: events\[0\]\.link: expected a string"):
        Metrics.from_dict(d)


def test_a_lockstep_run_into_a_directory_another_fleet_runs_into_is_refused_untouched(tmp_path):
    """Issue 27, broken 5, for the API: run_dir held by a running fleet is a ConfigError naming
    run_dir; nothing is started, its metrics are not removed."""
    from cdus.app.launcher import RunDirLock

    run = tmp_path / "run"
    run.mkdir()
    (run / "metrics.json").write_text("{}")  # the running fleet's
    with RunDirLock(run):
        with pytest.raises(cdus.ConfigError, match="run_dir: another `cdus launch` is running into"):
            cdus.run(cdus.load("configs/lake_circle.toml"), clock="lockstep", run_dir=run)
    assert (run / "metrics.json").read_text() == "{}" and not (run / "logs").exists()
