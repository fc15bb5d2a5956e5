import csv

import pyarrow.parquet as pq
import pytest

from cdus.app.sweep import Run, normalize_grid, parse_grid, run_text, summarize, sweep
from cdus.scenario.config import ConfigError, load_scenario


def test_a_sweep_writes_results_summary_and_plot_and_records_failures(tmp_path, monkeypatch):
    import cdus.app.sweepworker as worker
    from cdus.core.vehicle import DivergedError

    class Diverging(worker.InProcessFleet):  # the runs of loss 0.6 diverge: recorded, the sweep goes on
        def run(self, *a, **k):
            if self.scenario.link.loss == 0.6:
                raise DivergedError("vehicle c1: its state is no longer finite at t = 3.00 s")
            return super().run(*a, **k)

    monkeypatch.setattr(worker, "InProcessFleet", Diverging)  # jobs=1 runs in this process
    grid = parse_grid(["link.loss=0,0.3,0.6"])
    res = sweep("configs/concentric_circles.toml", grid, [1, 2], tmp_path, jobs=1, duration=20.0, quiet=True)
    rows = res.rows()
    assert (res.planned, res.done, res.ran, res.resumed, len(rows)) == (6, 6, 6, 0, 6)
    ok = [r for r in rows if r["status"] == "ok"]
    failed = [r for r in rows if r["status"] == "failed"]
    assert len(ok) == 4 and len(failed) == 2 and res.failed == 2
    assert all("DivergedError" in r["reason"] and "no longer finite" in r["reason"] for r in failed)
    with open(tmp_path / "results.csv") as fh:
        table = list(csv.DictReader(fh))
    assert [r["link.loss"] for r in table] == ["0", "0", "0.3", "0.3", "0.6", "0.6"]
    assert [r["seed"] for r in table] == ["1", "2"] * 3
    assert {"seed", "status", "coord_settle_s", "final_coord_error_max", "link_dropped"} <= set(table[0])
    lossy = [r for r in table if r["link.loss"] == "0.3"]
    assert all(int(r["link_dropped"]) > 0 for r in lossy)
    summary = (tmp_path / "summary.md").read_text()
    assert "| 0.3 | 2/2 | 2/2 |" in summary and "Failed runs:" in summary
    assert "95 % percentile bootstrap confidence interval of the mean" in summary
    assert (tmp_path / "sweep.png").stat().st_size > 10_000
    assert sum(1 for _ in open(tmp_path / "results.jsonl")) == 6


def test_the_parquet_table_has_the_grid_values_as_typed_columns(tmp_path):
    grid = {"link.loss": [0, 0.3], "link.policy": ["hold"], "link.burst": [{"p": 0.01, "r": 0.5}],
            "graph.weight": [1, 2]}
    res = sweep("configs/concentric_circles.toml", grid, 1, tmp_path, jobs=1, duration=5.0, quiet=True)
    t = pq.read_table(tmp_path / "results.parquet")
    types = {f.name: str(f.type) for f in t.schema}
    assert types["link.loss"] == "double" and types["graph.weight"] == "int64" and types["seed"] == "int64"
    assert types["link.policy"] == "string" and types["link.burst"] == "string"
    assert types["coord_settle_s"] == "double" and types["link_dropped"] == "int64" and types["completed"] == "bool"
    rows = res.rows()
    assert [r["link.loss"] for r in rows] == [0.0, 0.0, 0.3, 0.3]
    assert [r["graph.weight"] for r in rows] == [1, 2, 1, 2]
    assert {r["link.burst"] for r in rows} == {'{"p":0.01,"r":0.5}'}
    assert {r["seed"] for r in rows} == {load_scenario("configs/concentric_circles.toml").seed}
    # the CSV says the same as the Parquet file, row for row
    with open(tmp_path / "results.csv") as fh:
        table = list(csv.DictReader(fh))
    assert [float(r["final_coord_error_max"]) for r in table] == [r["final_coord_error_max"] for r in rows]


def test_table_values_label_their_cells(tmp_path):
    grid = parse_grid(["link.burst={p=0.01,r=0.5},{p=0.05,r=0.5}"])
    res = sweep("configs/lake_circle.toml", grid, [1], tmp_path, jobs=1, duration=2.0, quiet=True)
    rows = res.rows()
    assert [r["link.burst"] for r in rows] == ['{"p":0.01,"r":0.5}', '{"p":0.05,"r":0.5}']
    assert all(r["status"] == "ok" for r in rows)
    assert '{"p":0.05,"r":0.5}' in summarize(["link.burst"], res.cells)
    assert (tmp_path / "sweep.png").exists()


def test_a_scenario_object_sweeps_like_its_file(tmp_path):
    a = sweep("configs/concentric_circles.toml", {"link.loss": [0.2]}, 2, tmp_path / "a", jobs=1, duration=5.0,
              quiet=True)
    s = load_scenario("configs/concentric_circles.toml")
    b = sweep(s, {"link.loss": [0.2]}, 2, tmp_path / "b", jobs=1, duration=5.0, quiet=True)
    strip = [{k: v for k, v in r.items() if k not in ("wall_s", "realtime_factor")} for r in a.rows()]
    assert strip == [{k: v for k, v in r.items() if k not in ("wall_s", "realtime_factor")} for r in b.rows()]
    # and the manifest knows it is the same sweep: the file resumes the object's directory
    c = sweep("configs/concentric_circles.toml", {"link.loss": [0.2]}, 2, tmp_path / "b", jobs=1, duration=5.0,
              quiet=True)
    assert (c.ran, c.resumed) == (0, 2)


def test_progress_lines_round_and_say_never():
    run = Run((("link.loss", 0.1), ("link.burst", {"p": 0.01, "r": 0.5})), 3)
    text = run_text(run, {"status": "ok", "coord_settle_s": 141.42000000000002, "final_coord_error_max": 0.00023})
    assert text == 'link.loss=0.1, link.burst={"p":0.01,"r":0.5}, seed 3: coord settle 141.4 s, final edge error ' \
                   '0.00023 rad'
    text = run_text(run, {"status": "ok", "coord_settle_s": None, "final_coord_error_max": 0.0784})
    assert "coord settle never," in text and "None" not in text and "0.0784 rad" in text
    assert run_text(Run((), 1), {"status": "failed", "reason": "boom"}) == "(base), seed 1: FAILED: boom"


def test_the_cli_refuses_no_seeds(tmp_path, capsys):
    from cdus.app.cli import main

    assert main(["sweep", "configs/concentric_circles.toml", "--seeds", "0", "--out", str(tmp_path / "o")]) == 2
    assert "--seeds: must be at least 1" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_progress_goes_to_its_stream_with_an_eta_and_quiet_silences_it(tmp_path):
    import io

    loud = io.StringIO()
    sweep("configs/concentric_circles.toml", {"link.loss": [0, 0.3]}, 2, tmp_path / "a", jobs=1, duration=5.0,
          stream=loud)
    text = loud.getvalue()
    assert "sweep: 100%" in text and "4/4" in text and "<00:00" in text  # elapsed<remaining: the ETA
    assert "None" not in text
    again = io.StringIO()
    sweep("configs/concentric_circles.toml", {"link.loss": [0, 0.3]}, 3, tmp_path / "a", jobs=1, duration=5.0,
          stream=again)
    assert "4 of 6 runs already done" in again.getvalue()
    quiet = io.StringIO()
    sweep("configs/concentric_circles.toml", {"link.loss": [0, 0.3]}, 2, tmp_path / "b", jobs=1, duration=5.0,
          stream=quiet, quiet=True)
    assert quiet.getvalue() == ""


def test_the_result_iterates_over_its_rows_and_leaves_pyplot_alone(tmp_path):
    import sys

    before = sys.modules.get("matplotlib.pyplot")
    backend = before.get_backend() if before else None
    res = sweep("configs/concentric_circles.toml", {"link.loss": [0, 0.3]}, 1, tmp_path, jobs=1, duration=5.0,
                quiet=True)
    assert len(res) == 2 and list(res) == res.rows()
    pd = pytest.importorskip("pandas")
    assert list(pd.DataFrame(res)["link.loss"]) == [0.0, 0.3]
    assert res.table().shape == pd.DataFrame(res).shape
    after = sys.modules.get("matplotlib.pyplot")
    assert (after.get_backend() if after else None) == backend


def test_numpy_grids_and_seeds_are_plain_values(tmp_path):
    import numpy as np

    grid = normalize_grid({"link.loss": np.linspace(0, 0.2, 3), "rates.control": [np.int64(20), 50]})
    assert grid == [("link.loss", [0.0, 0.1, 0.2]), ("rates.control", [20, 50])]
    assert all(type(v) in (int, float) for _, vals in grid for v in vals)
    res = sweep("configs/concentric_circles.toml", {"link.loss": np.array([0.0, 0.1])}, np.arange(1, 3), tmp_path,
                jobs=1, duration=5.0, quiet=True)
    assert [(r["link.loss"], r["seed"]) for r in res.rows()] == [(0.0, 1), (0.0, 2), (0.1, 1), (0.1, 2)]


def test_a_bad_value_in_any_cell_refuses_the_sweep_before_any_run(tmp_path):
    grid = parse_grid(["link.loss=0,0.3,1.5"])  # 1.5 is not a probability
    with pytest.raises(ConfigError, match=r"link.loss.*probability|probability.*link.loss"):
        sweep("configs/concentric_circles.toml", grid, [1, 2], tmp_path / "out", jobs=1, duration=20.0, quiet=True)
    assert not (tmp_path / "out").exists()  # nothing run, nothing written


def test_the_cli_writes_the_plot_in_the_format_asked_and_refuses_another(tmp_path, capsys):
    from cdus.app.cli import main

    out = tmp_path / "o"
    assert main(["sweep", "configs/concentric_circles.toml", "--set", "link.loss=0,0.2", "--seeds", "1",
                 "--duration", "2", "--jobs", "1", "-q", "--plot-format", "pdf", "--out", str(out)]) == 0
    assert (out / "sweep.pdf").read_bytes()[:5] == b"%PDF-" and not (out / "sweep.png").exists()
    assert f"plot: {out / 'sweep.pdf'}" in capsys.readouterr().out
    with pytest.raises(SystemExit):
        main(["sweep", "configs/concentric_circles.toml", "--plot-format", "jpg", "--out", str(tmp_path / "x")])
    with pytest.raises(ConfigError, match="--plot-format: expected one of png, pdf, svg"):
        sweep("configs/concentric_circles.toml", {}, 1, tmp_path / "y", plot_format="jpg")
    assert not (tmp_path / "x").exists() and not (tmp_path / "y").exists()
