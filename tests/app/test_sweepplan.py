"""The grid of a sweep and its runs (cdus/app/sweepplan.py): parsed from --set, checked
key by key and cell by cell, planned cells × seeds."""

import pytest

from cdus.app.sweepplan import Run, check_grid, normalize_grid, parse_grid, plan
from cdus.scenario.config import ConfigError


def test_grid_values_are_parsed_as_config_values():
    grid = parse_grid(["link.loss=0,0.25", "link.policy=hold,extrapolate", "vehicle.usv1.gains.k=[1,2],[3,4]"])
    assert grid == [("link.loss", [0, 0.25]), ("link.policy", ["hold", "extrapolate"]),
                    ("vehicle.usv1.gains.k", [[1, 2], [3, 4]])]
    runs = plan(grid, [1, 2])
    assert len(runs) == 2 * 2 * 2 * 2
    assert runs[0].cell == (("link.loss", 0), ("link.policy", "hold"), ("vehicle.usv1.gains.k", [1, 2]))
    assert runs[1] == Run(runs[0].cell, 2)  # seeds innermost
    assert runs[-1].cell == (("link.loss", 0.25), ("link.policy", "extrapolate"), ("vehicle.usv1.gains.k", [3, 4]))


@pytest.mark.parametrize("bad", ["link.loss", "=1,2", "link.loss="])
def test_a_malformed_axis_is_a_config_error(bad):
    with pytest.raises(ConfigError, match="KEY=V1,V2"):
        parse_grid([bad])


def test_a_grid_is_a_mapping_or_pairs_each_key_and_value_once():
    assert normalize_grid({"link.loss": [0, 0.1], "link.policy": "hold"}) == \
        [("link.loss", [0, 0.1]), ("link.policy", ["hold"])]
    assert normalize_grid(None) == []
    with pytest.raises(ConfigError, match="link.loss: given twice"):
        normalize_grid([("link.loss", [0]), ("link.loss", [1])])
    with pytest.raises(ConfigError, match="a value is given twice"):
        normalize_grid({"link.loss": [0.1, 0.1]})
    with pytest.raises(ConfigError, match="no values"):
        normalize_grid({"link.loss": []})
    with pytest.raises(ConfigError, match="scenario.seed: is what --seeds"):
        normalize_grid({"scenario.seed": [1, 2]})


def test_the_grid_is_checked_cell_by_cell_with_its_values_together():
    grid = parse_grid(["link.burst.p=0.01,0.05", "link.burst.r=0.25"])
    check_grid("configs/lake_circle.toml", grid)  # p and r together make a burst
    with pytest.raises(ConfigError, match="link.burst.r: missing"):
        check_grid("configs/lake_circle.toml", parse_grid(["link.burst.p=0.01,0.05"]))
    with pytest.raises(ConfigError, match="link.loss"):
        check_grid("configs/lake_circle.toml", parse_grid(["link.loss=0.1,2"]))
