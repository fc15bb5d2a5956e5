"""A grid value that is a valid config value survives the sweep's files and a resume even
when it is inf (radio.shadowing_distance = inf, a [[link.down]] with to = inf): the
manifest, results.jsonl, results.csv, results.parquet and the plot keep it, and the same
command again runs nothing (issue 17 review: the manifest write crashed on inf, the rows
turned it into None)."""

import csv
import json
import math

import pyarrow.parquet as pq
import pytest
from matplotlib.figure import Figure

from cdus.app.cli import main
from cdus.app.sweep import sweep

RADIO = "configs/range_out.toml"
LINK = "configs/concentric_circles.toml"


@pytest.mark.parametrize("clock", ["inproc", "lockstep"])
def test_an_inf_grid_value_survives_the_files_and_a_resume_through_the_cli(tmp_path, capsys, clock):
    out = tmp_path / "s"
    argv = ["sweep", RADIO, "--set", "radio.shadowing_distance=50,inf", "--seeds", "1", "--clock", clock,
            "--duration", "0.5", "--jobs", "1", "--out", str(out), "-q"]
    assert main(argv) == 0
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["grid"] == [["radio.shadowing_distance", [50, math.inf]]]
    rows = [json.loads(line) for line in (out / "results.jsonl").read_text().splitlines()]
    assert [r["cell"]["radio.shadowing_distance"] for r in rows] == [50, math.inf]
    assert all(r["status"] == "ok" for r in rows)
    with open(out / "results.csv") as fh:
        assert [r["radio.shadowing_distance"] for r in csv.DictReader(fh)] == ["50", "inf"]
    assert pq.read_table(out / "results.parquet").column("radio.shadowing_distance").to_pylist() == [50.0, math.inf]
    before = (out / "results.jsonl").read_bytes()
    capsys.readouterr()
    assert main(argv) == 0  # the same command again: a resume of the same sweep, nothing new runs
    assert (out / "results.jsonl").read_bytes() == before
    assert "This call: 0 runs" in (out / "summary.md").read_text()
    assert "2 of 2 runs in the table" in capsys.readouterr().out


def test_a_link_down_window_to_inf_as_a_grid_value_resumes(tmp_path):
    down = [{"src": "*", "dst": "*", "from": 0.2, "to": math.inf}]
    grid = {"link.down": [[], down]}
    a = sweep(LINK, grid, 1, tmp_path, jobs=1, duration=0.5, quiet=True)
    assert (a.ran, a.done, a.failed) == (2, 2, 0)
    rows = [json.loads(line) for line in (tmp_path / "results.jsonl").read_text().splitlines()]
    assert [r["cell"]["link.down"] for r in rows] == [[], down]
    b = sweep(LINK, grid, 1, tmp_path, jobs=1, duration=0.5, quiet=True)
    assert (b.ran, b.resumed, b.done) == (0, 2, 2)


def test_the_plot_shows_an_inf_cell_as_a_category(monkeypatch, tmp_path):
    figs = []
    monkeypatch.setattr(Figure, "savefig", lambda self, *a, **k: figs.append(self))
    sweep(RADIO, {"radio.shadowing_distance": [50.0, math.inf]}, 1, tmp_path, jobs=1, duration=0.5, quiet=True)
    (fig,) = figs
    for ax in fig.axes:
        assert [t.get_text() for t in ax.get_xticklabels()] == ["50.0", "inf"]
