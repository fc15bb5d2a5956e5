"""The command line: how flags and the scenario file combine (no process is started here)."""

from __future__ import annotations

import pytest

from cdus.app.cli import build_parser, launch_options, main
from cdus.scenario.config import ConfigError, load_scenario
from cdus.scenario.model import RESTART_POLICIES

CONFIG = "configs/lake_circle.toml"


def options(*flags: str, **overrides):
    args = build_parser().parse_args(["launch", CONFIG, *flags])
    return args, launch_options(args, load_scenario(CONFIG, overrides))


def test_the_restart_policy_comes_from_the_scenario_unless_the_flag_is_given():
    args, opts = options()
    assert args.restart is None and opts.restart == "never"
    _, opts = options(**{"supervision.restart": "always"})
    assert opts.restart == "always"
    _, opts = options("--restart", "on-failure", **{"supervision.restart": "always"})
    assert opts.restart == "on-failure"


def test_the_restart_flag_takes_the_scenarios_vocabulary(capsys):
    for policy in RESTART_POLICIES:
        assert build_parser().parse_args(["launch", CONFIG, "--restart", policy]).restart == policy
    with pytest.raises(SystemExit):
        build_parser().parse_args(["launch", CONFIG, "--restart", "sometimes"])
    assert "invalid choice: 'sometimes'" in capsys.readouterr().err


def test_other_launch_options_come_from_the_flags():
    _, opts = options("--fleet", "f1", "--clock", "realtime", "--duration", "5", "--policy", "extrapolate")
    assert (opts.fleet, opts.clock, opts.duration, opts.policy) == ("f1", "realtime", 5.0, "extrapolate")
    _, opts = options()
    assert opts.fleet == "lake_circle" and opts.metrics_out is None


def test_remote_vehicles_are_checked_and_take_router_links():
    _, opts = options()
    assert opts.remote == () and opts.links == "router"  # the default
    _, opts = options("--remote", "usv1,usv2", "--remote", "uav3", "--remote", "usv1")
    assert opts.remote == ("usv1", "usv2", "uav3") and opts.links == "router"
    with pytest.raises(ConfigError, match=r"--remote: no vehicle 'usv9' in lake_circle; ids are usv1, "):
        options("--remote", "usv1,usv9")


@pytest.mark.parametrize("flag", [["--remote", "usv1"], ["--secure"], ["--tls"]])
def test_direct_links_are_refused_where_they_would_skip_the_router(flag):
    _, opts = options(*flag)
    assert opts.links == "router"
    with pytest.raises(ConfigError, match=f"--links: direct links .* with {flag[0]} use --links router"):
        options(*flag, "--links", "direct")


def test_scheduled_faults_after_the_end_are_named_not_silently_skipped(capsys, tmp_path):
    code = main(["sim", "configs/lake_circle.toml", "--rerun", "off", "-q", "--duration", "2",
                 "--metrics-out", str(tmp_path / "m.json"), "--set", 'event=[{at=100.0,action="kill",vehicle="usv2"}]'])
    assert code == 0
    assert "before kill of usv2 at 100 s: not carried out" in capsys.readouterr().err
