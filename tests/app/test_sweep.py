import csv

import pytest

from cdus.scenario.config import ConfigError
from cdus.app.sweep import check_grid, parse_grid, plan, summarize, sweep


def test_grid_values_are_parsed_as_config_values():
    grid = parse_grid(["link.loss=0,0.25", "link.policy=hold,extrapolate", "vehicle.usv1.gains.k=[1,2],[3,4]"])
    assert grid == [("link.loss", [0, 0.25]), ("link.policy", ["hold", "extrapolate"]),
                    ("vehicle.usv1.gains.k", [[1, 2], [3, 4]])]
    runs = plan(grid, [1, 2])
    assert len(runs) == 2 * 2 * 2 * 2
    assert runs[0].cell == (("link.loss", 0), ("link.policy", "hold"), ("vehicle.usv1.gains.k", [1, 2]))


@pytest.mark.parametrize("bad", ["link.loss", "=1,2", "link.loss="])
def test_a_malformed_axis_is_a_config_error(bad):
    with pytest.raises(ConfigError, match="KEY=V1,V2"):
        parse_grid([bad])


def test_a_sweep_writes_results_summary_and_plot_and_records_failures(tmp_path):
    grid = parse_grid(["link.loss=0,0.3,1.5"])  # 1.5 is not a probability: those runs fail
    rows = sweep("configs/concentric_circles.toml", grid, [1, 2], tmp_path, jobs=1, duration=20.0, quiet=True)
    assert len(rows) == 6
    ok = [r for r in rows if r["status"] == "ok"]
    failed = [r for r in rows if r["status"] == "failed"]
    assert len(ok) == 4 and len(failed) == 2
    assert all("link.loss" in r["reason"] and "probability" in r["reason"] for r in failed)
    with open(tmp_path / "results.csv") as fh:
        table = list(csv.DictReader(fh))
    assert [r["link.loss"] for r in table] == ["0", "0", "0.3", "0.3", "1.5", "1.5"]
    assert {"seed", "status", "coord_settle_s", "final_coord_error_max", "link_dropped"} <= set(table[0])
    lossy = [r for r in table if r["link.loss"] == "0.3"]
    assert all(int(r["link_dropped"]) > 0 for r in lossy)
    summary = (tmp_path / "summary.md").read_text()
    assert "| 0.3 | 2/2 |" in summary and "Failed runs:" in summary
    assert (tmp_path / "sweep.png").stat().st_size > 10_000


def test_the_grid_is_checked_cell_by_cell_with_its_values_together():
    grid = parse_grid(["link.burst.p=0.01,0.05", "link.burst.r=0.25"])
    check_grid("configs/lake_circle.toml", grid)  # p and r together make a burst
    with pytest.raises(ConfigError, match="link.burst.r: missing"):
        check_grid("configs/lake_circle.toml", parse_grid(["link.burst.p=0.01,0.05"]))
    with pytest.raises(ConfigError, match="link.loss"):
        check_grid("configs/lake_circle.toml", parse_grid(["link.loss=0.1,2"]))


def test_table_values_label_their_cells(tmp_path):
    grid = parse_grid(["link.burst={p=0.01,r=0.5},{p=0.05,r=0.5}"])
    rows = sweep("configs/lake_circle.toml", grid, [1], tmp_path, jobs=1, duration=2.0, quiet=True)
    assert [r["link.burst"] for r in rows] == ['{"p":0.01,"r":0.5}', '{"p":0.05,"r":0.5}']
    assert all(r["status"] == "ok" for r in rows)
    assert '{"p":0.05,"r":0.5}' in summarize(["link.burst"], rows)
    assert (tmp_path / "sweep.png").exists()
